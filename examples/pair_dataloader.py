#!/usr/bin/python3
"""A DataLoader over built pairs, in the layout GeoDrive's trainer uses.

    PYTHONPATH=build/python /usr/bin/python3 examples/pair_dataloader.py \
        /tmp/geodrive_demo/pairs/manifest.jsonl

(the demo's pairs: `bash scripts/demo.sh /tmp/geodrive_demo`). Prints one
batch's shapes and value range.
"""
import sys

import torch

from geodrive.torch import PairDataset

manifest = sys.argv[1] if len(sys.argv) > 1 else "/tmp/geodrive_demo/pairs/manifest.jsonl"

# 25 built frames padded to 49 (CogVideoX's clip length) and resized to the
# trainer's 480x720, in [-1, 1].
dataset = PairDataset(manifest, frames=49, size=(480, 720))
loader = torch.utils.data.DataLoader(dataset, batch_size=min(2, len(dataset)),
                                     shuffle=False, num_workers=2)

batch = next(iter(loader))
print(len(dataset), "pairs in", manifest)
for key in ("gt", "cond"):
    x = batch[key]
    print(key, x.shape, x.dtype, "range [%.3f, %.3f]" % (x.min(), x.max()))
print("clip ids", list(batch["meta"]["clip_id"]))
