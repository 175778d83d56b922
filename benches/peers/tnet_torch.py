#!/usr/bin/env python3
"""PyTorch peer of the candle bench `tnet_step_32x500_w128` (crates/synthgen-train/benches/tnet_step.rs).

The same TNet as crates/synthgen-train/src/models/tnet.rs: per point 3->64->128->width (ReLU), global
max-pool, head W_p f2 + W_g g (no bias on the global term) -> ReLU -> 128->64->3; L1 offset loss summed over
x, y, z and averaged over points; AdamW (lr 1e-3, weight decay 0.01 = candle's ParamsAdamW default).
One step = forward, loss, backward, optimizer step, reading the loss back (as the candle bench does).

Usage: python3 benches/peers/tnet_torch.py [--threads N] [--steps 30] [--warmup 5]
Prints one JSON line: {"peer": "pytorch", "median_ms": ..., ...}. CPU only. Never run in CI: it needs torch
(benches/peers/setup_torch.sh installs it into benches/peers/.venv-torch).
"""
import argparse
import json
import statistics
import time

import torch
from torch import nn


class TNet(nn.Module):
    def __init__(self, width: int = 128):
        super().__init__()
        self.l1 = nn.Linear(3, 64)
        self.l2 = nn.Linear(64, 128)
        self.l3 = nn.Linear(128, width)
        self.h1_point = nn.Linear(128, 128)
        self.h1_global = nn.Linear(width, 128, bias=False)
        self.h2 = nn.Linear(128, 64)
        self.h3 = nn.Linear(64, 3)

    def forward(self, x):
        b, n, _ = x.shape
        x = x.reshape(b * n, 3)
        f1 = torch.relu(self.l1(x))
        f2 = torch.relu(self.l2(f1))
        f3 = torch.relu(self.l3(f2))
        g = f3.reshape(b, n, -1).amax(dim=1)
        hg = self.h1_global(g).unsqueeze(1)
        hp = self.h1_point(f2).reshape(b, n, 128)
        h = torch.relu(hp + hg).reshape(b * n, 128)
        h = torch.relu(self.h2(h))
        return self.h3(h).reshape(b, n, 3)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--warmup", type=int, default=5)
    args = ap.parse_args()
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    b, n, width = 32, 500, 128
    # Points as the candle bench draws them (uniform box), centred and scaled by 10.
    pts = torch.empty(b, n, 3)
    pts[..., 0:2].uniform_(-0.1, 0.1)
    pts[..., 2].uniform_(0.6, 0.9)
    mean = pts.mean(dim=1, keepdim=True)
    x = (pts - mean) * 10.0
    centre = torch.tensor([0.0, 0.0, 0.75]).reshape(1, 1, 3)
    target = (centre - mean) * 10.0 - x
    net = TNet(width)
    opt = torch.optim.AdamW(net.parameters(), lr=1e-3, weight_decay=0.01)
    times = []
    for i in range(args.warmup + args.steps):
        t0 = time.perf_counter()
        opt.zero_grad(set_to_none=True)
        loss = (net(x) - target).abs().sum(-1).mean()
        loss.backward()
        opt.step()
        loss.item()
        dt = time.perf_counter() - t0
        if i >= args.warmup:
            times.append(dt)
    print(json.dumps({
        "peer": "pytorch",
        "torch": torch.__version__,
        "threads": torch.get_num_threads(),
        "steps": args.steps,
        "median_ms": 1000 * statistics.median(times),
        "min_ms": 1000 * min(times),
        "final_loss": float(loss),
    }))


if __name__ == "__main__":
    main()
