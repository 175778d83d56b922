"""synthgen from Python: annotated RGB-D frames rendered in memory as numpy arrays, BOP /
Linemod / YCB-Video datasets as the same frames, the CLI's render, mix and eval, poses
from images with no GT (:class:`Predictor`, as ``synthgen predict``), its
experiments (:mod:`synthgen.experiment`), the pose metrics, and PyTorch adapters in
:mod:`synthgen.torch` (imported only when used).

>>> import synthgen
>>> gen = synthgen.Generator(objects=["driller.ply"], scene="scenes/tabletop.toml", seed=0)
>>> frame = gen[0]
>>> frame.rgb.shape, frame.depth.dtype, frame.objects[0]["obj_id"]
((480, 640, 3), dtype('float32'), 1)
"""

from __future__ import annotations

import importlib
from typing import Any

from . import _native, experiment, metrics
from ._commands import evaluate, evaluate_detections, mix, render
from ._dataset import Dataset, open_dataset
from ._frame import Frame
from ._generator import Generator
from ._native import Error, InputError, InternalError
from ._predict import Predictor, predict
from ._progress import ProgressBar

__version__: str = _native.__version__

__all__ = [
    "Dataset",
    "Error",
    "Frame",
    "Generator",
    "InputError",
    "InternalError",
    "Predictor",
    "ProgressBar",
    "__version__",
    "evaluate",
    "evaluate_detections",
    "experiment",
    "metrics",
    "mix",
    "open_dataset",
    "predict",
    "render",
]


def __getattr__(name: str) -> Any:
    # PEP 562: `synthgen.torch` imports torch only when it is asked for.
    if name == "torch":
        return importlib.import_module(".torch", __name__)
    raise AttributeError(f"module 'synthgen' has no attribute {name!r}")
