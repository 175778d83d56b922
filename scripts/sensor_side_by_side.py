#!/usr/bin/env python3
"""The figure of docs/sensors.md: one real YCB-Video frame's depth beside its clean replay and
its replay through the fitted sensor, objects cropped, one colour scale (black = no reading;
the real frame's non-object pixels dimmed).

    python3 scripts/sensor_side_by_side.py REAL CLEAN_REPLAY FITTED_REPLAY SCENE IMAGE OUT.png

REAL is the YCB-Video folder (depth = value / 10000 m); the replays are BOP folders written by
`synthgen render --replay REAL --scenes SCENE --sensor ...` (depth = value * 0.1 mm). Needs
numpy and pillow.
"""
import sys

import numpy as np
from PIL import Image, ImageDraw


def main() -> None:
    real_dir, clean_dir, fit_dir, scene, im, out = sys.argv[1:7]
    scene_i, im_i = int(scene), int(im)
    real = np.array(Image.open(f"{real_dir}/data/{scene_i:04d}/{im_i:06d}-depth.png"), dtype=float) / 1e4

    def bop(d: str) -> np.ndarray:
        p = f"{d}/train/{scene_i:06d}/depth/{im_i:06d}.png"
        return np.array(Image.open(p), dtype=float) * 1e-4

    clean, fit = bop(clean_dir), bop(fit_dir)
    mask = clean > 0
    lo, hi = np.percentile(real[mask & (real > 0)], [1, 99])

    def colour(d: np.ndarray, dim: np.ndarray | None = None) -> np.ndarray:
        t = np.clip((d - lo) / (hi - lo), 0, 1)
        rgb = np.stack([np.clip(1.5 - abs(4 * t - k), 0, 1) for k in (3, 2, 1)], -1)
        img = (rgb * 255).astype(np.uint8)
        img[d <= 0] = 0
        if dim is not None:
            img[~dim] = (img[~dim] * 0.35).astype(np.uint8)
        return img

    ys, xs = np.nonzero(mask)
    y0, y1 = max(ys.min() - 20, 0), min(ys.max() + 20, mask.shape[0])
    x0, x1 = max(xs.min() - 20, 0), min(xs.max() + 20, mask.shape[1])
    panels = [colour(real, mask), colour(clean), colour(fit)]
    titles = ["real depth (Asus Xtion)", "clean replay (--sensor none)", "fitted replay (sensors/asus_xtion.toml)"]
    crops = [p[y0:y1, x0:x1] for p in panels]
    h, w = crops[0].shape[:2]
    fig = Image.new("RGB", (3 * w + 40, h + 30), (255, 255, 255))
    draw = ImageDraw.Draw(fig)
    for i, (c, t) in enumerate(zip(crops, titles)):
        fig.paste(Image.fromarray(c), (i * (w + 20), 30))
        draw.text((i * (w + 20) + 4, 8), t, fill=(0, 0, 0))
    fig.save(out)


if __name__ == "__main__":
    main()
