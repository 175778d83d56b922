"""`open_dataset`: BOP, Linemod and YCB-Video folders as `Frame`s, images decoded lazily."""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator, Sequence
from typing import Any, Dict, List, Optional, Tuple, Union, overload

import numpy as np

from . import _native
from ._frame import Frame
from ._types import PathLike


def _as_list(v: Union[None, int, str, Iterable[Any]]) -> Optional[List[Any]]:
    if v is None:
        return None
    if isinstance(v, (int, str)):
        return [v]
    return list(v)


class Dataset(Sequence[Frame]):
    """The frames of a dataset folder, in the order ``(split, scene_id, im_id)``.

    ``ds[i]`` is a :class:`Frame` whose annotations are read already and whose images are
    decoded on first access; ``len(ds)`` counts the frames kept by the filters. Made by
    :func:`open_dataset`; :meth:`filter` narrows it further.
    """

    def __init__(
        self,
        native: _native.Dataset,
        path: str,
        split: Optional[List[str]],
        obj_ids: Optional[List[int]],
        min_visib_fract: float,
    ) -> None:
        self._native = native
        self._path = path
        self._split = split
        self._obj_ids = obj_ids
        self._min_visib_fract = float(min_visib_fract)
        wanted = None if obj_ids is None else set(obj_ids)
        self._rows: List[Tuple[int, List[int]]] = []
        for i, (ids, fracts) in enumerate(
            zip(native.frame_obj_ids(), native.frame_visib_fracts())
        ):
            keep = [
                g
                for g, (o, v) in enumerate(zip(ids, fracts))
                if (wanted is None or o in wanted)
                and (
                    v is None
                    or v >= self._min_visib_fract
                    or self._min_visib_fract <= 0
                )
            ]
            if keep or (wanted is None and self._min_visib_fract <= 0):
                self._rows.append((i, keep))

    def __reduce__(self) -> Tuple[Any, ...]:
        return (
            open_dataset,
            (self._path, self._split, self._obj_ids, self._min_visib_fract),
        )

    def __len__(self) -> int:
        return len(self._rows)

    @overload
    def __getitem__(self, i: int) -> Frame: ...

    @overload
    def __getitem__(self, i: slice) -> List[Frame]: ...

    def __getitem__(self, i: Union[int, slice]) -> Union[Frame, List[Frame]]:
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        n = len(self._rows)
        j = int(i) + n if int(i) < 0 else int(i)
        if not 0 <= j < n:
            raise IndexError(f"frame {i} out of range (the dataset has {n})")
        native_i, gt_ids = self._rows[j]
        ann = self._native.annotations(native_i, gt_ids)
        source = {
            k: ann.pop(k)
            for k in ("split", "scene_id", "im_id", "rgb_path", "depth_scale")
        }
        source["rgb_path"] = os.fspath(source["rgb_path"])
        native = self._native

        def loader(rgb: bool, depth: bool, masks: bool) -> Dict[str, np.ndarray]:
            return native.images(native_i, gt_ids, rgb=rgb, depth=depth, masks=masks)

        return Frame(
            index=j,
            cam_K=ann["cam_K"],
            objects=ann["objects"],
            source=source,
            loader=loader,
        )

    def __iter__(self) -> Iterator[Frame]:
        for j in range(len(self)):
            yield self[j]

    def filter(
        self,
        obj_ids: Union[None, int, Iterable[int]] = None,
        min_visib_fract: Optional[float] = None,
    ) -> Dataset:
        """The frames with at least one instance of ``obj_ids`` at least ``min_visib_fract``
        visible; each frame's ``objects`` (and masks) keep only those instances."""
        ids = _as_list(obj_ids)
        if ids is not None and self._obj_ids is not None:
            ids = [i for i in ids if i in self._obj_ids]
        elif ids is None:
            ids = self._obj_ids
        fract = (
            self._min_visib_fract if min_visib_fract is None else float(min_visib_fract)
        )
        return Dataset(self._native, self._path, self._split, ids, fract)

    @property
    def root(self) -> str:
        return os.fspath(self._native.root)

    @property
    def layout(self) -> str:
        """``"bop"``, ``"linemod"`` or ``"ycbv"``."""
        return self._native.layout

    @property
    def splits(self) -> List[str]:
        return self._native.splits

    @property
    def obj_ids(self) -> List[int]:
        """The distinct object ids of the kept instances, sorted."""
        ids = self._native.frame_obj_ids()
        return sorted({ids[i][g] for i, keep in self._rows for g in keep})

    def eval_model(self, obj_id: int) -> Tuple[np.ndarray, float, bool]:
        """``(points (M, 3) metres, diameter metres, symmetric)``: the model ``synthgen eval``
        scores ``obj_id`` with (see :mod:`synthgen.metrics`)."""
        return self._native.eval_model(int(obj_id))

    def __repr__(self) -> str:
        return f"<synthgen.Dataset {self.layout} {self.root}: {len(self)} frames>"


def open_dataset(
    path: PathLike,
    split: Union[None, str, Sequence[str]] = None,
    obj_ids: Union[None, int, Iterable[int]] = None,
    min_visib_fract: float = 0.0,
) -> Dataset:
    """Opens a BOP, Linemod or YCB-Video dataset folder (the layout is detected).

    Args:
        path: the dataset folder (BOP: the one with ``camera.json``).
        split: only these splits (BOP split folders such as ``train_pbr``; Linemod ``train``
            / ``test``; YCB-Video image sets); default: all.
        obj_ids: only frames with these objects, and only their instances in each frame.
        min_visib_fract: only instances at least this visible (where the dataset says).

    Raises:
        synthgen.InputError: the folder is missing or not a readable dataset.
    """
    p = os.fspath(path)
    splits = _as_list(split)
    native = _native.Dataset(p, splits or [])
    return Dataset(native, p, splits, _as_list(obj_ids), min_visib_fract)
