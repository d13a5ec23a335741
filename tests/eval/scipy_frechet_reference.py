#!/usr/bin/python3
"""pytorch-fid's Fréchet distance (scipy.linalg.sqrtm route) for tests/eval/frechet_test.cc.

usage: scipy_frechet_reference.py FEATS1.npy FEATS2.npy   (N x D float64 each)
Prints the distance with mu = mean, sigma = np.cov(rowvar=False), exactly as
pytorch_fid.fid_score.calculate_frechet_distance (eps retry, real part).
"""
import sys

import numpy as np
from scipy import linalg

f1 = np.load(sys.argv[1])
f2 = np.load(sys.argv[2])
mu1, mu2 = f1.mean(axis=0), f2.mean(axis=0)
s1, s2 = np.cov(f1, rowvar=False), np.cov(f2, rowvar=False)
diff = mu1 - mu2
covmean, _ = linalg.sqrtm(s1.dot(s2), disp=False)
if not np.isfinite(covmean).all():
    offset = np.eye(s1.shape[0]) * 1e-6
    covmean = linalg.sqrtm((s1 + offset).dot(s2 + offset))
if np.iscomplexobj(covmean):
    covmean = covmean.real
print("%.17g" % (diff.dot(diff) + np.trace(s1) + np.trace(s2) - 2 * np.trace(covmean)))
