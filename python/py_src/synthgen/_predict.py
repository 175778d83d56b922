"""`Predictor`: a trained detector and pose model on numpy images with no GT, as
``synthgen predict`` runs them per frame (docs/predict.md)."""

from __future__ import annotations

import os
from typing import Any, Dict, List, Optional

import numpy as np

from . import _native
from ._types import PathLike


class Predictor:
    """A detector (``synthgen detector train``) and a pose model (``synthgen train``), loaded
    once, that turn an image into the objects found and their poses.

    >>> p = synthgen.Predictor("runs/dense", "runs/det")
    >>> for o in p.predict(rgb, K):
    ...     print(o["obj_id"], o["score"], o["R"], o["t"])

    ``objects_from`` is the dataset whose object models the pose model reads (Full, rgb,
    rgb-dense; default: the model's training dataset); ``min_score``, ``per_object``,
    ``refine`` (``"none"``, ``"edges"``, ``"views"``: the RGB models' estimates refined on the
    image, each kept to its detection's box) and ``refine_models`` (the colours of ``"views"``
    from these meshes) as ``synthgen predict``'s ``--min-score``, ``--per-object``,
    ``--refine`` and ``--refine-models``.
    """

    def __init__(
        self,
        model: PathLike,
        detector: PathLike,
        *,
        objects_from: Optional[PathLike] = None,
        min_score: float = 0.05,
        per_object: int = 1,
        refine: str = "none",
        refine_models: Optional[PathLike] = None,
    ) -> None:
        self._native = _native.Predictor(
            os.fspath(model),
            os.fspath(detector),
            objects_from=None if objects_from is None else os.fspath(objects_from),
            min_score=float(min_score),
            per_object=int(per_object),
            refine=str(refine),
            refine_models=None if refine_models is None else os.fspath(refine_models),
        )

    @property
    def model_kind(self) -> str:
        """The pose model's kind: ``"tnet"``, ``"rnet"``, ``"full"``, ``"rgb"``, ``"rgb-dense"``."""
        return self._native.model_kind

    @property
    def needs_depth(self) -> bool:
        """Whether :meth:`predict` needs ``depth`` (the RGB-D models)."""
        return self._native.needs_depth

    def predict(self, rgb: Any, K: Any, depth: Optional[Any] = None) -> List[Dict[str, Any]]:
        """The objects found in one image, best first per object.

        Args:
            rgb: ``uint8`` array ``(H, W, 3)``.
            K: the intrinsics, ``(3, 3)`` (or nine numbers, row-major).
            depth: ``(H, W)`` depth in metres (0 or NaN where none), registered to ``rgb``;
                needed by the RGB-D models.

        Returns:
            Per detection a dict: ``obj_id``, ``score`` (the detection's), ``pose_score``
            (the pose model's confidence, 1 where it has none), ``bbox`` (``[x, y, w, h]``,
            pixels), ``R`` (``(3, 3)``, camera from object) and ``t`` (``(3,)``, metres) —
            each None where the model predicts none (TNet: no R; RNet: no t) or the detection
            had too few valid depth pixels —, ``mask`` (``(H, W)`` bool, or None for a
            detector without masks).
        """
        image = np.ascontiguousarray(rgb, dtype=np.uint8)
        k = np.asarray(K, dtype=np.float64).reshape(3, 3)
        d = None if depth is None else np.ascontiguousarray(depth, dtype=np.float32)
        found: List[Dict[str, Any]] = self._native.predict(image, k, d)
        return found


def predict(
    model: PathLike,
    detector: PathLike,
    rgb: Any,
    K: Any,
    depth: Optional[Any] = None,
    *,
    objects_from: Optional[PathLike] = None,
    min_score: float = 0.05,
    per_object: int = 1,
    refine: str = "none",
) -> List[Dict[str, Any]]:
    """:meth:`Predictor.predict` of one image with models loaded for it; for many images,
    hold a :class:`Predictor` (the models are loaded once)."""
    return Predictor(
        model,
        detector,
        objects_from=objects_from,
        min_score=min_score,
        per_object=per_object,
        refine=refine,
    ).predict(rgb, K, depth)
