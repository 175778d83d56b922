#!/usr/bin/env python3
"""PyTorch peer of the candle bench `rgb_step_32x64_w256` (crates/synthgen-train/benches/rgb_step.rs).

The same RGB model as crates/synthgen-train/src/models/rgb.rs: four 3x3 stride-2 convolutions
3->32->64->128->128 with padding 1 and ReLU on 64x64 crops, a fully connected layer on the flattened
4x4x128 map plus a bias-free term of the 3 box-geometry inputs (ReLU), a second one (ReLU), one head of
7 outputs per class (5 classes) picked by the crop's class; the quaternion normalized after adding
(1, 0, 0, 0); loss = smooth L1 (beta 0.1) on the 3 translation outputs summed, + 4 x the mean point
distance between R(q) x and the target points (100 points, one symmetry); AdamW (lr 1e-3, weight decay
0.01 = candle's ParamsAdamW default). One step = forward, loss, backward, optimizer step, reading the
loss back, on 32 crops already in memory (the candle bench also cuts and jitters the crops from their
stored regions each step, ~1 ms of its time).

Usage: python3 benches/peers/rgb_torch.py [--threads N] [--steps 30] [--warmup 5]
Prints one JSON line: {"peer": "pytorch", "median_ms": ..., "predict_ms_per_crop": ...}. CPU only. Never
run in CI: it needs torch (benches/peers/setup_torch.sh installs it into benches/peers/.venv-torch).
"""
import argparse
import json
import statistics
import time

import torch
from torch import nn

CLASSES = 5


class RgbNet(nn.Module):
    def __init__(self, width: int = 256, crop: int = 64):
        super().__init__()
        chans = [3, 32, 64, 128, 128]
        self.convs = nn.ModuleList(
            nn.Conv2d(chans[i], chans[i + 1], 3, stride=2, padding=1) for i in range(4)
        )
        side = crop
        for _ in range(4):
            side = (side + 1) // 2
        self.fc1 = nn.Linear(128 * side * side, width)
        self.fc1_geom = nn.Linear(3, width, bias=False)
        self.fc2 = nn.Linear(width, width)
        self.head = nn.Linear(width, CLASSES * 7)

    def forward(self, crops, geom, cls):
        x = crops
        for c in self.convs:
            x = torch.relu(c(x))
        h = torch.relu(self.fc1(x.flatten(1)) + self.fc1_geom(geom))
        h = torch.relu(self.fc2(h))
        out = self.head(h).reshape(-1, CLASSES, 7)
        out = out[torch.arange(out.shape[0]), cls]
        q = out[:, 3:] + torch.tensor([1.0, 0.0, 0.0, 0.0])
        q = q / (q.square().sum(-1, keepdim=True) + 1e-12).sqrt()
        return out[:, :3], q


def quat_to_matrix(q):
    w, x, y, z = q.unbind(-1)
    return torch.stack(
        [
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ],
        -1,
    ).reshape(*q.shape[:-1], 3, 3)


def smooth_l1(d, beta=0.1):
    a = d.abs()
    m = a.clamp(max=beta)
    return (0.5 * m * m / beta + (a - m)).sum(-1).mean()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--warmup", type=int, default=5)
    args = ap.parse_args()
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    b, crop, width, m = 32, 64, 256, 100
    crops = torch.randn(b, 3, crop, crop)
    geom = torch.rand(b, 3) * 0.2
    cls = torch.arange(b) % CLASSES
    t_target = torch.randn(b, 3)
    pts = (torch.rand(b, m, 3) - 0.5)
    r_target = pts @ quat_to_matrix(nn.functional.normalize(torch.randn(b, 4), dim=-1)).transpose(1, 2)
    net = RgbNet(width, crop)
    opt = torch.optim.AdamW(net.parameters(), lr=1e-3, weight_decay=0.01)
    times = []
    for i in range(args.warmup + args.steps):
        t0 = time.perf_counter()
        opt.zero_grad(set_to_none=True)
        t, q = net(crops, geom, cls)
        posed = pts @ quat_to_matrix(q).transpose(1, 2)
        rot = ((posed - r_target).square().sum(-1) + 1e-12).sqrt().mean()
        loss = smooth_l1(t - t_target) + 4.0 * rot
        loss.backward()
        opt.step()
        loss.item()
        dt = time.perf_counter() - t0
        if i >= args.warmup:
            times.append(dt)
    # Predictions: 64 crops per batch, no gradients.
    crops64 = torch.randn(64, 3, crop, crop)
    geom64, cls64 = torch.rand(64, 3) * 0.2, torch.arange(64) % CLASSES
    pred = []
    with torch.no_grad():
        for i in range(args.warmup + args.steps):
            t0 = time.perf_counter()
            net(crops64, geom64, cls64)
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
