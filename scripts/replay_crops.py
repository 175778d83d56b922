#!/usr/bin/env python3
"""The figure of docs/models.md: real photographs beside their replays, one object per row.

    python3 scripts/replay_crops.py OUT.png REAL REPLAY [REPLAY ...]

REAL is a real dataset with GT (e.g. ../shared/data/ycbv_real); each REPLAY a folder that
`synthgen render --replay REAL ...` wrote (same frames, same order). Per object of REAL the
frame where it shows the most visible pixels is chosen; every column is cropped to the box of
its real visible mask (plus a margin) and scaled to one height; each replay crop gets one gain
per channel that matches its mean inside the real mask to the photograph's (exposure and white
balance, as `synthgen sensor compare-rgb` fits them per frame). Needs the synthgen Python
package and numpy only (the PNG is written with zlib).
"""
import struct
import sys
import zlib

import numpy as np
import synthgen

ROW_PX = 112
GAP = 6


def write_png(path: str, img: np.ndarray) -> None:
    h, w, _ = img.shape
    raw = b"".join(b"\x00" + img[y].tobytes() for y in range(h))

    def chunk(tag: bytes, data: bytes) -> bytes:
        body = tag + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def resize(img: np.ndarray, height: int) -> np.ndarray:
    """Nearest-neighbour scaling to `height` rows, the aspect kept."""
    h, w, _ = img.shape
    width = max(1, round(w * height / h))
    ys = (np.arange(height) * h / height).astype(int)
    xs = (np.arange(width) * w / width).astype(int)
    return img[ys][:, xs]


def main() -> None:
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    out, real_dir, replays = sys.argv[1], sys.argv[2], sys.argv[3:]
    real = synthgen.open_dataset(real_dir)
    others = [synthgen.open_dataset(d) for d in replays]
    for d, o in zip(replays, others):
        if len(o) != len(real):
            sys.exit(f"{d} has {len(o)} frames, {real_dir} {len(real)}: not a replay of it")
    best: dict[int, tuple[int, int, int]] = {}  # obj_id -> (visible px, frame, instance)
    for i in range(len(real)):
        f = real[i]
        for k, (oid, m) in enumerate(zip(f.obj_ids, f.masks_visib)):
            n = int(np.count_nonzero(m))
            if n > best.get(int(oid), (0, 0, 0))[0]:
                best[int(oid)] = (n, i, k)
    rows = []
    for oid in sorted(best):
        _, i, k = best[oid]
        ys, xs = np.nonzero(real[i].masks_visib[k])
        h, w = real[i].rgb.shape[:2]
        m = max(8, (ys.max() - ys.min()) // 8)
        y0, y1 = max(0, ys.min() - m), min(h, ys.max() + m + 1)
        x0, x1 = max(0, xs.min() - m), min(w, xs.max() + m + 1)
        mask = real[i].masks_visib[k][y0:y1, x0:x1] > 0
        target = real[i].rgb[y0:y1, x0:x1].astype(float)
        crops = [resize(target.astype(np.uint8), ROW_PX)]
        for d in others:
            c = d[i].rgb[y0:y1, x0:x1].astype(float)
            gain = target[mask].mean(0) / np.maximum(c[mask].mean(0), 1.0)
            crops.append(resize(np.clip(c * gain, 0, 255).astype(np.uint8), ROW_PX))
        sep = np.full((ROW_PX, GAP, 3), 255, np.uint8)
        row = crops[0]
        for c in crops[1:]:
            row = np.concatenate([row, sep, c], 1)
        rows.append(row)
    width = max(r.shape[1] for r in rows)
    padded = []
    for r in rows:
        pad = np.full((ROW_PX, width - r.shape[1], 3), 255, np.uint8)
        padded.append(np.concatenate([r, pad], 1))
        padded.append(np.full((GAP, width, 3), 255, np.uint8))
    write_png(out, np.concatenate(padded[:-1], 0))
    print(f"wrote {out}: {len(rows)} objects x {1 + len(others)} columns")


if __name__ == "__main__":
    main()
