"""`Frame`: one annotated RGB-D frame, rendered or read from a dataset (the same class)."""

from __future__ import annotations

from typing import Any, Callable, Dict, List, Optional

import numpy as np

#: ``loader(rgb, depth, masks)`` -> the image arrays asked for (a dataset frame's images are
#: decoded on first access).
ImageLoader = Callable[[bool, bool, bool], Dict[str, np.ndarray]]

_MASK_KEYS = ("instance_ids", "masks", "masks_visib")


class Frame:
    """One frame: images as numpy arrays and the annotated objects in GT order.

    Attributes:
        index: the generator's global frame index, or the frame's position in its dataset.
        rgb: ``uint8`` array ``(H, W, 3)``.
        depth: ``float32`` array ``(H, W)`` in metres, 0 where there is no reading (after the
            sensor model for rendered frames); ``None`` for a dataset frame without depth.
        instance_ids: ``uint16`` array ``(H, W)``: ``k + 1`` where ``objects[k]`` is visible,
            0 elsewhere.
        masks: ``bool`` array ``(N, H, W)``: each object's full silhouette inside the image
            (BOP ``mask/``); ``None`` for datasets that do not have them (YCB-Video, Linemod).
        masks_visib: ``bool`` array ``(N, H, W)``: the visible part (BOP ``mask_visib/``).
        cam_K: ``float64`` array ``(3, 3)``, the intrinsics.
        objects: one dict per object, in GT order: ``obj_id``, ``R`` (3x3 rotation of
            ``cam_from_obj``), ``t`` (3, metres), ``bbox_obj`` and ``bbox_visib`` (BOP
            ``[x, y, w, h]``), ``visib_fract``, ``px_count_all``, ``px_count_valid``,
            ``px_count_visib`` (``None`` where a dataset has no ``scene_gt_info``) and
            ``gt_id`` (the index in the frame's full GT list).
        source: for a dataset frame, ``split``, ``scene_id``, ``im_id``, ``rgb_path`` and
            ``depth_scale``; ``None`` for a rendered one.
    """

    __slots__ = (
        "_arrays",
        "_loader",
        "cam_K",
        "index",
        "objects",
        "source",
    )

    def __init__(
        self,
        *,
        index: int,
        cam_K: np.ndarray,
        objects: List[Dict[str, Any]],
        rgb: Optional[np.ndarray] = None,
        depth: Optional[np.ndarray] = None,
        instance_ids: Optional[np.ndarray] = None,
        masks: Optional[np.ndarray] = None,
        masks_visib: Optional[np.ndarray] = None,
        source: Optional[Dict[str, Any]] = None,
        loader: Optional[ImageLoader] = None,
    ) -> None:
        self.index = index
        self.cam_K = cam_K
        self.objects = objects
        self.source = source
        self._loader = loader
        self._arrays: Dict[str, Optional[np.ndarray]] = {}
        if loader is None:
            self._arrays = {
                "rgb": rgb,
                "depth": depth,
                "instance_ids": instance_ids,
                "masks": masks,
                "masks_visib": masks_visib,
            }

    def _get(self, key: str) -> Optional[np.ndarray]:
        if key not in self._arrays:
            self._load(key == "rgb", key == "depth", key in _MASK_KEYS)
        return self._arrays[key]

    def _load(self, rgb: bool, depth: bool, masks: bool) -> None:
        rgb, depth = (
            rgb and "rgb" not in self._arrays,
            depth and "depth" not in self._arrays,
        )
        masks = masks and "masks" not in self._arrays
        if not (rgb or depth or masks) or self._loader is None:
            return
        loaded = self._loader(rgb, depth, masks)
        keys = (
            (("rgb",) if rgb else ())
            + (("depth",) if depth else ())
            + (_MASK_KEYS if masks else ())
        )
        for k in keys:
            self._arrays[k] = loaded.get(k)

    @property
    def rgb(self) -> np.ndarray:
        a = self._get("rgb")
        assert a is not None
        return a

    @property
    def depth(self) -> Optional[np.ndarray]:
        return self._get("depth")

    @property
    def instance_ids(self) -> np.ndarray:
        a = self._get("instance_ids")
        assert a is not None
        return a

    @property
    def masks(self) -> Optional[np.ndarray]:
        return self._get("masks")

    @property
    def masks_visib(self) -> Optional[np.ndarray]:
        return self._get("masks_visib")

    @property
    def obj_ids(self) -> List[int]:
        """The objects' ids in GT order."""
        return [o["obj_id"] for o in self.objects]

    @property
    def height(self) -> int:
        return int(self.rgb.shape[0])

    @property
    def width(self) -> int:
        return int(self.rgb.shape[1])

    def load(self) -> Frame:
        """Decodes every image now (a dataset frame loads them on first access)."""
        self._load(True, True, True)
        self._loader = None
        return self

    def __getstate__(self) -> Dict[str, Any]:
        # Pickled (e.g. to a DataLoader's main process) with its images, never the loader.
        self.load()
        return {
            "index": self.index,
            "cam_K": self.cam_K,
            "objects": self.objects,
            "source": self.source,
            **self._arrays,
        }

    def __setstate__(self, state: Dict[str, Any]) -> None:
        self.__init__(**state)  # type: ignore[misc]

    def __repr__(self) -> str:
        where = ""
        if self.source is not None:
            where = f" {self.source['split']}/{self.source['scene_id']}/{self.source['im_id']}"
        return f"<synthgen.Frame {self.index}{where}: objects {self.obj_ids}>"
