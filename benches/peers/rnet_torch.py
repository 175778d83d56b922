#!/usr/bin/env python3
"""PyTorch peer of the candle bench `rnet_step_32x500_c48_w128` (crates/synthgen-train/benches/rnet_step.rs).

The same RNet as crates/synthgen-train/src/models/rnet.rs: a point stem per point 3->64->128 (ReLU); a
colour CNN on the 48x48 crop, 3x3 convolutions 3->16 (stride 1), 16->32 (stride 2), 32->32 (stride 1),
padding 1, ReLU, giving a 24x24 map of 32 channels whose feature at each sampled pixel is gathered per
point (index into the flattened (B*24*24, 32) maps); per point relu(W_c e + b_c + W_p f) (128, no bias on
the point term), a layer to the width (128, ReLU), the global feature averaged over the points, a head
relu(W_p' h + b + W_g g) (128, no bias on the global term) -> 64 (ReLU) -> 5: a quaternion (w, x, y, z)
normalized by sqrt(|q|^2 + 1e-12) and a sigmoid confidence per point. Loss (DenseFusion's): mean over
points and clouds of (1 - |<q_gt, q_i>|) c_i - 0.015 log c_i. AdamW (lr 1e-3, weight decay 0.01 =
candle's ParamsAdamW default). One step = forward, loss, backward, optimizer step, reading the loss back,
on 32 clouds of 500 points with their crops and pixel indices already in memory as tensors (the candle
bench also normalizes the clouds and builds the crop and index tensors from its instances each step, as
`PoseModel::run_training` does).

Usage: python3 benches/peers/rnet_torch.py [--threads N] [--steps 30] [--warmup 5]
Prints one JSON line: {"peer": "pytorch", "median_ms": ..., ...}. CPU only. Never run in CI: it needs torch
(benches/peers/setup_torch.sh installs it into benches/peers/.venv-torch).
"""
import argparse
import json
import statistics
import time

import torch
from torch import nn

from rgb_torch import quat_to_matrix  # the RGB model's peer, same folder

COLOUR_CHANNELS = 32
CONFIDENCE_WEIGHT = 0.015


class PointStem(nn.Module):
    """TNet's first layers: per point 3 -> 64 -> 128 (ReLU)."""

    def __init__(self) -> None:
        super().__init__()
        self.l1 = nn.Linear(3, 64)
        self.l2 = nn.Linear(64, 128)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.relu(self.l2(torch.relu(self.l1(x))))


class ColourCnn(nn.Module):
    """(B, 3, S, S) -> (B, 32, S/2, S/2)."""

    def __init__(self) -> None:
        super().__init__()
        self.c1 = nn.Conv2d(3, 16, 3, stride=1, padding=1)
        self.c2 = nn.Conv2d(16, COLOUR_CHANNELS, 3, stride=2, padding=1)
        self.c3 = nn.Conv2d(COLOUR_CHANNELS, COLOUR_CHANNELS, 3, stride=1, padding=1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = torch.relu(self.c1(x))
        x = torch.relu(self.c2(x))
        return torch.relu(self.c3(x))


class RotationBranch(nn.Module):
    """Colour CNN, fusion with the point features, mean pooling, per-point quaternion + confidence."""

    def __init__(self, width: int = 128) -> None:
        super().__init__()
        self.width = width
        self.cnn = ColourCnn()
        self.fuse_c = nn.Linear(COLOUR_CHANNELS, 128)
        self.fuse_p = nn.Linear(128, 128, bias=False)
        self.fuse2 = nn.Linear(128, width)
        self.r1_point = nn.Linear(width, 128)
        self.r1_global = nn.Linear(width, 128, bias=False)
        self.r2 = nn.Linear(128, 64)
        self.r3 = nn.Linear(64, 5)

    def forward(
        self, point_feat: torch.Tensor, crops: torch.Tensor, pixels: torch.Tensor, b: int, n: int
    ) -> tuple[torch.Tensor, torch.Tensor]:
        fmap = self.cnn(crops)
        _, c, h, w = fmap.shape
        flat = fmap.reshape(b, c, h * w).transpose(1, 2).reshape(b * h * w, c)
        colour = flat.index_select(0, pixels)  # (B*N, C)
        fused = torch.relu(self.fuse_c(colour) + self.fuse_p(point_feat))
        fused = torch.relu(self.fuse2(fused))  # (B*N, width)
        g = fused.reshape(b, n, self.width).mean(1)
        hg = self.r1_global(g).unsqueeze(1)  # (B, 1, 128)
        hp = self.r1_point(fused).reshape(b, n, 128)
        hh = torch.relu(hp + hg).reshape(b * n, 128)
        hh = torch.relu(self.r2(hh))
        out = self.r3(hh).reshape(b, n, 5)
        raw_q = out[..., :4]
        quats = raw_q / (raw_q.square().sum(-1, keepdim=True) + 1e-12).sqrt()
        conf = torch.sigmoid(out[..., 4])
        return quats, conf


class RNet(nn.Module):
    def __init__(self, width: int = 128) -> None:
        super().__init__()
        self.stem = PointStem()
        self.rot = RotationBranch(width)

    def forward(
        self, points: torch.Tensor, crops: torch.Tensor, pixels: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        b, n, _ = points.shape
        f = self.stem(points.reshape(b * n, 3))
        return self.rot(f, crops, pixels, b, n)


def quaternion_confidence_loss(
    q_gt: torch.Tensor, q_pred: torch.Tensor, conf: torch.Tensor, w: float = CONFIDENCE_WEIGHT
) -> torch.Tensor:
    """(1/BN) sum (L_i c_i - w log c_i), L_i = 1 - |<q, q_i>|; q_gt (B, 4), q_pred (B, N, 4), conf (B, N)."""
    dot = (q_pred * q_gt.unsqueeze(1)).sum(-1)
    return ((1.0 - dot.abs()) * conf - conf.log() * w).mean()


def random_quaternions(b: int) -> torch.Tensor:
    """(B, 4) unit quaternions (w, x, y, z) with w >= 0, as `quaternion_wxyz` gives the GT."""
    q = nn.functional.normalize(torch.randn(b, 4), dim=-1)
    return q * torch.where(q[:, :1] < 0, -1.0, 1.0)


def synthetic_batch(
    b: int, n: int, crop: int, loss_points: int = 100, scale: float = 10.0
) -> dict[str, torch.Tensor]:
    """A batch like the candle bench's: per cloud an asymmetric model (random points in a 10 cm cube) in
    a random pose 0.6-1.0 m away, n of its points as the cloud and its first `loss_points` as the loss
    points. Returns the normalized clouds `points` (B, N, 3) (minus the mean, times `scale`), the GT
    quaternions `q_gt` (B, 4), the GT translations in the normalized frame `t_norm` (B, 3), the
    standardized crops `crops` (B, 3, S, S), the points' indices `pixels` (B*N) into the flattened
    (B, S/2, S/2) maps and the loss points `model_points` (B, M, 3, metres)."""
    model = torch.rand(b, n + loss_points, 3) * 0.1 - 0.05
    q = random_quaternions(b)
    r = quat_to_matrix(q)
    t = torch.stack([torch.rand(b) * 0.2 - 0.1, torch.rand(b) * 0.2 - 0.1, 0.6 + 0.4 * torch.rand(b)], -1)
    pts = model[:, loss_points:] @ r.transpose(1, 2) + t[:, None]
    mean = pts.mean(1)
    crops = (torch.randint(0, 256, (b, 3, crop, crop)).float() / 255.0 - 0.5) / 0.25
    half = crop // 2
    pixels = torch.randint(0, half * half, (b, n)) + (torch.arange(b) * half * half)[:, None]
    return {
        "points": (pts - mean[:, None]) * scale,
        "q_gt": q,
        "t_norm": (t - mean) * scale,
        "crops": crops,
        "pixels": pixels.reshape(-1),
        "model_points": model[:, :loss_points],
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--warmup", type=int, default=5)
    args = ap.parse_args()
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    b, n, width, crop = 32, 500, 128, 48
    batch = synthetic_batch(b, n, crop)
    x, q_gt, crops, pixels = batch["points"], batch["q_gt"], batch["crops"], batch["pixels"]
    net = RNet(width)
    opt = torch.optim.AdamW(net.parameters(), lr=1e-3, betas=(0.9, 0.999), eps=1e-8, weight_decay=0.01)
    times = []
    for i in range(args.warmup + args.steps):
        t0 = time.perf_counter()
        opt.zero_grad(set_to_none=True)
        quats, conf = net(x, crops, pixels)
        loss = quaternion_confidence_loss(q_gt, quats, conf)
        loss.backward()
        opt.step()
        value = loss.item()
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
