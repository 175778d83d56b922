"""synthgen.torch against real torch: workers split the frames, none twice, none missing."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Dict, List

import numpy as np
import pytest
import synthgen

try:
    import torch
    from torch.utils.data import DataLoader
except ImportError:  # pragma: no cover - depends on the machine
    if os.environ.get("SYNTHGEN_REQUIRE_TORCH") == "1":
        raise
    pytest.skip(
        "torch is not installed: the synthgen.torch tests did not run "
        "(pip install torch; CI runs them with SYNTHGEN_REQUIRE_TORCH=1)",
        allow_module_level=True,
    )

from synthgen.torch import FolderDataset, GeneratorDataset, collate, shard


def digest(f: synthgen.Frame) -> str:
    h = hashlib.sha256()
    for a in (f.rgb, f.depth, f.instance_ids, f.masks, f.masks_visib):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def frames_by_index(loader: DataLoader) -> Dict[int, str]:
    seen: Dict[int, str] = {}
    for batch in loader:
        for f in batch:
            assert f.index not in seen, f"frame {f.index} delivered twice"
            seen[f.index] = digest(f)
    return seen


def test_shard_covers_everything_once() -> None:
    for n in range(12):
        for parts in range(1, 5):
            got: List[int] = []
            for p in range(parts):
                got.extend(shard(n, p, parts))
            assert got == list(range(n))


@pytest.mark.parametrize("context", ["fork", "spawn"])
def test_two_workers_deliver_the_same_frames_as_one(
    gen: synthgen.Generator, context: str
) -> None:
    gen[0]  # the parent has rendered (its render threads exist) before the workers fork
    ds = GeneratorDataset(gen.with_frames(7))
    one = frames_by_index(DataLoader(ds, batch_size=2, collate_fn=list))
    two = frames_by_index(
        DataLoader(
            ds,
            batch_size=2,
            num_workers=2,
            collate_fn=list,
            multiprocessing_context=context,
            timeout=300,
        )
    )
    assert sorted(one) == list(range(7))
    assert one == two
    assert one[3] == digest(gen[3])


def test_collate_batches_tensors(gen: synthgen.Generator) -> None:
    loader = DataLoader(
        GeneratorDataset(gen),
        batch_size=3,
        num_workers=2,
        collate_fn=collate,
        timeout=300,
    )
    batches = list(loader)
    assert len(batches) == 2
    b = batches[0]
    assert b["rgb"].shape == (3, 480, 640, 3) and b["rgb"].dtype == torch.uint8
    assert b["depth"].shape == (3, 480, 640) and b["depth"].dtype == torch.float32
    assert b["instance_ids"].dtype == torch.int32 and b["cam_K"].shape == (3, 3, 3)
    assert b["masks"][0].dtype == torch.bool and b["masks"][0].shape[0] == len(
        b["objects"][0]
    )
    assert sorted(torch.cat([x["index"] for x in batches]).tolist()) == list(
        range(len(gen))
    )


def test_transform_runs_in_the_workers(gen: synthgen.Generator) -> None:
    ds = GeneratorDataset(gen, transform=_rgb_tensor)
    out = list(DataLoader(ds, batch_size=2, num_workers=2, timeout=300))
    assert torch.cat(out).shape == (len(gen), 3, 480, 640)


def _rgb_tensor(f: synthgen.Frame) -> torch.Tensor:
    return torch.from_numpy(f.rgb).permute(2, 0, 1)


def test_folder_dataset_with_workers(rendered: Path) -> None:
    ds = FolderDataset(rendered)
    one = {f.source["im_id"]: digest(f) for f in DataLoader(ds, batch_size=None)}
    two = {
        f.source["im_id"]: digest(f)
        for f in DataLoader(ds, batch_size=None, num_workers=2, timeout=300)
    }
    assert one == two and len(one) == len(ds)
    only = FolderDataset(rendered, min_visib_fract=0.5)
    assert len(only) <= len(ds)
