#!/usr/bin/env python3
"""Draws GT (green) and estimated (magenta) poses of a BOP results CSV onto a dataset's frames:
every 5th point of each object's evaluation model, projected. Needs the synthgen Python package
(and numpy); writes the PNG itself.

Usage: overlay_estimates.py DATASET RESULTS.csv OUT.png FRAME[,FRAME...]
FRAME: frame indices of synthgen.open_dataset(DATASET). One frame: rows 100-400 of it; several:
side by side, whole.
"""
import csv
import struct
import sys
import zlib

import numpy as np
import synthgen


def write_png(path: str, img: np.ndarray) -> None:
    h, w, _ = img.shape
    raw = b"".join(b"\x00" + img[y].tobytes() for y in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = zlib.crc32(kind + data) & 0xFFFFFFFF
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)

    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header))
        f.write(chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def main() -> None:
    dataset, results, out, frames = sys.argv[1:5]
    ds = synthgen.open_dataset(dataset)
    est = {}
    with open(results) as f:
        for r in csv.DictReader(f):
            rot = np.array([float(x) for x in r["R"].split()]).reshape(3, 3)
            t = np.array([float(x) for x in r["t"].split()]) / 1000.0
            est[(int(r["im_id"]), int(r["obj_id"]))] = (rot, t)
    tiles = []
    for i in [int(x) for x in frames.split(",")]:
        frame = ds[i]
        img = frame.rgb.copy()

        def draw(points: np.ndarray, colour: tuple) -> None:
            p = (frame.cam_K @ points.T).T
            for u, v in (p[:, :2] / p[:, 2:3])[::5]:
                u, v = int(round(u)), int(round(v))
                if 0 <= u < img.shape[1] and 0 <= v < img.shape[0]:
                    img[max(v - 1, 0) : v + 1, max(u - 1, 0) : u + 1] = colour

        for g in frame.objects:
            pts, _, _ = ds.eval_model(g["obj_id"])
            draw(pts @ np.array(g["R"]).T + np.array(g["t"]), (0, 255, 0))
            e = est.get((frame.source["im_id"], g["obj_id"]))
            if e is not None:
                draw(pts @ e[0].T + e[1], (255, 0, 255))
        tiles.append(img)
    if len(tiles) == 1:
        write_png(out, tiles[0][100:400])
        return
    sep = np.full((tiles[0].shape[0], 6, 3), 255, np.uint8)
    row = tiles[0]
    for t in tiles[1:]:
        row = np.concatenate([row, sep, t], 1)
    write_png(out, row)


if __name__ == "__main__":
    main()
