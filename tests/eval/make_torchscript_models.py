#!/usr/bin/python3
"""Small deterministic TorchScript stand-ins for the deep-metric networks, and
the features PyTorch computes with them (run by tests/eval/deep_metrics_test.cc
with Debian's /usr/bin/python3 and python3-torch).

    make_torchscript_models.py DIR [KIND:MODEL:FOLDER:OUT.npy ...]

writes DIR/*.pt with the I/O contract of the real models (docs/EVAL.md):
  inception_like.pt  x [N,3,299,299] in [-1,1] -> [ [N,16,1,1] ] (a list, as
                     pytorch-fid's InceptionV3 returns a list of blocks)
  i3d_like.pt        forward(x [N,3,T,224,224], rescale=True, resize=True,
                     return_features=False) -> [N,400], like i3d_torchscript.pt:
                     features only with return_features=True, and it rescales /
                     resizes itself unless told not to
  i3d_small.pt       the same with 4 features (FVD needs more clips than
                     feature dimensions: a CLI test with a few clips)
  lpips_like.pt      (x, y) [N,3,H,W] in [-1,1] -> [N,1,1,1]
  bad_output.pt      x -> a 1-D tensor (a wrong output shape)
and then, for each job, the float64 features (KIND fid or fvd: FOLDER holds
one frame folder per clip, PNGs) or LPIPS distances (lpips: FOLDER/a and
FOLDER/b hold the frame pairs) that the saved model gives with the
preprocessing of pytorch-fid, common_metrics_on_video_quality and lpips,
written here from those projects' code, independently of the C++
implementation.
"""

import math
import os
import sys

import numpy as np
import torch
import torch.nn.functional as F
from PIL import Image


class InceptionLike(torch.nn.Module):
    def __init__(self):
        super().__init__()
        self.conv1 = torch.nn.Conv2d(3, 8, kernel_size=5, stride=4)
        self.conv2 = torch.nn.Conv2d(8, 16, kernel_size=3, stride=2)

    def forward(self, x):
        x = F.relu(self.conv1(x))
        x = self.conv2(x)
        return [10 * F.adaptive_avg_pool2d(x, (1, 1))]


class I3dLike(torch.nn.Module):
    def __init__(self, features=400):
        super().__init__()
        self.conv1 = torch.nn.Conv3d(3, 8, kernel_size=(3, 7, 7),
                                     stride=(1, 4, 4))
        self.conv2 = torch.nn.Conv3d(8, 16, kernel_size=3, stride=2)
        self.fc = torch.nn.Linear(16, features)

    def forward(self, x, rescale: bool = True, resize: bool = True,
                return_features: bool = False):
        if rescale:  # the real model maps [0, 255] to [-1, 1] here
            x = x / 127.5 - 1
        if resize:
            x = F.interpolate(x, size=(x.shape[2], 224, 224),
                              mode='trilinear', align_corners=False)
        x = F.relu(self.conv1(x))
        x = F.relu(self.conv2(x))
        x = F.adaptive_avg_pool3d(x, 1).flatten(1)
        logits = 10 * self.fc(x)
        if return_features:
            return logits
        return F.softmax(logits, dim=1)


class LpipsLike(torch.nn.Module):
    def __init__(self):
        super().__init__()
        self.conv = torch.nn.Conv2d(3, 8, kernel_size=3, stride=2)
        self.lin = torch.nn.Conv2d(8, 1, kernel_size=1, bias=False)
        with torch.no_grad():
            self.lin.weight.abs_()

    def forward(self, x, y):
        fx = F.relu(self.conv(x))
        fy = F.relu(self.conv(y))
        nx = fx / (torch.sqrt(torch.sum(fx ** 2, dim=1, keepdim=True)) + 1e-10)
        ny = fy / (torch.sqrt(torch.sum(fy ** 2, dim=1, keepdim=True)) + 1e-10)
        return self.lin((nx - ny) ** 2).mean([2, 3], keepdim=True)


class BadOutput(torch.nn.Module):
    def forward(self, x):
        return x.flatten()[:5]


def load_frames(folder):
    """uint8 frames of a frame folder, sorted by file name (PIL, RGB)."""
    names = sorted(n for n in os.listdir(folder) if n.endswith('.png'))
    return [np.asarray(Image.open(os.path.join(folder, n)).convert('RGB'))
            for n in names]


def to_tensor(frame):
    """torchvision ToTensor: HWC uint8 -> CHW float32 / 255."""
    return torch.from_numpy(frame.copy()).permute(2, 0, 1).float().div(255)


def subfolders(folder):
    return [os.path.join(folder, d) for d in sorted(os.listdir(folder))]


def fid_features(model, folder):
    """pytorch-fid: InceptionV3(resize_input=True, normalize_input=True)."""
    feats = []
    for clip in subfolders(folder):
        for frame in load_frames(clip):
            x = to_tensor(frame).unsqueeze(0)
            x = F.interpolate(x, size=(299, 299), mode='bilinear',
                              align_corners=False)
            x = 2 * x - 1
            feats.append(model(x)[0].squeeze(3).squeeze(2))
    return torch.cat(feats, 0)


def preprocess_single(video, resolution=224):
    """common_metrics_on_video_quality fvd/styleganv/fvd.py (C,T,H,W in
    [0,1])."""
    c, t, h, w = video.shape
    scale = resolution / min(h, w)
    if h < w:
        target_size = (resolution, math.ceil(w * scale))
    else:
        target_size = (math.ceil(h * scale), resolution)
    video = F.interpolate(video, size=target_size, mode='bilinear',
                          align_corners=False)
    c, t, h, w = video.shape
    w_start = (w - resolution) // 2
    h_start = (h - resolution) // 2
    video = video[:, :, h_start:h_start + resolution,
                  w_start:w_start + resolution]
    video = (video - 0.5) * 2
    return video.contiguous()


def fvd_features(model, folder):
    feats = []
    for clip in subfolders(folder):
        video = torch.stack([to_tensor(f) for f in load_frames(clip)], 0)
        video = video.permute(1, 0, 2, 3)  # TCHW -> CTHW
        x = torch.stack([preprocess_single(video)])
        feats.append(model(x, rescale=False, resize=False,
                           return_features=True))
    return torch.cat(feats, 0)


def lpips_distances(model, folder):
    a = load_frames(os.path.join(folder, 'a'))
    b = load_frames(os.path.join(folder, 'b'))
    out = []
    for fa, fb in zip(a, b):
        x = to_tensor(fa).unsqueeze(0) * 2 - 1
        y = to_tensor(fb).unsqueeze(0) * 2 - 1
        out.append(model(x, y).mean().item())
    return torch.tensor(out, dtype=torch.float64)


def main():
    root = sys.argv[1]
    torch.manual_seed(0)
    torch.set_num_threads(1)
    os.makedirs(root, exist_ok=True)
    models = {
        'inception_like': InceptionLike(),
        'i3d_like': I3dLike(),
        'i3d_small': I3dLike(features=4),
        'lpips_like': LpipsLike(),
        'bad_output': BadOutput(),
    }
    for name, m in models.items():
        torch.jit.script(m.eval()).save(os.path.join(root, name + '.pt'))
    # Jobs KIND:MODEL:FOLDER:OUT.npy, run on the saved (reloaded) models.
    compute = {'fid': fid_features, 'fvd': fvd_features,
               'lpips': lpips_distances}
    with torch.no_grad():
        for job in sys.argv[2:]:
            kind, model, folder, out = job.split(':')
            m = torch.jit.load(os.path.join(root, model + '.pt'))
            t = compute[kind](m, folder)
            np.save(out, t.double().numpy())
            print(kind, model, folder, tuple(t.shape))


if __name__ == '__main__':
    main()
