# Stubs of the native module (python/src/*.rs); checked against the built module with
# `python -m mypy.stubtest synthgen._native` in .ci/run.
from collections.abc import Sequence
from os import PathLike
from typing import Any, Callable, Dict, List, Optional, Tuple, Union

import numpy as np
from typing_extensions import TypeAlias, final

_Path: TypeAlias = Union[str, PathLike[str]]
_Progress: TypeAlias = Callable[[str, str, int], None]

__version__: str

class Error(Exception): ...
class InputError(Error): ...
class InternalError(Error): ...

@final
class RenderJob:
    def __new__(
        cls,
        objects: Sequence[_Path],
        *,
        obj_ids: Optional[Sequence[int]] = None,
        scene: Optional[_Path] = None,
        camera: Optional[str] = None,
        image_size: Optional[Tuple[int, int]] = None,
        units: str = ...,
        seed: int = 0,
        start: int = 0,
        count: int = 100,
        threads: int = 0,
        progress: Optional[_Progress] = None,
    ) -> RenderJob: ...
    @property
    def frame_range(self) -> Tuple[int, int]: ...
    @property
    def seed(self) -> int: ...
    @property
    def threads(self) -> int: ...
    @property
    def image_size(self) -> Tuple[int, int]: ...
    @property
    def cam_K(self) -> np.ndarray: ...
    @property
    def objects(self) -> List[Tuple[int, str, str]]: ...
    def spec_toml(self) -> str: ...
    def frame(self, index: int) -> Dict[str, Any]: ...
    def frames_batch(self, indices: Sequence[int]) -> List[Dict[str, Any]]: ...
    def time_in_memory(self) -> float: ...

@final
class Dataset:
    def __new__(cls, path: _Path, splits: Sequence[str] = ...) -> Dataset: ...
    def __len__(self) -> int: ...
    @property
    def root(self) -> str: ...
    @property
    def layout(self) -> str: ...
    @property
    def splits(self) -> List[str]: ...
    def frame_obj_ids(self) -> List[List[int]]: ...
    def frame_visib_fracts(self) -> List[List[Optional[float]]]: ...
    def annotations(self, i: int, gt_ids: Optional[Sequence[int]] = None) -> Dict[str, Any]: ...
    def images(
        self,
        i: int,
        gt_ids: Sequence[int],
        rgb: bool = True,
        depth: bool = True,
        masks: bool = True,
    ) -> Dict[str, np.ndarray]: ...
    def model_file(self, obj_id: int) -> Tuple[str, str]: ...
    def eval_model(self, obj_id: int) -> Tuple[np.ndarray, float, bool]: ...

@final
class Predictor:
    def __new__(
        cls,
        model: _Path,
        detector: _Path,
        *,
        objects_from: Optional[_Path] = None,
        min_score: float = 0.05,
        per_object: int = 1,
        refine: str = "none",
        refine_models: Optional[_Path] = None,
    ) -> Predictor: ...
    @property
    def model_kind(self) -> str: ...
    @property
    def needs_depth(self) -> bool: ...
    def predict(
        self, rgb: np.ndarray, K: np.ndarray, depth: Optional[np.ndarray] = None
    ) -> List[Dict[str, Any]]: ...

def render(
    objects: Sequence[_Path],
    out: _Path,
    *,
    frames: int = 100,
    first_frame: int = 0,
    scene: Optional[_Path] = None,
    camera: Optional[str] = None,
    image_size: Optional[Tuple[int, int]] = None,
    units: str = ...,
    obj_ids: Optional[Sequence[int]] = None,
    seed: int = 0,
    threads: int = 0,
    format: str = ...,
    split: str = ...,
    chunk_size: int = 1000,
    rgb_format: str = ...,
    jpg_quality: int = 95,
    depth_scale: Optional[float] = None,
    force: bool = False,
    fail_fast: bool = False,
    command_line: Sequence[str] = ...,
    progress: Optional[_Progress] = None,
) -> Dict[str, Any]: ...
def mix(
    real: _Path,
    synth: _Path,
    out: _Path,
    *,
    real_count: int,
    synth_count: int,
    test_count: Optional[int] = None,
    seed: int = 0,
    force: bool = False,
    exclude_shared: bool = False,
    test_scenes: Sequence[str] = ...,
    command_line: Sequence[str] = ...,
    progress: Optional[_Progress] = None,
) -> Dict[str, Any]: ...
def run_experiment(
    kind: str,
    options: str,
    *,
    progress: Optional[_Progress] = None,
) -> str: ...
def evaluate(
    data: _Path,
    results: _Path,
    *,
    split: Optional[str] = None,
    min_visib_fract: float = 0.1,
    bop: bool = False,
    targets: Optional[_Path] = None,
    visib_gt_min: float = -1.0,
    rotations: str = "as_stored",
) -> Dict[str, Any]: ...
def evaluate_detections(
    data: _Path,
    detections: _Path,
    *,
    split: Optional[str] = None,
    targets: Optional[_Path] = None,
    all_frames: bool = False,
    bbox_type: str = "amodal",
) -> Dict[str, Any]: ...

ADD_THRESHOLD_FRACTION: float
TE_THRESHOLD_M: float
RE_THRESHOLD_DEG: float

def add(
    points_m: np.ndarray,
    R_gt: np.ndarray,
    t_gt: np.ndarray,
    R_est: np.ndarray,
    t_est: np.ndarray,
) -> float: ...
def add_s(
    points_m: np.ndarray,
    R_gt: np.ndarray,
    t_gt: np.ndarray,
    R_est: np.ndarray,
    t_est: np.ndarray,
) -> float: ...
def re(R_gt: np.ndarray, R_est: np.ndarray) -> float: ...
def te(t_gt: np.ndarray, t_est: np.ndarray) -> float: ...
def within_5cm5deg(
    R_gt: np.ndarray, t_gt: np.ndarray, R_est: np.ndarray, t_est: np.ndarray
) -> bool: ...
def pose_errors(
    points_m: np.ndarray,
    diameter_m: float,
    symmetric: bool,
    R_gt: np.ndarray,
    t_gt: np.ndarray,
    R_est: np.ndarray,
    t_est: np.ndarray,
) -> Dict[str, Union[float, bool]]: ...
