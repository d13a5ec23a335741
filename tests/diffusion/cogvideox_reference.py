"""Independent reference forward of CogVideoXTransformer3DModel + the GeoDrive branch, written after
diffusers' module code (CogVideoXPatchEmbed, CogVideoXLayerNormZero, CogVideoXAttnProcessor2_0,
get_3d_rotary_pos_embed, AdaLayerNorm, unpatchify) with plain torch 1.13 (Debian python3-torch).

usage: cogvideox_reference.py WEIGHTS INPUTS CONFIG_JSON
WEIGHTS holds the backbone and the encoder under "branch."; INPUTS holds noisy, image, cond, text,
timesteps. Prints the model output (v-prediction), one float per line, in C order.
"""
import json
import math
import struct
import sys

import torch
import torch.nn.functional as F

DTYPES = {"F32": torch.float32, "F64": torch.float64, "BF16": torch.bfloat16,
          "F16": torch.float16, "I64": torch.int64}


def load(path):
    with open(path, "rb") as f:
        data = f.read()
    n = struct.unpack("<Q", data[:8])[0]
    header = json.loads(data[8:8 + n])
    base = 8 + n
    out = {}
    for name, v in header.items():
        if name == "__metadata__":
            continue
        b, e = v["data_offsets"]
        t = torch.frombuffer(bytearray(data[base + b:base + e]), dtype=DTYPES[v["dtype"]])
        out[name] = t.reshape(v["shape"]).clone()
    return out


def main():
    allw = load(sys.argv[1])
    inp = load(sys.argv[2])
    cfg = json.loads(sys.argv[3])
    heads, hd, p = cfg["heads"], cfg["head_dim"], cfg["patch"]
    eps, qk_eps, layers = cfg["eps"], cfg["qk_eps"], cfg["layers"]
    backbone = {k: v for k, v in allw.items() if not k.startswith("branch.")}
    branch = {k[len("branch."):]: v for k, v in allw.items() if k.startswith("branch.")}

    def lin(w, x, n):
        return F.linear(x, w[n + ".weight"], w.get(n + ".bias"))

    def ln(w, x, n, e):
        return F.layer_norm(x, (x.shape[-1],), w[n + ".weight"], w[n + ".bias"], e)

    def time_embed(w, t):
        dim = heads * hd
        half = dim // 2
        exponent = -math.log(10000) * torch.arange(0, half, dtype=torch.float32) / half
        emb = t[:, None].float() * torch.exp(exponent)[None, :]
        emb = torch.cat([torch.sin(emb), torch.cos(emb)], dim=-1)
        emb = torch.cat([emb[:, half:], emb[:, :half]], dim=-1)  # flip_sin_to_cos
        return lin(w, F.silu(lin(w, emb, "time_embedding.linear_1")), "time_embedding.linear_2")

    def rope_1d(dim, pos):
        freqs = 1.0 / (10000 ** (torch.arange(0, dim, 2, dtype=torch.float64)[: dim // 2] / dim))
        freqs = torch.outer(pos.double(), freqs)
        return (freqs.cos().repeat_interleave(2, dim=1).float(),
                freqs.sin().repeat_interleave(2, dim=1).float())

    def rope_3d(T, H, W):
        dt, dh = hd // 4, hd // 8 * 3
        ct, st = rope_1d(dt, torch.arange(T))
        ch, sh = rope_1d(dh, torch.arange(H))
        cw, sw = rope_1d(dh, torch.arange(W))

        def combine(ft, fh, fw):
            ft = ft[:, None, None, :].expand(-1, H, W, -1)
            fh = fh[None, :, None, :].expand(T, -1, W, -1)
            fw = fw[None, None, :, :].expand(T, H, -1, -1)
            return torch.cat([ft, fh, fw], dim=-1).reshape(T * H * W, -1)
        return combine(ct, ch, cw), combine(st, sh, sw)

    def apply_rope(x, cos, sin):
        x_real, x_imag = x.reshape(*x.shape[:-1], -1, 2).unbind(-1)
        x_rot = torch.stack([-x_imag, x_real], dim=-1).flatten(3)
        return (x.float() * cos + x_rot.float() * sin).to(x.dtype)

    def block(w, pre, hs, ehs, temb, rope):
        L = ehs.shape[1]

        def norm_zero(n, hs, ehs):
            sh, sc, g, esh, esc, eg = lin(w, F.silu(temb), n + ".linear").chunk(6, dim=1)
            hs = ln(w, hs, n + ".norm", eps) * (1 + sc)[:, None, :] + sh[:, None, :]
            ehs = ln(w, ehs, n + ".norm", eps) * (1 + esc)[:, None, :] + esh[:, None, :]
            return hs, ehs, g[:, None, :], eg[:, None, :]

        nh, ne, g, eg = norm_zero(pre + "norm1", hs, ehs)
        x = torch.cat([ne, nh], dim=1)
        B, N, _ = x.shape
        q = lin(w, x, pre + "attn1.to_q").view(B, -1, heads, hd).transpose(1, 2)
        k = lin(w, x, pre + "attn1.to_k").view(B, -1, heads, hd).transpose(1, 2)
        v = lin(w, x, pre + "attn1.to_v").view(B, -1, heads, hd).transpose(1, 2)
        q = ln(w, q, pre + "attn1.norm_q", qk_eps)
        k = ln(w, k, pre + "attn1.norm_k", qk_eps)
        q[:, :, L:] = apply_rope(q[:, :, L:], *rope)
        k[:, :, L:] = apply_rope(k[:, :, L:], *rope)
        a = torch.softmax(q @ k.transpose(-1, -2) / math.sqrt(hd), dim=-1) @ v
        a = lin(w, a.transpose(1, 2).reshape(B, -1, heads * hd), pre + "attn1.to_out.0")
        ea, ha = a.split([L, N - L], dim=1)
        hs = hs + g * ha
        ehs = ehs + eg * ea
        nh, ne, g, eg = norm_zero(pre + "norm2", hs, ehs)
        x = torch.cat([ne, nh], dim=1)
        ff = lin(w, F.gelu(lin(w, x, pre + "ff.net.0.proj"), approximate="tanh"), pre + "ff.net.2")
        return hs + g * ff[:, L:], ehs + eg * ff[:, :L]

    def embed(w, latents, text):
        B, Fr, C, H, W = latents.shape
        t = lin(w, text, "patch_embed.text_proj")
        x = F.conv2d(latents.reshape(-1, C, H, W), w["patch_embed.proj.weight"],
                     w["patch_embed.proj.bias"], stride=p)
        x = x.view(B, Fr, *x.shape[1:]).flatten(3).transpose(2, 3).flatten(1, 2)
        e = torch.cat([t, x], dim=1) + w["patch_embed.pos_embedding"]
        L = text.shape[1]
        return e[:, L:], e[:, :L]

    with torch.no_grad():
        noisy, image, cond = inp["noisy"], inp["image"], inp["cond"]
        text, ts = inp["text"], inp["timesteps"]
        B, Fr, C, H, W = noisy.shape
        rope = rope_3d(Fr, H // p, W // p)
        # Branch (CogvideoXBranchModel / CogVideoXWarpEncoder forward).
        temb = time_embed(branch, ts)
        hs, ehs = embed(branch, torch.cat([noisy, cond], dim=2), text)
        samples = []
        for i in range(cfg["branch_layers"]):
            hs, ehs = block(branch, "transformer_blocks.%d." % i, hs, ehs, temb, rope)
            samples.append(lin(branch, hs, "branch_blocks.%d" % i) * cfg["scale"])
        # Backbone with injection after each block.
        temb = time_embed(backbone, ts)
        hs, ehs = embed(backbone, torch.cat([noisy, image], dim=2), text)
        interval = int(math.ceil(layers / len(samples)))
        for i in range(layers):
            hs, ehs = block(backbone, "transformer_blocks.%d." % i, hs, ehs, temb, rope)
            hs = hs + samples[i // interval]
        L = ehs.shape[1]
        hs = ln(backbone, torch.cat([ehs, hs], dim=1), "norm_final", eps)[:, L:]
        shift, scale = lin(backbone, F.silu(temb), "norm_out.linear").chunk(2, dim=1)
        hs = ln(backbone, hs, "norm_out.norm", eps) * (1 + scale)[:, None, :] + shift[:, None, :]
        hs = lin(backbone, hs, "proj_out")
        out = hs.reshape(B, Fr, H // p, W // p, -1, p, p)
        out = out.permute(0, 1, 4, 2, 5, 3, 6).flatten(5, 6).flatten(3, 4)
        for v in out.reshape(-1).tolist():
            print(repr(v))


if __name__ == "__main__":
    main()
