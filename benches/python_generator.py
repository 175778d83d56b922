#!/usr/bin/env python3
"""Frames/s that `synthgen.Generator` delivers to a Python loop as numpy arrays, against the
Rust in-memory rate of the same job in the same process (`PreparedJob::frames`, no numpy),
and through a torch DataLoader with 2 workers when torch is installed.

The scene is the 5-object Linemod one of the pipeline's `pipeline_640x480` criterion bench:
scenes/linemod_like.toml with LMO objects 1, 5, 6, 8, 9 at 640x480, ToF depth noise.

    pip install ./python            # a release wheel (maturin's default)
    python benches/python_generator.py --frames 200 --repeats 3

Prints a markdown table (medians of the repeats, rounds alternated) and one JSON line.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

import synthgen

REPO = Path(__file__).resolve().parents[1]
IDS = (1, 5, 6, 8, 9)


def generator(lmo: Path, frames: int, threads: int) -> synthgen.Generator:
    return synthgen.Generator(
        objects=[lmo / "models" / f"obj_{i:06d}.ply" for i in IDS],
        scene=REPO / "scenes" / "linemod_like.toml",
        seed=2024,
        frames=frames,
        units="mm",
        threads=threads,
    )


def python_loop(gen: synthgen.Generator) -> float:
    started = time.perf_counter()
    n = 0
    for f in gen:
        # What a training loop reads: the arrays exist as numpy, no copy made here.
        assert (
            f.rgb.shape == (480, 640, 3) and f.depth is not None and f.masks is not None
        )
        n += 1
    assert n == len(gen)
    return n / (time.perf_counter() - started)


def rust_in_memory(gen: synthgen.Generator) -> float:
    return len(gen) / gen._native_job.time_in_memory()


def dataloader(gen: synthgen.Generator, workers: int) -> float:
    from synthgen.torch import GeneratorDataset
    from torch.utils.data import DataLoader

    ds = GeneratorDataset(
        gen, threads_per_worker=max(1, (os.cpu_count() or 1) // workers)
    )
    loader = DataLoader(ds, batch_size=None, num_workers=workers, timeout=600)
    started = time.perf_counter()
    n = sum(1 for _ in loader)
    assert n == len(gen)
    return n / (time.perf_counter() - started)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=200)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument(
        "--threads", type=int, default=0, help="render threads (0: all cores)"
    )
    p.add_argument("--workers", type=int, default=2, help="DataLoader workers")
    p.add_argument(
        "--lmo",
        type=Path,
        default=Path(
            os.environ.get("SYNTHGEN_LMO_DIR", REPO.parent / "shared" / "data" / "lmo")
        ),
    )
    args = p.parse_args()

    gen = generator(args.lmo, args.frames, args.threads)
    gen.batch(range(min(4, len(gen))))  # warm-up: page in the models, start the threads
    rust, py = [], []
    for _ in range(args.repeats):
        rust.append(rust_in_memory(gen))
        py.append(python_loop(gen))
    try:
        import torch  # noqa: F401

        loader = [dataloader(gen, args.workers) for _ in range(args.repeats)]
    except ImportError:
        loader = []

    med = statistics.median
    print(
        f"{args.frames} frames, 640x480, 5 LMO objects, {gen.threads} render threads, "
        f"{os.cpu_count()} cores; medians of {args.repeats}"
    )
    print()
    print("| path | rounds (frames/s) | median | vs Rust |")
    print("|---|---|---:|---:|")
    rows = [
        ("Rust in memory (`PreparedJob::frames`)", rust),
        ("`Generator` → Python loop, numpy", py),
    ]
    if loader:
        rows.append(
            (f"`GeneratorDataset` → DataLoader, {args.workers} workers", loader)
        )
    for name, xs in rows:
        rounds = ", ".join(f"{x:.1f}" for x in xs)
        print(f"| {name} | {rounds} | {med(xs):.1f} | {med(xs) / med(rust):.2f} |")
    if not loader:
        print("\n(torch not installed: no DataLoader row)")
    print(
        json.dumps(
            {
                "frames": args.frames,
                "threads": gen.threads,
                "rust_in_memory_fps": rust,
                "python_loop_fps": py,
                "dataloader_fps": loader,
                "python_vs_rust": med(py) / med(rust),
            }
        )
    )


if __name__ == "__main__":
    main()
