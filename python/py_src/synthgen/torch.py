"""PyTorch adapters: :class:`GeneratorDataset` (frames rendered in the DataLoader's workers)
and :class:`FolderDataset` (a dataset folder), with :func:`collate` to batch frames.

Imported only on ``import synthgen.torch`` (or ``synthgen.torch`` attribute access): plain
``import synthgen`` never imports torch. Install torch yourself (``pip install torch``).
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from typing import Any, Callable, Dict, List, Optional

import numpy as np
import torch
from torch.utils.data import Dataset as _TorchDataset
from torch.utils.data import IterableDataset, get_worker_info

from ._dataset import Dataset, open_dataset
from ._frame import Frame
from ._generator import Generator

__all__ = ["FolderDataset", "GeneratorDataset", "collate", "shard"]

Transform = Callable[[Frame], Any]


def shard(n: int, part: int, parts: int) -> range:
    """Contiguous block ``part`` of ``parts`` over ``range(n)``: the blocks cover every index
    once, and their sizes differ by at most one."""
    if not 0 <= part < parts:
        raise ValueError(f"part {part} not in 0..{parts}")
    base, extra = divmod(n, parts)
    start = part * base + min(part, extra)
    return range(start, start + base + (1 if part < extra else 0))


def _rank() -> tuple:
    if torch.distributed.is_available() and torch.distributed.is_initialized():
        return torch.distributed.get_rank(), torch.distributed.get_world_size()
    return 0, 1


class GeneratorDataset(IterableDataset):
    """A :class:`synthgen.Generator`'s frames for ``torch.utils.data.DataLoader``.

    Each worker of each rank (``torch.distributed``) renders its own contiguous block of the
    generator's frames, in order: together they give every frame once, and the same frames
    for any number of workers. Every worker prepares its own render job (after the fork),
    with ``threads_per_worker`` threads (default: the cores shared between the workers).

    Yields ``transform(frame)``, or the :class:`synthgen.Frame` itself (batch those with
    ``collate_fn=synthgen.torch.collate``).
    """

    def __init__(
        self,
        generator: Generator,
        transform: Optional[Transform] = None,
        threads_per_worker: Optional[int] = None,
        batch_frames: Optional[int] = None,
    ) -> None:
        super().__init__()
        self.kwargs = generator.kwargs
        self.transform = transform
        self.threads_per_worker = threads_per_worker
        self.batch_frames = batch_frames
        self._generator: Optional[Generator] = generator

    def __len__(self) -> int:
        return len(self.kwargs["frames"])

    def positions(self) -> range:
        """The generator positions this process (worker, rank) renders."""
        rank, world = _rank()
        info = get_worker_info()
        worker, workers = (info.id, info.num_workers) if info is not None else (0, 1)
        mine = shard(len(self), rank, world)
        block = shard(len(mine), worker, workers)
        return range(mine.start + block.start, mine.start + block.stop)

    def _worker_generator(self) -> Generator:
        info = get_worker_info()
        if info is None and self._generator is not None:
            return self._generator
        threads = self.threads_per_worker
        if threads is None:
            workers = info.num_workers if info is not None else 1
            threads = max(1, (os.cpu_count() or 1) // workers)
        return Generator(**dict(self.kwargs, threads=threads))

    def __iter__(self) -> Iterator[Any]:
        gen = self._worker_generator()
        pos = self.positions()
        step = self.batch_frames or max(1, 2 * gen.threads)
        for first in range(pos.start, pos.stop, step):
            for frame in gen.batch(range(first, min(first + step, pos.stop))):
                yield self.transform(frame) if self.transform is not None else frame

    def __getstate__(self) -> Dict[str, Any]:
        # Workers build their own generator; the parent's render threads do not survive a fork.
        state = dict(self.__dict__)
        state["_generator"] = None
        return state


class FolderDataset(_TorchDataset):
    """A dataset folder (BOP, Linemod, YCB-Video) as a map-style torch ``Dataset``:
    ``ds[i]`` is ``transform(frame)`` or the :class:`synthgen.Frame` with its images
    decoded. Arguments after ``path`` are those of :func:`synthgen.open_dataset`."""

    def __init__(
        self,
        path: Any,
        split: Any = None,
        obj_ids: Any = None,
        min_visib_fract: float = 0.0,
        transform: Optional[Transform] = None,
    ) -> None:
        self.dataset: Dataset = open_dataset(path, split, obj_ids, min_visib_fract)
        self.transform = transform

    def __len__(self) -> int:
        return len(self.dataset)

    def __getitem__(self, i: int) -> Any:
        frame = self.dataset[i].load()
        return self.transform(frame) if self.transform is not None else frame


def collate(frames: Sequence[Frame]) -> Dict[str, Any]:
    """Batches frames of one image size: ``rgb`` ``(B, H, W, 3)`` uint8, ``depth`` ``(B, H,
    W)`` float32, ``instance_ids`` ``(B, H, W)`` int32, ``cam_K`` ``(B, 3, 3)`` float64 and
    ``index`` ``(B,)`` as tensors; ``masks`` and ``masks_visib`` as lists of ``(N_b, H, W)``
    bool tensors (``None`` where a frame has none) and ``objects`` as the frames' lists,
    since the object count varies."""

    def stack(key: str, dtype: Any = None) -> torch.Tensor:
        arrays = [getattr(f, key) for f in frames]
        a = np.stack(arrays)
        return torch.from_numpy(a if dtype is None else a.astype(dtype))

    def each(key: str) -> List[Optional[torch.Tensor]]:
        out: List[Optional[torch.Tensor]] = []
        for f in frames:
            m = getattr(f, key)
            out.append(None if m is None else torch.from_numpy(m))
        return out

    batch: Dict[str, Any] = {
        "index": torch.tensor([f.index for f in frames]),
        "rgb": stack("rgb"),
        "instance_ids": stack("instance_ids", np.int32),
        "cam_K": stack("cam_K"),
        "masks": each("masks"),
        "masks_visib": each("masks_visib"),
        "objects": [f.objects for f in frames],
    }
    if all(f.depth is not None for f in frames):
        batch["depth"] = stack("depth")
    return batch
