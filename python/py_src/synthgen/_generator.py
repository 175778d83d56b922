"""`Generator`: frames rendered on demand, in memory, as numpy arrays."""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from typing import Any, Dict, List, Optional, Tuple, Union, overload

import numpy as np

from . import _native
from ._frame import Frame
from ._progress import log_only
from ._types import PathLike


def _frame_range(frames: Union[int, range]) -> Tuple[int, int]:
    if isinstance(frames, range):
        if frames.step != 1:
            raise ValueError(f"frames must be a range with step 1, got {frames!r}")
        return frames.start, max(0, frames.stop - frames.start)
    if frames < 0:
        raise ValueError(f"frames must be >= 0, got {frames}")
    return 0, int(frames)


class Generator(Sequence[Frame]):
    """Renders annotated RGB-D frames of ``objects`` placed as ``scene`` says.

    ``gen[i]`` renders frame ``i`` in memory (the GIL is released meanwhile) and returns a
    :class:`Frame`; iterating renders several frames at a time in parallel, and
    :meth:`batch` renders a list of them. Frame ``i`` depends only on the scene, the
    objects, ``seed`` and ``i``: the same arrays whatever was rendered before and however
    many threads render.

    Args:
        objects: mesh files (PLY, OBJ, glTF/GLB): the target objects, before the scene's own
            ``[[objects]]``. Ids come from ``obj_ids``, else the file name (``obj_000008.ply``
            is 8), else 1, 2, ...
        scene: a scene spec (TOML, e.g. ``scenes/tabletop.toml``); default: the built-in
            defaults.
        camera: a camera preset (``linemod``, ``d455``, ``ycbv``), over the scene's.
        seed: the global seed.
        frames: how many frames (``0 .. frames``) or a ``range`` of global frame indices.
        units: the meshes' units: ``"auto"``, ``"mm"`` or ``"m"``.
        obj_ids: one BOP object id per mesh in ``objects``.
        image_size: ``(width, height)`` over the camera's.
        threads: worker threads for rendering; 0: all cores.
    """

    def __init__(
        self,
        objects: Sequence[PathLike] = (),
        scene: Optional[PathLike] = None,
        camera: Optional[str] = None,
        seed: int = 0,
        frames: Union[int, range] = 100,
        *,
        units: str = "auto",
        obj_ids: Optional[Sequence[int]] = None,
        image_size: Optional[Tuple[int, int]] = None,
        threads: int = 0,
    ) -> None:
        start, count = _frame_range(frames)
        self._kwargs: Dict[str, Any] = dict(
            objects=[os.fspath(o) for o in objects],
            scene=None if scene is None else os.fspath(scene),
            camera=camera,
            seed=int(seed),
            frames=range(start, start + count),
            units=units,
            obj_ids=None if obj_ids is None else [int(i) for i in obj_ids],
            image_size=(
                None if image_size is None else (int(image_size[0]), int(image_size[1]))
            ),
            threads=int(threads),
        )
        self._start, self._count = start, count
        self._job = self._build()
        self._pid = os.getpid()

    def _build(self) -> _native.RenderJob:
        k = self._kwargs
        return _native.RenderJob(
            k["objects"],
            obj_ids=k["obj_ids"],
            scene=k["scene"],
            camera=k["camera"],
            image_size=k["image_size"],
            units=k["units"],
            seed=k["seed"],
            start=self._start,
            count=self._count,
            threads=k["threads"],
            progress=log_only,
        )

    @property
    def _native_job(self) -> _native.RenderJob:
        # A forked process (a DataLoader worker) has none of the parent's render threads:
        # it prepares its own job.
        if self._pid != os.getpid():
            self._job = self._build()
            self._pid = os.getpid()
        return self._job

    def __reduce__(self) -> Tuple[Any, ...]:
        return (_rebuild, (self._kwargs,))

    def __len__(self) -> int:
        return self._count

    def _global(self, i: int) -> int:
        n = self._count
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError(f"frame {i} out of range (the generator has {n})")
        return self._start + i

    @overload
    def __getitem__(self, i: int) -> Frame: ...

    @overload
    def __getitem__(self, i: slice) -> List[Frame]: ...

    def __getitem__(self, i: Union[int, slice]) -> Union[Frame, List[Frame]]:
        if isinstance(i, slice):
            return self.batch(range(*i.indices(self._count)))
        return Frame(**self._native_job.frame(self._global(int(i))))

    def batch(self, indices: Sequence[int]) -> List[Frame]:
        """Frames ``indices`` (positions, as for ``gen[i]``), rendered in parallel."""
        glob = [self._global(int(i)) for i in indices]
        return [Frame(**d) for d in self._native_job.frames_batch(glob)]

    def __iter__(self) -> Iterator[Frame]:
        # Two frames per thread per call keeps every thread busy and memory bounded.
        step = max(1, 2 * self._native_job.threads)
        for first in range(0, self._count, step):
            yield from self.batch(range(first, min(first + step, self._count)))

    @property
    def frame_indices(self) -> range:
        """The global frame indices ``gen[0]``, ``gen[1]``, ... render."""
        return range(self._start, self._start + self._count)

    @property
    def seed(self) -> int:
        return int(self._kwargs["seed"])

    @property
    def threads(self) -> int:
        """Render threads in this process."""
        return self._native_job.threads

    @property
    def image_size(self) -> Tuple[int, int]:
        """``(width, height)``."""
        return self._native_job.image_size

    @property
    def cam_K(self) -> np.ndarray:
        return self._native_job.cam_K

    @property
    def objects(self) -> List[Tuple[int, str, str]]:
        """The target objects: ``(obj_id, name, path)``."""
        return [(i, n, os.fspath(p)) for i, n, p in self._native_job.objects]

    @property
    def kwargs(self) -> Dict[str, Any]:
        """The arguments this generator was made with (``Generator(**g.kwargs)`` is the same)."""
        return dict(self._kwargs)

    def with_frames(
        self, frames: Union[int, range], threads: Optional[int] = None
    ) -> Generator:
        """The same scene, objects and seed over other frames (and threads)."""
        k = dict(self._kwargs, frames=frames)
        if threads is not None:
            k["threads"] = threads
        return Generator(**k)

    def spec_toml(self) -> str:
        """The scene spec in effect, as TOML."""
        return self._native_job.spec_toml()

    def __repr__(self) -> str:
        w, h = self.image_size
        ids = [i for i, _, _ in self.objects]
        return (
            f"<synthgen.Generator {len(self)} frames {self.frame_indices.start}.."
            f"{self.frame_indices.stop} of objects {ids} at {w}x{h}, seed {self.seed}>"
        )


def _rebuild(kwargs: Dict[str, Any]) -> Generator:
    return Generator(**kwargs)
