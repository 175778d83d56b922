#!/usr/bin/env python3
"""PyTorch peer of the candle bench `full_step_32x500_c48_w128` (crates/synthgen-train/benches/full_step.rs).

The same Full model as crates/synthgen-train/src/models/full.rs: TNet (crates/synthgen-train/src/models/
tnet.rs, no object classes: per point 3->64->128->width (ReLU), a global feature max-pooled over the
points, head relu(W_p f2 + b + W_g g) (128, no bias on the global term) -> 64 (ReLU) -> 3 offsets) and
RNet's rotation branch (benches/peers/rnet_torch.py: colour CNN on the 48x48 crop, per-point gather,
fusion with TNet's 128-channel point features, mean pooling, per-point quaternion + sigmoid confidence).
Loss (crates/synthgen-train/src/losses.rs, `full_loss`): per point i the centre t_i = x_i + offset_i and
the rotation R(q_i); the per-point ADD distance (1/M) sum_j ||R_i m_j + t_i - y_kj|| (sqrt(|.|^2 + 1e-12))
over the M = 100 loss points, its minimum over the object's K symmetries (K = 1: asymmetric objects),
everything in the normalized frame (centred on the cloud's mean, times 10) and divided by 10 back to
metres; then DenseFusion's mean of (d_i c_i - 0.015 log c_i). The R_i m_j products are one batched
matmul (B, M, 3) x (B, 3, N*3), as the candle loss computes them. AdamW (lr 1e-3, weight decay 0.01 =
candle's ParamsAdamW default). One step = forward, loss, backward, optimizer step, reading the loss back,
on 32 clouds of 500 points with crops, pixel indices, loss points and targets already in memory as
tensors (the candle bench also normalizes the clouds and builds these tensors from its instances and
objects each step, as `PoseModel::run_training` does).

Usage: python3 benches/peers/full_torch.py [--threads N] [--steps 30] [--warmup 5]
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
from rnet_torch import CONFIDENCE_WEIGHT, PointStem, RotationBranch, synthetic_batch  # RNet's peer

SCALE = 10.0


class Full(nn.Module):
    """TNet's offsets and RNet's rotation branch on TNet's first-layer point features."""

    def __init__(self, width: int = 128) -> None:
        super().__init__()
        self.stem = PointStem()
        self.l3 = nn.Linear(128, width)
        self.h1_point = nn.Linear(128, 128)
        self.h1_global = nn.Linear(width, 128, bias=False)
        self.h2 = nn.Linear(128, 64)
        self.h3 = nn.Linear(64, 3)
        self.rot = RotationBranch(width)

    def forward(
        self, points: torch.Tensor, crops: torch.Tensor, pixels: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Per point offsets (B, N, 3), quaternions (B, N, 4) and confidences (B, N)."""
        b, n, _ = points.shape
        f2 = self.stem(points.reshape(b * n, 3))
        f3 = torch.relu(self.l3(f2))
        g = f3.reshape(b, n, -1).amax(dim=1)
        hg = self.h1_global(g).unsqueeze(1)
        hp = self.h1_point(f2).reshape(b, n, 128)
        h = torch.relu(hp + hg).reshape(b * n, 128)
        h = torch.relu(self.h2(h))
        offsets = self.h3(h).reshape(b, n, 3)
        quats, conf = self.rot(f2, crops, pixels, b, n)
        return offsets, quats, conf


def full_loss(
    offsets: torch.Tensor,
    quats: torch.Tensor,
    conf: torch.Tensor,
    points: torch.Tensor,
    model_points: torch.Tensor,
    targets: torch.Tensor,
    scale: float = SCALE,
    w: float = CONFIDENCE_WEIGHT,
) -> torch.Tensor:
    """`points` (B, N, 3) the normalized cloud, `model_points` (B, M, 3) loss points times `scale`,
    `targets` (B, K, M, 3) the GT-posed (and symmetry-turned) loss points in the normalized frame."""
    b, n, _ = quats.shape
    m = model_points.shape[1]
    r = quat_to_matrix(quats)  # (B, N, 3, 3)
    t = points + offsets
    # Entry [k, (i, r)] = R_i[r, k]: all pixels' rotations in one batched matmul.
    r_cols = r.permute(0, 3, 1, 2).reshape(b, 3, n * 3)
    posed = (model_points @ r_cols).reshape(b, m, n, 3).transpose(1, 2) + t.unsqueeze(2)  # (B, N, M, 3)
    diff = posed.unsqueeze(2) - targets.unsqueeze(1)  # (B, N, K, M, 3)
    dist = (diff.square().sum(-1) + 1e-12).sqrt()  # (B, N, K, M)
    d = dist.mean(-1).amin(-1) / scale  # (B, N), metres
    return (d * conf - conf.log() * w).mean()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--warmup", type=int, default=5)
    args = ap.parse_args()
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    b, n, width, crop, loss_points = 32, 500, 128, 48, 100
    batch = synthetic_batch(b, n, crop, loss_points, SCALE)
    x, crops, pixels = batch["points"], batch["crops"], batch["pixels"]
    model_points = batch["model_points"] * SCALE
    # K = 1 (no symmetries): y_j = R m_j + t, all in the normalized frame.
    targets = (model_points @ quat_to_matrix(batch["q_gt"]).transpose(1, 2) + batch["t_norm"][:, None]).unsqueeze(1)
    net = Full(width)
    opt = torch.optim.AdamW(net.parameters(), lr=1e-3, betas=(0.9, 0.999), eps=1e-8, weight_decay=0.01)
    times = []
    for i in range(args.warmup + args.steps):
        t0 = time.perf_counter()
        opt.zero_grad(set_to_none=True)
        offsets, quats, conf = net(x, crops, pixels)
        loss = full_loss(offsets, quats, conf, x, model_points, targets)
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
