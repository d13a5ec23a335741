"""Independent reference of diffusers' AutoencoderKLCogVideoX (CogVideoX's 3D causal VAE), written
after the diffusers module code (autoencoder_kl_cogvideox.py: CogVideoXCausalConv3d,
CogVideoXSpatialNorm3D, CogVideoXResnetBlock3D, CogVideoXDown/Mid/UpBlock3D, CogVideoXEncoder3D,
CogVideoXDecoder3D, the framewise `_encode` / `_decode` loops; downsampling.py CogVideoXDownsample3D;
upsampling.py CogVideoXUpsample3D) as nn.Modules, with plain torch 1.13 (Debian python3-torch).
The state-dict names therefore come from the module tree, as in diffusers.

usage:
  vae_reference.py names CONFIG_JSON                 prints "name shape..." per parameter, in order
  vae_reference.py encode CONFIG_JSON WEIGHTS INPUT  prints the latent mean, one float per line
  vae_reference.py decode CONFIG_JSON WEIGHTS INPUT  prints the decoded video, one float per line
WEIGHTS: safetensors with the state dict; INPUT: safetensors with tensor "x".
CONFIG_JSON: {"in_channels", "latent_channels", "block_out_channels", "layers_per_block",
"norm_num_groups", "temporal_compression_ratio"}.
"""
import json
import math
import struct
import sys

import torch
import torch.nn as nn
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


class CausalConv3d(nn.Module):
    def __init__(self, cin, cout, k):
        super().__init__()
        self.k = k
        self.pad = (k - 1) // 2
        self.conv = nn.Conv3d(cin, cout, k)

    def forward(self, x, cache=None):
        if self.k > 1:
            cached = [cache] if cache is not None else [x[:, :, :1]] * (self.k - 1)
            x = torch.cat(cached + [x], dim=2)
        new_cache = x[:, :, -self.k + 1:].clone()
        x = F.pad(x, (self.pad, self.pad, self.pad, self.pad), mode="constant", value=0)
        return self.conv(x), new_cache


class SpatialNorm3D(nn.Module):
    def __init__(self, f, zq, groups):
        super().__init__()
        self.norm_layer = nn.GroupNorm(num_channels=f, num_groups=groups, eps=1e-6, affine=True)
        self.conv_y = CausalConv3d(zq, f, 1)
        self.conv_b = CausalConv3d(zq, f, 1)

    def forward(self, f, zq, cache):
        cache = cache or {}
        new = {}
        if f.shape[2] > 1 and f.shape[2] % 2 == 1:
            z_first = F.interpolate(zq[:, :, :1], size=f[:, :, :1].shape[-3:])
            z_rest = F.interpolate(zq[:, :, 1:], size=f[:, :, 1:].shape[-3:])
            zq = torch.cat([z_first, z_rest], dim=2)
        else:
            zq = F.interpolate(zq, size=f.shape[-3:])
        y, new["conv_y"] = self.conv_y(zq, cache.get("conv_y"))
        b, new["conv_b"] = self.conv_b(zq, cache.get("conv_b"))
        return self.norm_layer(f) * y + b, new


class Resnet(nn.Module):
    def __init__(self, cin, cout, groups, eps, zq_dim=None):
        super().__init__()
        self.cin, self.cout = cin, cout
        if zq_dim is None:
            self.norm1 = nn.GroupNorm(num_channels=cin, num_groups=groups, eps=eps)
            self.norm2 = nn.GroupNorm(num_channels=cout, num_groups=groups, eps=eps)
        else:
            self.norm1 = SpatialNorm3D(cin, zq_dim, groups)
            self.norm2 = SpatialNorm3D(cout, zq_dim, groups)
        self.conv1 = CausalConv3d(cin, cout, 3)
        self.conv2 = CausalConv3d(cout, cout, 3)
        if cin != cout:
            self.conv_shortcut = nn.Conv3d(cin, cout, kernel_size=1, stride=1, padding=0)

    def forward(self, x, zq, cache):
        cache = cache or {}
        new = {}
        h = x
        if zq is not None:
            h, new["norm1"] = self.norm1(h, zq, cache.get("norm1"))
        else:
            h = self.norm1(h)
        h = F.silu(h)
        h, new["conv1"] = self.conv1(h, cache.get("conv1"))
        if zq is not None:
            h, new["norm2"] = self.norm2(h, zq, cache.get("norm2"))
        else:
            h = self.norm2(h)
        h = F.silu(h)
        h, new["conv2"] = self.conv2(h, cache.get("conv2"))
        if self.cin != self.cout:
            x = self.conv_shortcut(x)
        return h + x, new


class Downsample3D(nn.Module):
    def __init__(self, c, compress_time):
        super().__init__()
        self.conv = nn.Conv2d(c, c, kernel_size=3, stride=2, padding=0)
        self.compress_time = compress_time

    def forward(self, x):
        if self.compress_time:
            b, c, t, h, w = x.shape
            x = x.permute(0, 3, 4, 1, 2).reshape(b * h * w, c, t)
            if x.shape[-1] % 2 == 1:
                x_first, x_rest = x[..., 0], x[..., 1:]
                if x_rest.shape[-1] > 0:
                    x_rest = F.avg_pool1d(x_rest, kernel_size=2, stride=2)
                x = torch.cat([x_first[..., None], x_rest], dim=-1)
            else:
                x = F.avg_pool1d(x, kernel_size=2, stride=2)
            x = x.reshape(b, h, w, c, x.shape[-1]).permute(0, 3, 4, 1, 2)
        x = F.pad(x, (0, 1, 0, 1), mode="constant", value=0)
        b, c, t, h, w = x.shape
        x = x.permute(0, 2, 1, 3, 4).reshape(b * t, c, h, w)
        x = self.conv(x)
        return x.reshape(b, t, x.shape[1], x.shape[2], x.shape[3]).permute(0, 2, 1, 3, 4)


class Upsample3D(nn.Module):
    def __init__(self, c, compress_time):
        super().__init__()
        self.conv = nn.Conv2d(c, c, kernel_size=3, stride=1, padding=1)
        self.compress_time = compress_time

    def forward(self, x):
        if self.compress_time:
            if x.shape[2] > 1 and x.shape[2] % 2 == 1:
                x_first, x_rest = x[:, :, 0], x[:, :, 1:]
                x_first = F.interpolate(x_first, scale_factor=2.0)
                x_rest = F.interpolate(x_rest, scale_factor=2.0)
                x = torch.cat([x_first[:, :, None, :, :], x_rest], dim=2)
            elif x.shape[2] > 1:
                x = F.interpolate(x, scale_factor=2.0)
            else:
                x = F.interpolate(x.squeeze(2), scale_factor=2.0)[:, :, None, :, :]
        else:
            b, c, t, h, w = x.shape
            x = x.permute(0, 2, 1, 3, 4).reshape(b * t, c, h, w)
            x = F.interpolate(x, scale_factor=2.0)
            x = x.reshape(b, t, c, *x.shape[2:]).permute(0, 2, 1, 3, 4)
        b, c, t, h, w = x.shape
        x = x.permute(0, 2, 1, 3, 4).reshape(b * t, c, h, w)
        x = self.conv(x)
        return x.reshape(b, t, *x.shape[1:]).permute(0, 2, 1, 3, 4)


class Block(nn.Module):
    """CogVideoXDownBlock3D / CogVideoXMidBlock3D / CogVideoXUpBlock3D."""

    def __init__(self, cin, cout, layers, groups, eps, zq_dim=None, down=None, up=None):
        super().__init__()
        self.resnets = nn.ModuleList(
            [Resnet(cin if i == 0 else cout, cout, groups, eps, zq_dim) for i in range(layers)])
        if down is not None:
            self.downsamplers = nn.ModuleList([Downsample3D(cout, down)])
        if up is not None:
            self.upsamplers = nn.ModuleList([Upsample3D(cout, up)])

    def forward(self, x, zq, cache):
        cache = cache or {}
        new = {}
        for i, r in enumerate(self.resnets):
            x, new[f"resnet_{i}"] = r(x, zq, cache.get(f"resnet_{i}"))
        for m in getattr(self, "downsamplers", []):
            x = m(x)
        for m in getattr(self, "upsamplers", []):
            x = m(x)
        return x, new


class Encoder(nn.Module):
    def __init__(self, cfg):
        super().__init__()
        ch, g, L = cfg["block_out_channels"], cfg["norm_num_groups"], cfg["layers_per_block"]
        level = int(math.log2(cfg["temporal_compression_ratio"]))
        self.conv_in = CausalConv3d(cfg["in_channels"], ch[0], 3)
        self.down_blocks = nn.ModuleList()
        out = ch[0]
        for i in range(len(ch)):
            inp, out = out, ch[i]
            last = i == len(ch) - 1
            self.down_blocks.append(Block(inp, out, L, g, 1e-6,
                                          down=None if last else (i < level)))
        self.mid_block = Block(ch[-1], ch[-1], 2, g, 1e-6)
        self.norm_out = nn.GroupNorm(g, ch[-1], eps=1e-6)
        self.conv_out = CausalConv3d(ch[-1], 2 * cfg["latent_channels"], 3)

    def forward(self, x, cache=None):
        cache = cache or {}
        new = {}
        h, new["conv_in"] = self.conv_in(x, cache.get("conv_in"))
        for i, b in enumerate(self.down_blocks):
            h, new[f"down_block_{i}"] = b(h, None, cache.get(f"down_block_{i}"))
        h, new["mid_block"] = self.mid_block(h, None, cache.get("mid_block"))
        h = F.silu(self.norm_out(h))
        h, new["conv_out"] = self.conv_out(h, cache.get("conv_out"))
        return h, new


class Decoder(nn.Module):
    def __init__(self, cfg):
        super().__init__()
        ch = list(reversed(cfg["block_out_channels"]))
        g, L, zc = cfg["norm_num_groups"], cfg["layers_per_block"], cfg["latent_channels"]
        level = int(math.log2(cfg["temporal_compression_ratio"]))
        self.conv_in = CausalConv3d(zc, ch[0], 3)
        self.mid_block = Block(ch[0], ch[0], 2, g, 1e-6, zq_dim=zc)
        self.up_blocks = nn.ModuleList()
        out = ch[0]
        for i in range(len(ch)):
            prev, out = out, ch[i]
            last = i == len(ch) - 1
            self.up_blocks.append(Block(prev, out, L + 1, g, 1e-6, zq_dim=zc,
                                        up=None if last else (i < level)))
        self.norm_out = SpatialNorm3D(ch[-1], zc, g)
        self.conv_out = CausalConv3d(ch[-1], cfg["in_channels"], 3)

    def forward(self, z, cache=None):
        cache = cache or {}
        new = {}
        h, new["conv_in"] = self.conv_in(z, cache.get("conv_in"))
        h, new["mid_block"] = self.mid_block(h, z, cache.get("mid_block"))
        for i, b in enumerate(self.up_blocks):
            h, new[f"up_block_{i}"] = b(h, z, cache.get(f"up_block_{i}"))
        h, new["norm_out"] = self.norm_out(h, z, cache.get("norm_out"))
        h = F.silu(h)
        h, new["conv_out"] = self.conv_out(h, cache.get("conv_out"))
        return h, new


class Vae(nn.Module):
    def __init__(self, cfg):
        super().__init__()
        self.encoder = Encoder(cfg)
        self.decoder = Decoder(cfg)

    # diffusers AutoencoderKLCogVideoX._encode (num_sample_frames_batch_size 8) + latent_dist.mode()
    def encode(self, x, frame_batch_size=8):
        num_frames = x.shape[2]
        num_batches = max(num_frames // frame_batch_size, 1)
        conv_cache = None
        enc = []
        for i in range(num_batches):
            remaining_frames = num_frames % frame_batch_size
            start_frame = frame_batch_size * i + (0 if i == 0 else remaining_frames)
            end_frame = frame_batch_size * (i + 1) + remaining_frames
            h, conv_cache = self.encoder(x[:, :, start_frame:end_frame], conv_cache)
            enc.append(h)
        enc = torch.cat(enc, dim=2)
        mean, _ = torch.chunk(enc, 2, dim=1)
        return mean

    # diffusers AutoencoderKLCogVideoX._decode (num_latent_frames_batch_size 2)
    def decode(self, z, frame_batch_size=2):
        num_frames = z.shape[2]
        num_batches = max(num_frames // frame_batch_size, 1)
        conv_cache = None
        dec = []
        for i in range(num_batches):
            remaining_frames = num_frames % frame_batch_size
            start_frame = frame_batch_size * i + (0 if i == 0 else remaining_frames)
            end_frame = frame_batch_size * (i + 1) + remaining_frames
            h, conv_cache = self.decoder(z[:, :, start_frame:end_frame], conv_cache)
            dec.append(h)
        return torch.cat(dec, dim=2)


def main():
    mode, cfg = sys.argv[1], json.loads(sys.argv[2])
    if mode == "names":
        with _NoInit():
            vae = Vae(cfg)
        for name, p in vae.state_dict().items():
            print(name, *p.shape)
        return
    vae = Vae(cfg)
    vae.load_state_dict(load(sys.argv[3]), strict=True)
    x = load(sys.argv[4])["x"]
    with torch.no_grad():
        out = vae.encode(x) if mode == "encode" else vae.decode(x)
    sys.stdout.write("\n".join(repr(v) for v in out.reshape(-1).tolist()) + "\n")


class _NoInit:
    """Skips the (slow) random initialisation while building the real-size model."""

    def __enter__(self):
        self.saved = (nn.init.kaiming_uniform_, nn.init.uniform_)
        nn.init.kaiming_uniform_ = lambda t, *a, **k: t
        nn.init.uniform_ = lambda t, *a, **k: t
        return self

    def __exit__(self, *exc):
        nn.init.kaiming_uniform_, nn.init.uniform_ = self.saved
        return False


if __name__ == "__main__":
    main()
