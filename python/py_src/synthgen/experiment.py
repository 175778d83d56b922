"""synthgen's experiments from Python: the same library calls as ``synthgen experiment mix``,
``sim2real`` and ``rgb`` (the Rust crate ``synthgen-experiment``), with the same outputs in
``out``, the same resuming (a re-run with the same options keeps the finished steps) and the
same refusals. Every option is keyword-only and has the CLI flag's default.

>>> import synthgen
>>> r = synthgen.experiment.sim2real(
...     test="../shared/data/ycbv_real", fit="../shared/data/ycbv_real",
...     test_scenes=[2], quick=True, out="/tmp/s2r")
>>> r["report"]["all"]["mean_centre_error_cm"]  # doctest: +SKIP
"""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Dict, Optional, Union

from . import _native
from ._commands import Progress, _command_line
from ._progress import callback
from ._types import PathLike


def _path(p: Optional[PathLike]) -> Optional[str]:
    return None if p is None else os.fspath(p)


def _run(kind: str, options: Dict[str, Any], progress: Progress) -> str:
    # The reproducing call: the keyword arguments as given (the budget's flattened), without
    # those left at an empty or off default.
    flat = {k: v for k, v in options.items() if k != "budget"}
    flat.update(options.get("budget", {}))
    shown = {k: v for k, v in flat.items() if v is not None and v is not False and v != []}
    options["command_line"] = _command_line(f"experiment.{kind}", shown)
    return _native.run_experiment(kind, json.dumps(options), progress=callback(progress))


def _report(out: str, markdown: str) -> Dict[str, Any]:
    path = Path(out) / "report.json"
    report = json.loads(path.read_text()) if path.is_file() else None
    return {"out": out, "markdown": markdown, "report": report}


def mix(
    *,
    real: Optional[PathLike] = None,
    real_proxy: bool = False,
    synth: Optional[PathLike] = None,
    scene: Optional[PathLike] = None,
    objects: Sequence[PathLike] = (),
    obj_ids: Sequence[int] = (),
    model: str = "tnet",
    total: Optional[int] = None,
    ratios: Sequence[str] = (),
    test_count: Optional[int] = None,
    test_scenes: Sequence[Union[int, str]] = (),
    plus_synth: Sequence[int] = (),
    epochs: Optional[int] = None,
    batch: Optional[int] = None,
    lr: Optional[float] = None,
    points: Optional[int] = None,
    width: Optional[int] = None,
    seed: int = 0,
    repeats: int = 1,
    quick: bool = False,
    out: PathLike = "runs/mix",
    force: bool = False,
    jobs: Optional[int] = None,
    progress: Progress = None,
) -> Dict[str, Any]:
    """The real/synthetic mixing table, as ``synthgen experiment mix`` runs it: for each
    composition of a fixed-size training set, mix, train the same model with the same budget,
    and test on the same held-out real frames (docs/experiments.md).

    Args:
        real: the real dataset (BOP, Linemod or YCB-Video); or ``real_proxy=True`` for a
            rendered stand-in.
        synth: a synthetic dataset; absent, it is rendered from ``objects`` (or the real
            set's annotated models) with ``scene``.
        model: ``"tnet"``, ``"rnet"`` or ``"full"``.
        total, ratios, test_count, test_scenes, plus_synth: the rows and the test split.
        epochs, batch, lr, points, width: the training budget of every row.
        quick: small and fast, to check the pipeline.
        progress: as for :func:`synthgen.render`.

    Returns:
        ``out``, ``markdown`` (the table), ``table`` (the rows of ``table.csv`` as dicts).
    """
    o = _path(out) or "runs/mix"
    md = _run(
        "mix",
        dict(
            real=_path(real),
            real_proxy=real_proxy,
            synth=_path(synth),
            scene=_path(scene),
            objects=[os.fspath(p) for p in objects],
            obj_ids=[int(i) for i in obj_ids],
            model=model,
            total=total,
            ratios=[str(r) for r in ratios],
            test_count=test_count,
            test_scenes=[str(s) for s in test_scenes],
            plus_synth=[int(k) for k in plus_synth],
            budget=dict(epochs=epochs, batch=batch, lr=lr, points=points, width=width),
            seed=int(seed),
            repeats=int(repeats),
            quick=quick,
            out=o,
            force=force,
            jobs=jobs,
        ),
        progress,
    )
    with open(Path(o) / "table.csv", newline="") as f:
        table = list(csv.DictReader(f))
    return {"out": o, "markdown": md, "table": table}


def sim2real(
    *,
    test: PathLike,
    fit: Optional[PathLike] = None,
    test_scenes: Sequence[int] = (),
    model: str = "tnet",
    frames: Optional[int] = None,
    scene: Optional[PathLike] = None,
    models: Optional[PathLike] = None,
    cycles_frames: Optional[int] = None,
    epochs: Optional[int] = None,
    batch: Optional[int] = None,
    lr: Optional[float] = None,
    points: Optional[int] = None,
    width: Optional[int] = None,
    ablation: bool = False,
    unseen_up: str = "stable",
    mask_jitter_px: int = 3,
    mask_shift_px: int = 0,
    occlusion_prob: float = 0.0,
    point_dropout: float = 0.0,
    per_object: bool = False,
    ensemble: Optional[int] = None,
    refine: str = "icp",
    visible_box: str = "none",
    seed: int = 0,
    rows: Sequence[str] = (),
    max_failed_fraction: float = 0.01,
    detector: Optional[PathLike] = "train",
    detector_epochs: Optional[int] = None,
    quick: bool = False,
    out: PathLike = "runs/sim2real",
    force: bool = False,
    jobs: Optional[int] = None,
    progress: Progress = None,
) -> Dict[str, Any]:
    """Train on synthgen's frames only, test on real ones, as ``synthgen experiment
    sim2real`` runs it: fit the scene (and the sensor) to ``fit``, render, train one model per
    synthetic set, score it on the real test frames beside the naive baselines.

    Args:
        test: the real test frames; ``test_scenes`` of it are held out of the fits.
        fit: real frames the scene and sensor are fitted to (or ``scene``, a scene file, with
            the RGB models).
        model: ``"tnet"``, ``"rnet"``, ``"full"`` (depth) or ``"rgb"``, ``"rgb-dense"`` (RGB,
            scored with the GT boxes).
        models, cycles_frames: the RGB models' replacement meshes and Cycles rows.
        ablation, unseen_up, mask_jitter_px, mask_shift_px, occlusion_prob, point_dropout,
            per_object, ensemble: the depth models' knobs (docs/experiments.md).
        refine: ``"icp"`` (the depth models' poses refined by ICP of the object's model on
            the real depth: TNet's centre, the fit giving its rotation; Full's whole pose, its
            rotation judging between fits the depth cannot tell apart; the rows with a
            rotation are scored with BOP's AR and the ADD-S AUC), ``"edges"`` (the RGB models'
            estimates refined on the real RGB images:
            each object's outline moved onto the image's edges), ``"views"`` (as edges, after a
            search over each object's rotations about the estimate, with the models' colours
            where they have them) or ``"none"``.
        visible_box: with ``refine="edges"`` or ``"views"``: ``"gt"`` keeps each refinement
            to its instance's GT visible box (as ``synthgen eval --visible-box gt``), ``"none"``
            does not.
        rows: only these rows.
        detector: the detector of the scores from raw frames (``report["no_gt"]`` and
            ``report["detection"]``): ``"train"`` (trained on the main row's synthetic frames,
            ``detector_epochs`` epochs), a folder ``synthgen detector train`` wrote, or
            ``None`` / ``"none"`` (no scores from raw frames).
        progress: as for :func:`synthgen.render`.

    Returns:
        ``out``, ``markdown`` (``report.md``), ``report`` (``report.json``).
    """
    o = _path(out) or "runs/sim2real"
    det = "none" if detector is None else os.fspath(detector)
    md = _run(
        "sim2real",
        dict(
            fit=_path(fit),
            test=os.fspath(test),
            test_scenes=[int(s) for s in test_scenes],
            model=model,
            frames=frames,
            scene=_path(scene),
            models=_path(models),
            cycles_frames=cycles_frames,
            budget=dict(epochs=epochs, batch=batch, lr=lr, points=points, width=width),
            ablation=ablation,
            unseen_up=unseen_up,
            mask_jitter_px=int(mask_jitter_px),
            mask_shift_px=int(mask_shift_px),
            occlusion_prob=float(occlusion_prob),
            point_dropout=float(point_dropout),
            per_object=per_object,
            ensemble=ensemble,
            refine=refine,
            visible_box=visible_box,
            seed=int(seed),
            rows=[str(r) for r in rows],
            max_failed_fraction=float(max_failed_fraction),
            detector=det,
            detector_epochs=detector_epochs,
            quick=quick,
            out=o,
            force=force,
            jobs=jobs,
        ),
        progress,
    )
    return _report(o, md)


def rgb(
    *,
    train: PathLike,
    test: PathLike,
    train_split: Optional[str] = None,
    test_split: Optional[str] = None,
    test_scenes: Sequence[int] = (),
    variants: Sequence[str] = ("centre-tz", "xyz"),
    epochs: Optional[int] = None,
    batch: Optional[int] = None,
    lr: float = 2e-3,
    width: Optional[int] = None,
    crop_size: Optional[int] = None,
    min_visib_fract: float = 0.1,
    seed: int = 0,
    quick: bool = False,
    out: PathLike = "runs/rgb",
    force: bool = False,
    jobs: Optional[int] = None,
    progress: Progress = None,
) -> Dict[str, Any]:
    """Seed 001's Table 1, as ``synthgen experiment rgb`` runs it: the RGB model trained once
    per translation variant (``"centre-tz"``, ``"xyz"``) on the same crops, scored per object
    and scene on ``test``.

    Returns:
        ``out``, ``markdown`` (``table.md``), ``report`` (``report.json``).
    """
    o = _path(out) or "runs/rgb"
    md = _run(
        "rgb",
        dict(
            train=os.fspath(train),
            test=os.fspath(test),
            train_split=train_split,
            test_split=test_split,
            test_scenes=[int(s) for s in test_scenes],
            variants=[str(v) for v in variants],
            epochs=epochs,
            batch=batch,
            lr=float(lr),
            width=width,
            crop_size=crop_size,
            min_visib_fract=float(min_visib_fract),
            seed=int(seed),
            quick=quick,
            out=o,
            force=force,
            jobs=jobs,
        ),
        progress,
    )
    return _report(o, md)
