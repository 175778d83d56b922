#!/usr/bin/env python3
"""PyTorch peer of the candle bench `detector_step_16x160x120_c8` (crates/synthgen-detect/benches/detector_step.rs).

The same box detector as crates/synthgen-detect/src/net.rs (CenterNet-style centre heatmaps): 3x3
convolutions 3->32->64->128 (stride 2, padding 1, ReLU) on 160x120 frames, two 3x3 ones at 1/8
(128->128, stride 1, ReLU), a x2 nearest upsampling concatenated with the 1/4 map (128 + 64 channels) and
a 3x3 convolution (->64, ReLU), then a 1x1 head of 5 outputs per class (8 classes, LM-O's objects): the
heatmap logit (plus the prior -2.19), the centre's offset in the cell and the box's log width and height,
on the 40x30 map. Loss (`detector_loss`): CenterNet's penalty-reduced focal loss (alpha 2, beta 4; log p
and log(1 - p) as -softplus(-x) and -softplus(x)) over the heatmaps against Gaussian targets, plus the L1
of the 4 regression outputs at the centre cells, both over the number of boxes. Targets as
crates/synthgen-detect/src/detector.rs `targets` builds them (TTFNet's elliptical Gaussian, sigma = 0.09
x the box side in cells, at least half a cell), for every class once per frame, boxes 10 to 50 px. AdamW
(lr 2e-3, weight decay 1e-4, betas 0.9/0.999, eps 1e-8: the detector's `DetectorConfig` defaults). One
step = forward, loss, backward, optimizer step, reading the loss back, on 16 frames and targets already in
memory as tensors (NCHW here, NHWC in candle).

Usage: python3 benches/peers/detector_torch.py [--threads N] [--steps 30] [--warmup 5]
Prints one JSON line: {"peer": "pytorch", "median_ms": ..., ...}. CPU only. Never run in CI: it needs torch
(benches/peers/setup_torch.sh installs it into benches/peers/.venv-torch).
"""
import argparse
import json
import math
import random
import statistics
import time

import torch
from torch import nn
from torch.nn import functional as F

CLASSES = 8
DET_OUT = 5
DET_STRIDE = 4
HEAT_PRIOR = -2.19


class DetectorNet(nn.Module):
    def __init__(self, classes: int = CLASSES) -> None:
        super().__init__()
        self.classes = classes
        self.enc = nn.ModuleList(
            [nn.Conv2d(3, 32, 3, 2, 1), nn.Conv2d(32, 64, 3, 2, 1), nn.Conv2d(64, 128, 3, 2, 1)]
        )
        self.mid = nn.ModuleList([nn.Conv2d(128, 128, 3, 1, 1), nn.Conv2d(128, 128, 3, 1, 1)])
        self.dec = nn.Conv2d(128 + 64, 64, 3, 1, 1)
        self.head = nn.Conv2d(64, classes * DET_OUT, 1)

    def forward(self, frames: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """`frames` (B, 3, H, W) -> heatmap logits (B, C, h, w) and offset + log size (B, C, 4, h, w)."""
        e1 = torch.relu(self.enc[0](frames))
        e2 = torch.relu(self.enc[1](e1))
        e3 = torch.relu(self.enc[2](e2))
        m = torch.relu(self.mid[0](e3))
        m = torch.relu(self.mid[1](m))
        x = torch.cat([F.interpolate(m, scale_factor=2, mode="nearest"), e2], 1)
        d = torch.relu(self.dec(x))
        b, _, h, w = d.shape
        out = self.head(d).reshape(b, self.classes, DET_OUT, h, w)
        return out[:, :, 0] + HEAT_PRIOR, out[:, :, 1:]


def detector_loss(
    heat_logits: torch.Tensor, boxes: torch.Tensor, heat: torch.Tensor, reg: torch.Tensor, centres: torch.Tensor
) -> torch.Tensor:
    """Focal loss (alpha 2, beta 4) + L1 at the centres, both over the number of boxes (at least 1)."""
    n = centres.sum().clamp(min=1.0)
    x = heat_logits
    p = torch.sigmoid(x)
    log_p = -F.softplus(-x)
    log_q = -F.softplus(x)
    pos = (1.0 - p).square() * log_p * centres
    neg = p.square() * log_q * ((1.0 - heat).pow(4.0) * (1.0 - centres))
    focal = -(pos + neg).sum() / n
    l1 = ((boxes - reg).abs() * centres.unsqueeze(2)).sum() / n
    return focal + l1


def targets(
    boxes: list[list[tuple[int, list[float]]]], input_wh: tuple[int, int], nc: int
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Heatmaps (B, C, h, w), offset + log size (B, C, 4, h, w) and centre cells (B, C, h, w) of
    `boxes` (per frame: class index and [x0, y0, x1, y1] in input pixels), as detector.rs builds them."""
    mw, mh = input_wh[0] // DET_STRIDE, input_wh[1] // DET_STRIDE
    b = len(boxes)
    heat = torch.zeros(b, nc, mh, mw)
    reg = torch.zeros(b, nc, 4, mh, mw)
    centres = torch.zeros(b, nc, mh, mw)
    s = float(DET_STRIDE)
    for bi, frame in enumerate(boxes):
        for c, (x0, y0, x1, y1) in frame:
            cx, cy = (x0 + x1) / 2.0 / s, (y0 + y1) / 2.0 / s
            bw, bh = (x1 - x0) / s, (y1 - y0) / s
            ix, iy = min(math.floor(cx), mw - 1), min(math.floor(cy), mh - 1)
            sgx, sgy = max(0.09 * bw, 0.5), max(0.09 * bh, 0.5)
            rx, ry = math.ceil(3.0 * sgx), math.ceil(3.0 * sgy)
            for y in range(max(iy - ry, 0), min(iy + ry, mh - 1) + 1):
                for x in range(max(ix - rx, 0), min(ix + rx, mw - 1) + 1):
                    dx, dy = x - ix, y - iy
                    g = math.exp(-(dx * dx) / (2.0 * sgx * sgx) - (dy * dy) / (2.0 * sgy * sgy))
                    heat[bi, c, y, x] = max(float(heat[bi, c, y, x]), g)
            heat[bi, c, iy, ix] = 1.0
            centres[bi, c, iy, ix] = 1.0
            reg[bi, c, :, iy, ix] = torch.tensor([cx - ix, cy - iy, math.log(max(bw, 1e-3)), math.log(max(bh, 1e-3))])
    return heat, reg, centres


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--warmup", type=int, default=5)
    args = ap.parse_args()
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    rng = random.Random(0)
    b, (iw, ih) = 16, (160, 120)
    frames = (torch.randint(0, 256, (b, 3, ih, iw)).float() / 255.0 - 0.5) / 0.25
    boxes = []
    for _ in range(b):
        frame = []
        for k in range(CLASSES):
            w, h = rng.uniform(10.0, 50.0), rng.uniform(10.0, 50.0)
            x0, y0 = rng.uniform(0.0, iw - w), rng.uniform(0.0, ih - h)
            frame.append((k, [x0, y0, x0 + w, y0 + h]))
        boxes.append(frame)
    heat, reg, centres = targets(boxes, (iw, ih), CLASSES)
    net = DetectorNet(CLASSES)
    opt = torch.optim.AdamW(net.parameters(), lr=2e-3, betas=(0.9, 0.999), eps=1e-8, weight_decay=1e-4)
    times = []
    for i in range(args.warmup + args.steps):
        t0 = time.perf_counter()
        opt.zero_grad(set_to_none=True)
        heat_logits, box_out = net(frames)
        loss = detector_loss(heat_logits, box_out, heat, reg, centres)
        value = loss.item()
        loss.backward()
        opt.step()
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
        "params": sum(p.numel() for p in net.parameters()),
        "final_loss": value,
    }))


if __name__ == "__main__":
    main()
