"""`render`, `mix`, `evaluate`: what `synthgen render`, `synthgen mix` and `synthgen eval
--results` do, from Python."""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from typing import Any, Dict, Optional, Tuple, Union

from . import _native
from ._progress import ProgressCallback, callback
from ._types import PathLike

Progress = Union[bool, None, ProgressCallback]


def _command_line(name: str, args: Dict[str, Any]) -> list:
    shown = ", ".join(f"{k}={v!r}" for k, v in args.items() if v is not None)
    return [
        os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else "python",
        f"synthgen.{name}({shown})",
    ]


def render(
    objects: Sequence[PathLike],
    out: PathLike,
    frames: int = 100,
    *,
    first_frame: int = 0,
    scene: Optional[PathLike] = None,
    camera: Optional[str] = None,
    image_size: Optional[Tuple[int, int]] = None,
    units: str = "auto",
    obj_ids: Optional[Sequence[int]] = None,
    seed: int = 0,
    threads: int = 0,
    format: str = "bop",
    split: str = "train_pbr",
    chunk_size: int = 1000,
    rgb_format: str = "png",
    jpg_quality: int = 95,
    depth_scale: Optional[float] = None,
    force: bool = False,
    fail_fast: bool = False,
    progress: Progress = None,
) -> Dict[str, Any]:
    """Renders frames ``first_frame .. first_frame + frames`` and writes them as a dataset,
    as ``synthgen render`` does (same files, ``synthgen.json`` manifest, lock on ``out``).

    Args:
        objects, scene, camera, image_size, units, obj_ids, seed, threads: as for
            :class:`Generator`.
        out: the dataset folder; it must be empty or absent unless ``force``, which replaces
            an output synthgen wrote there (everything in it is removed first) and refuses a
            folder holding other files.
        format: ``"bop"`` (default), ``"linemod"`` or ``"ycbv"``.
        split, chunk_size: BOP's split folder and frames per scene folder.
        rgb_format, jpg_quality: ``"png"`` or ``"jpg"`` RGB images.
        depth_scale: depth PNG value x this = millimetres (default: the format's).
        fail_fast: stop at the first failed frame instead of recording it and going on.
        progress: ``None``: a bar on stderr when it is a terminal; ``True``/``False``: always
            / never; or a callable ``(event, text, n)``.

    Returns:
        ``out``, ``written``, ``rendered``, ``failures`` (``(frame, message)`` pairs),
        ``nothing_visible``, ``physics_fallbacks``, ``depth_out_of_range_px``,
        ``description``.

    Raises:
        synthgen.InputError: a bad mesh, scene or option, an output folder in use or not
            empty, or most frames showing no object.
    """
    args = dict(
        objects=[os.fspath(o) for o in objects],
        out=os.fspath(out),
        frames=frames,
        first_frame=first_frame,
        scene=scene,
        camera=camera,
        seed=seed,
        format=format,
    )
    return _native.render(
        [os.fspath(o) for o in objects],
        os.fspath(out),
        frames=int(frames),
        first_frame=int(first_frame),
        scene=None if scene is None else os.fspath(scene),
        camera=camera,
        image_size=(
            None if image_size is None else (int(image_size[0]), int(image_size[1]))
        ),
        units=units,
        obj_ids=None if obj_ids is None else [int(i) for i in obj_ids],
        seed=int(seed),
        threads=int(threads),
        format=format,
        split=split,
        chunk_size=int(chunk_size),
        rgb_format=rgb_format,
        jpg_quality=int(jpg_quality),
        depth_scale=depth_scale,
        force=force,
        fail_fast=fail_fast,
        command_line=_command_line("render", args),
        progress=callback(progress),
    )


def mix(
    real: PathLike,
    synth: PathLike,
    out: PathLike,
    real_count: int,
    synth_count: int,
    *,
    test_count: Optional[int] = None,
    seed: int = 0,
    force: bool = False,
    exclude_shared: bool = False,
    test_scenes: Sequence[Union[int, str]] = (),
    progress: Progress = None,
) -> Dict[str, Any]:
    """Draws a reproducible mix of ``real_count`` real and ``synth_count`` synthetic training
    frames plus a real test split into ``out`` (BOP, with ``provenance.json``), as ``synthgen
    mix`` does. Frames without ``mask/`` and ``scene_gt_info`` (YCB-Video, Linemod) get them
    computed from their poses and models.

    Args:
        test_count: real frames held out for testing (default: 10% of the real frames).
        test_scenes: hold out every frame of these scenes (``2`` or ``"test/2"``) instead.
        force: replace an existing mix (or other output synthgen wrote) in ``out``; a folder
            holding other files is refused.
        exclude_shared: leave out training frames that are the same image as a test frame.

    Returns:
        ``out``, ``train_real``, ``train_synth``, ``test``, ``linked``, ``copied``,
        ``completed``, ``excluded_shared``, ``duplicate_train``, ``warnings``.
    """
    args = dict(
        real=os.fspath(real),
        synth=os.fspath(synth),
        out=os.fspath(out),
        real_count=real_count,
        synth_count=synth_count,
        seed=seed,
    )
    return _native.mix(
        os.fspath(real),
        os.fspath(synth),
        os.fspath(out),
        real_count=int(real_count),
        synth_count=int(synth_count),
        test_count=None if test_count is None else int(test_count),
        seed=int(seed),
        force=force,
        exclude_shared=exclude_shared,
        test_scenes=[str(s) for s in test_scenes],
        command_line=_command_line("mix", args),
        progress=callback(progress),
    )


def evaluate(
    data: PathLike,
    results: PathLike,
    *,
    split: Optional[str] = None,
    min_visib_fract: float = 0.1,
    bop: bool = False,
    targets: Optional[PathLike] = None,
    visib_gt_min: float = -1.0,
    rotations: str = "as_stored",
) -> Dict[str, Any]:
    """Scores a BOP results CSV (``scene_id,im_id,obj_id,score,R,t,time``) against
    ``data``'s ground truth, as ``synthgen eval --results`` does.

    With ``bop=True`` also BOP's Average Recall (VSD, MSSD, MSPD), as ``synthgen eval --bop``
    computes it (docs/metrics.md): ``targets`` is a ``test_targets_bop19.json`` (default: the
    one in ``data``, else every GT instance), ``visib_gt_min`` bop_toolkit's setting.
    ``rotations`` says which matrices ADD(-S), the rotation error and 5cm5° use:
    ``"as_stored"`` (the files' numbers, as bop_toolkit's ``pose_error``) or ``"nearest"``
    (the nearest proper rotation of each), as ``eval --rotations``.

    Returns:
        ``scores``: per object id (as a string) and ``"all"``: ``n_gt``, ``n_est``,
        ``add_s_acc``, ``mean_add_mm``, ``acc_5cm5deg``, ``mean_te_cm``, ``mean_re_deg`` (the
        JSON ``synthgen eval --json`` writes); ``bop``: the ``"bop"`` object of
        ``eval --bop --json`` (``vsd``, ``mssd``, ``mspd``, ``ar``, ``counts``), or None;
        ``markdown`` (the table the CLI prints); ``split``; ``estimates``;
        ``unmatched_estimates``; ``skipped_rows`` (``(line, message)`` of rows that could
        not be read).
    """
    return _native.evaluate(
        os.fspath(data),
        os.fspath(results),
        split=split,
        min_visib_fract=float(min_visib_fract),
        bop=bool(bop),
        targets=None if targets is None else os.fspath(targets),
        visib_gt_min=float(visib_gt_min),
        rotations=str(rotations),
    )


def evaluate_detections(
    data: PathLike,
    detections: PathLike,
    *,
    split: Optional[str] = None,
    targets: Optional[PathLike] = None,
    all_frames: bool = False,
    bbox_type: str = "amodal",
) -> Dict[str, Any]:
    """Scores a BOP detections file (a JSON list of ``scene_id``, ``image_id``,
    ``category_id``, ``score``, ``bbox`` and, optionally, ``segmentation`` as COCO RLE) against
    ``data``'s ground truth as bop_toolkit's ``eval_bop22_coco.py`` scores BOP's detection and
    segmentation tasks, as ``synthgen detector eval`` does (docs/metrics.md).

    ``targets`` is a BOP targets file choosing the images (default: ``data``'s
    ``test_targets_bop19.json`` when it has one, else every frame; ``all_frames=True``: every
    frame); ``bbox_type`` the GT box, ``"amodal"`` (bop_toolkit's default) or ``"modal"``.

    Returns:
        ``bbox`` and ``segm`` (None when no entry has a mask): ``stats`` with bop_toolkit's
        names (``AP``, ``AP50``, ``AP75``, ``AP_small``, ..., ``AR100``, ...) and
        ``objects`` (per object id as a string: ``AP``, ``AP50``, ``AP75``, ``AR100``,
        ``n_gt``); ``n_images``, ``n_gt``, ``entries``, ``scored``, ``other_images``,
        ``objects_without_gt``, ``without_mask``, ``images_with_rendered_masks``.
    """
    result: Dict[str, Any] = _native.evaluate_detections(
        os.fspath(data),
        os.fspath(detections),
        split=split,
        targets=None if targets is None else os.fspath(targets),
        all_frames=bool(all_frames),
        bbox_type=str(bbox_type),
    )
    return result
