#!/usr/bin/env python3
"""PyTorch peer of the candle bench `rgb_dense_step_32x64_w128`
(crates/synthgen-train/benches/rgb_dense_step.rs).

The same dense RGB model as crates/synthgen-train/src/models/rgb_dense.rs: 3x3 convolutions
3->32->64->128 (stride 2, padding 1, ReLU) on 64x64 crops, a 3x3 one at 1/8 (128), a global feature
(the flattened 8x8x128 map through a fully connected layer of 128, ReLU), a x2 nearest upsampling
concatenated with the 1/4 map and a 3x3 convolution (->64) to which the global feature's bias-free
projection is added before the ReLU, a 1x1 head of 4 outputs per class (8 classes: coordinates and a
visibility logit) picked by the crop's class, and on the global feature a quaternion head (normalized
after adding (1, 0, 0, 0)) and a 3-output translation head per class. Loss = the coordinates' L1
(x, y, z summed) averaged over the visible cells (half of them) + the visibility's binary
cross-entropy averaged over all cells + the mean point distance between R(q) x and the target points
(100 points) + smooth L1 (beta 0.1) of the translation summed over its 3 outputs; AdamW (lr 1e-3,
weight decay 0.01 = candle's ParamsAdamW default). One step = forward, loss, backward, optimizer step,
reading the loss back, on 32 crops already in memory (the candle bench also cuts, jitters and augments
the crops and cuts the targets each step).

Usage: python3 benches/peers/rgb_dense_torch.py [--threads N] [--steps 30] [--warmup 5]
Prints one JSON line: {"peer": "pytorch", "median_ms": ..., "predict_ms_per_crop": ...} (the
prediction time is the network only: no PnP). CPU only. Never run in CI: it needs torch
(benches/peers/setup_torch.sh installs it into benches/peers/.venv-torch).
"""
import argparse
import json
import statistics
import time

import torch
from torch import nn

from rgb_torch import quat_to_matrix, smooth_l1  # the RGB model's peer, same folder

CLASSES = 8


class DenseNet(nn.Module):
    def __init__(self, width: int = 128, crop: int = 64):
        super().__init__()
        self.enc = nn.ModuleList(
            [nn.Conv2d(3, 32, 3, 2, 1), nn.Conv2d(32, 64, 3, 2, 1), nn.Conv2d(64, 128, 3, 2, 1)]
        )
        self.mid = nn.Conv2d(128, 128, 3, 1, 1)
        side = crop // 8
        self.glob = nn.Linear(128 * side * side, width)
        self.glob2 = nn.Linear(width, 64, bias=False)
        self.dec2 = nn.Conv2d(128 + 64, 64, 3, 1, 1)
        self.head = nn.Conv2d(64, CLASSES * 4, 1)
        self.rot = nn.Linear(width, CLASSES * 4)
        self.trans = nn.Linear(width, CLASSES * 3)

    def forward(self, crops, cls):
        e1 = torch.relu(self.enc[0](crops))
        e2 = torch.relu(self.enc[1](e1))
        e3 = torch.relu(self.enc[2](e2))
        m = torch.relu(self.mid(e3))
        g = torch.relu(self.glob(m.flatten(1)))
        x = torch.cat([nn.functional.interpolate(m, scale_factor=2, mode="nearest"), e2], 1)
        d = torch.relu(self.dec2(x) + self.glob2(g)[:, :, None, None])
        b, _, s, _ = d.shape
        out = self.head(d).reshape(b, CLASSES, 4, s, s)[torch.arange(b), cls]
        q = self.rot(g).reshape(b, CLASSES, 4)[torch.arange(b), cls] + torch.tensor([1.0, 0.0, 0.0, 0.0])
        q = q / (q.square().sum(-1, keepdim=True) + 1e-12).sqrt()
        t = self.trans(g).reshape(b, CLASSES, 3)[torch.arange(b), cls]
        return out[:, :3], out[:, 3], q, t


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--warmup", type=int, default=5)
    args = ap.parse_args()
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    b, crop, width, m = 32, 64, 128, 100
    s = crop // 4
    crops = torch.randn(b, 3, crop, crop)
    cls = torch.arange(b) % CLASSES
    coords_t = torch.rand(b, 3, s, s) - 0.5
    visible = (torch.rand(b, s, s) < 0.5).float()
    t_target = torch.randn(b, 3)
    pts = torch.rand(b, m, 3) - 0.5
    r_target = pts @ quat_to_matrix(nn.functional.normalize(torch.randn(b, 4), dim=-1)).transpose(1, 2)
    net = DenseNet(width, crop)
    opt = torch.optim.AdamW(net.parameters(), lr=1e-3, weight_decay=0.01)
    bce = nn.BCEWithLogitsLoss()
    times = []
    for i in range(args.warmup + args.steps):
        t0 = time.perf_counter()
        opt.zero_grad(set_to_none=True)
        coords, logits, q, t = net(crops, cls)
        l1 = ((coords - coords_t).abs().sum(1) * visible).sum() / visible.sum().clamp(min=1.0)
        posed = pts @ quat_to_matrix(q).transpose(1, 2)
        rot = ((posed - r_target).square().sum(-1) + 1e-12).sqrt().mean()
        loss = l1 + bce(logits, visible) + rot + smooth_l1(t - t_target)
        loss.backward()
        opt.step()
        loss.item()
        dt = time.perf_counter() - t0
        if i >= args.warmup:
            times.append(dt)
    crops64, cls64 = torch.randn(64, 3, crop, crop), torch.arange(64) % CLASSES
    pred = []
    with torch.no_grad():
        for i in range(args.warmup + args.steps):
            t0 = time.perf_counter()
            net(crops64, cls64)
            if i >= args.warmup:
                pred.append(time.perf_counter() - t0)
    print(json.dumps({
        "peer": "pytorch",
        "torch": torch.__version__,
        "threads": torch.get_num_threads(),
        "steps": args.steps,
        "median_ms": 1000 * statistics.median(times),
        "min_ms": 1000 * min(times),
        "predict_ms_per_crop": 1000 * statistics.median(pred) / 64,
        "final_loss": float(loss),
    }))


if __name__ == "__main__":
    main()
