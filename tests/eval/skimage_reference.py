#!/usr/bin/python3
"""Reference PSNR/SSIM with Debian's python3-skimage for tests/eval/image_metrics_test.cc.

usage: skimage_reference.py A.npy B.npy [luma]
A and B are uint8 (H, W, 3) or (H, W) arrays, or float64. Prints "psnr ssim" (data_range 255).
With "luma", both are first converted to full-range BT.601 Y in float64.
"""
import sys

import numpy as np
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

a = np.load(sys.argv[1])
b = np.load(sys.argv[2])
if len(sys.argv) > 3 and sys.argv[3] == "luma":
    w = np.array([0.299, 0.587, 0.114])
    a = a.astype(np.float64) @ w
    b = b.astype(np.float64) @ w
kw = dict(gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=255)
if a.ndim == 3:
    kw["channel_axis"] = -1
ssim = structural_similarity(a, b, **kw)
psnr = peak_signal_noise_ratio(a, b, data_range=255)
print("%.17g %.17g" % (psnr, ssim))
