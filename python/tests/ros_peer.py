"""A ROS 2 peer that is not synthgen: Eclipse Cyclone DDS (its Python binding, the RMW of many
ROS 2 installs) with ROS 2's type names and CDR, talking to `synthgen ros` over DDS.

Run as a script inside a private network namespace (`unshare -n`: DDS discovery multicasts,
and here the multicast never leaves the namespace's loopback). It starts the node, publishes
camera info and images (good ones, one with an unknown encoding, one whose size is not its
camera info's), reads the node's Detection3DArray and Detection2DArray, stops the node with
SIGINT and writes what it saw as JSON for the test (test_ros_node.py) to check field by field.
"""

# No `from __future__ import annotations`: Cyclone DDS reads the field types at run time.

import argparse
import json
import signal
import subprocess
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple

import cyclonedds.idl.types as t
from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from PIL import Image as PilImage


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: t.int32
    nanosec: t.uint32


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@dataclass
class Image(IdlStruct, typename="sensor_msgs::msg::dds_::Image_"):
    header: Header
    height: t.uint32
    width: t.uint32
    encoding: str
    is_bigendian: t.uint8
    step: t.uint32
    data: t.sequence[t.uint8]


@dataclass
class RegionOfInterest(IdlStruct, typename="sensor_msgs::msg::dds_::RegionOfInterest_"):
    x_offset: t.uint32
    y_offset: t.uint32
    height: t.uint32
    width: t.uint32
    do_rectify: bool


@dataclass
class CameraInfo(IdlStruct, typename="sensor_msgs::msg::dds_::CameraInfo_"):
    header: Header
    height: t.uint32
    width: t.uint32
    distortion_model: str
    d: t.sequence[t.float64]
    k: t.array[t.float64, 9]
    r: t.array[t.float64, 9]
    p: t.array[t.float64, 12]
    binning_x: t.uint32
    binning_y: t.uint32
    roi: RegionOfInterest


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: t.float64
    y: t.float64
    z: t.float64


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: t.float64
    y: t.float64
    z: t.float64


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: t.float64
    y: t.float64
    z: t.float64
    w: t.float64


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point
    orientation: Quaternion


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose
    covariance: t.array[t.float64, 36]


@dataclass
class ObjectHypothesis(IdlStruct, typename="vision_msgs::msg::dds_::ObjectHypothesis_"):
    class_id: str
    score: t.float64


@dataclass
class ObjectHypothesisWithPose(
    IdlStruct, typename="vision_msgs::msg::dds_::ObjectHypothesisWithPose_"
):
    hypothesis: ObjectHypothesis
    pose: PoseWithCovariance


@dataclass
class BoundingBox3D(IdlStruct, typename="vision_msgs::msg::dds_::BoundingBox3D_"):
    center: Pose
    size: Vector3


@dataclass
class Detection3D(IdlStruct, typename="vision_msgs::msg::dds_::Detection3D_"):
    header: Header
    results: t.sequence[ObjectHypothesisWithPose]
    bbox: BoundingBox3D
    id: str


@dataclass
class Detection3DArray(IdlStruct, typename="vision_msgs::msg::dds_::Detection3DArray_"):
    header: Header
    detections: t.sequence[Detection3D]


@dataclass
class Point2D(IdlStruct, typename="vision_msgs::msg::dds_::Point2D_"):
    x: t.float64
    y: t.float64


@dataclass
class Pose2D(IdlStruct, typename="vision_msgs::msg::dds_::Pose2D_"):
    position: Point2D
    theta: t.float64


@dataclass
class BoundingBox2D(IdlStruct, typename="vision_msgs::msg::dds_::BoundingBox2D_"):
    center: Pose2D
    size_x: t.float64
    size_y: t.float64


@dataclass
class Detection2D(IdlStruct, typename="vision_msgs::msg::dds_::Detection2D_"):
    header: Header
    results: t.sequence[ObjectHypothesisWithPose]
    bbox: BoundingBox2D
    id: str


@dataclass
class Detection2DArray(IdlStruct, typename="vision_msgs::msg::dds_::Detection2DArray_"):
    header: Header
    detections: t.sequence[Detection2D]


FRAME_ID = "camera_color_optical_frame"


def loopback_multicast() -> None:
    """In a fresh network namespace: loopback up, multicast on it, routed to it."""
    for cmd in (
        ["ip", "link", "set", "lo", "up"],
        ["ip", "link", "set", "lo", "multicast", "on"],
        ["ip", "route", "add", "224.0.0.0/4", "dev", "lo"],
    ):
        subprocess.run(cmd, check=True)


def header(sec: int, frame_id: str = FRAME_ID) -> Header:
    return Header(stamp=Time(sec=sec, nanosec=250_000_000), frame_id=frame_id)


def camera_info(sec: int, k: List[float], width: int, height: int) -> CameraInfo:
    fx, _, cx, _, fy, cy, _, _, _ = k
    return CameraInfo(
        header=header(sec),
        height=height,
        width=width,
        distortion_model="plumb_bob",
        d=[0.0] * 5,
        k=k,
        r=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p=[fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
        binning_x=0,
        binning_y=0,
        roi=RegionOfInterest(0, 0, 0, 0, False),
    )


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--exe", required=True)
    ap.add_argument("--model", required=True)
    ap.add_argument("--detector", required=True)
    ap.add_argument("--image", required=True, help="an RGB PNG")
    ap.add_argument("--k", required=True, help="JSON: nine numbers, row-major")
    ap.add_argument("--record", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument(
        "--soak",
        type=float,
        default=0.0,
        help="instead of the checks: publish the image at --rate Hz for this many seconds",
    )
    ap.add_argument("--rate", type=float, default=5.0)
    ap.add_argument("--status-every", type=float, default=60.0, help="the node's, with --soak")
    ap.add_argument("--node-arg", action="append", default=[], help="more flags for the node")
    ap.add_argument(
        "--depth-mm",
        help="a 16-bit PNG of the image's depth in millimetres: published as 16UC1 beside each "
        "image, and the node started with --depth-topic (the RGB-D models)",
    )
    a = ap.parse_args()
    loopback_multicast()
    k = [float(v) for v in json.loads(a.k)]
    rgb = PilImage.open(a.image).convert("RGB")
    w, h = rgb.size
    node = subprocess.Popen(
        [
            a.exe,
            "ros",
            "--model",
            a.model,
            "--detector",
            a.detector,
            "--image-topic",
            "/camera/color/image_raw",
            "--min-score",
            "0",
            "--record",
            a.record,
            "--status-every",
            str(a.status_every) if a.soak > 0 else "0",
            "--domain-id",
            "0",
            *(["--depth-topic", "/camera/depth/image_rect_raw"] if a.depth_mm else []),
            *a.node_arg,
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    dp = DomainParticipant(0)
    sensor = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(5))
    reliable = Qos(Policy.Reliability.Reliable(1_000_000_000), Policy.History.KeepLast(50))
    image_w = DataWriter(dp, Topic(dp, "rt/camera/color/image_raw", Image), qos=sensor)
    info_w = DataWriter(dp, Topic(dp, "rt/camera/color/camera_info", CameraInfo), qos=sensor)
    depth_w = DataWriter(dp, Topic(dp, "rt/camera/depth/image_rect_raw", Image), qos=sensor)
    d3_r = DataReader(dp, Topic(dp, "rt/synthgen/detections", Detection3DArray), qos=reliable)
    d2_r = DataReader(dp, Topic(dp, "rt/synthgen/detections_2d", Detection2DArray), qos=reliable)

    got3: Dict[int, Any] = {}
    got2: Dict[int, Any] = {}

    def poll() -> None:
        for m in d3_r.take(N=100):
            if isinstance(m, Detection3DArray):
                got3[m.header.stamp.sec] = m
        for m in d2_r.take(N=100):
            if isinstance(m, Detection2DArray):
                got2[m.header.stamp.sec] = m

    def publish(
        sec: int, img: Image, wait_for: Optional[float], depth: Optional[Image] = None
    ) -> bool:
        """Camera info (and the depth) then the image, again every 0.2 s until the node
        answers for this stamp (best effort: the first may go before discovery) or `wait_for`
        seconds pass."""
        deadline = time.time() + (wait_for if wait_for is not None else a.timeout)
        while time.time() < deadline:
            info_w.write(camera_info(sec, k, w, h))
            if depth is not None:
                depth.header = header(sec)
                depth_w.write(depth)
            img.header = header(sec)
            image_w.write(img)
            end = time.time() + 0.2
            while time.time() < end:
                poll()
                if sec in got3 and sec in got2:
                    return True
                time.sleep(0.01)
        return False

    def image(width: int, height: int, encoding: str, data: bytes) -> Image:
        bpp = len(data) // (width * height)
        return Image(header(0), height, width, encoding, 0, width * bpp, data)

    good = image(w, h, "rgb8", rgb.tobytes())
    # bgr8 of the same picture: the channels swapped per pixel.
    px = bytearray(rgb.tobytes())
    px[0::3], px[2::3] = px[2::3], px[0::3]
    bgr = image(w, h, "bgr8", bytes(px))
    small = rgb.resize((w // 2, h // 2))
    if a.soak > 0:
        return soak(a, node, info_w, image_w, d3_r, good, k, w, h)
    steps: List[Dict[str, Any]] = []
    try:
        if a.depth_mm:
            import numpy as np

            mm = np.asarray(PilImage.open(a.depth_mm), dtype=np.uint16)
            depth = image(w, h, "16UC1", mm.astype("<u2").tobytes())
            steps.append({"sec": 100, "what": "rgbd", "answered": publish(100, good, None, depth)})
            # An image with no depth near its stamp: skipped after its wait; the node goes on.
            steps.append({"sec": 101, "what": "no depth", "answered": publish(101, good, 2.0)})
            steps.append(
                {"sec": 103, "what": "rgbd", "answered": publish(103, good, a.timeout, depth)}
            )
        else:
            ok = publish(100, good, None)
            steps.append({"sec": 100, "what": "rgb8", "answered": ok})
            # An encoding the node does not read, then a size that is not the camera info's:
            # both skipped (no answer), and the node goes on.
            bad = image(w, h, "yuv422", bytes(w * h * 2))
            steps.append({"sec": 101, "what": "yuv422", "answered": publish(101, bad, 2.0)})
            wrong = image(w // 2, h // 2, "rgb8", small.tobytes())
            steps.append({"sec": 102, "what": "size", "answered": publish(102, wrong, 2.0)})
            steps.append({"sec": 103, "what": "bgr8", "answered": publish(103, bgr, a.timeout)})
    finally:
        time.sleep(0.3)
        poll()
        out, err = stop(node)
    return write_out(a, steps, got3, got2, node.returncode, out, err)


def stop(node: "subprocess.Popen[str]") -> Tuple[str, str]:
    """SIGINT, as Ctrl-C stops the node (it finishes --record and prints its summary); its
    output. Killed if it has not stopped in 30 s."""
    node.send_signal(signal.SIGINT)
    try:
        return node.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        node.kill()
        return node.communicate()


def write_out(
    a: argparse.Namespace,
    steps: List[Dict[str, Any]],
    got3: Dict[int, Any],
    got2: Dict[int, Any],
    rc: int,
    out: str,
    err: str,
) -> int:
    """What the peer saw, as JSON for the test."""

    def plain(m: Any) -> Any:
        return json.loads(json.dumps(asdict(m), default=list))

    Path(a.out).write_text(
        json.dumps(
            {
                "steps": steps,
                "detections": {str(s): plain(m) for s, m in got3.items()},
                "detections_2d": {str(s): plain(m) for s, m in got2.items()},
                "rc": rc,
                "stdout": out,
                "stderr": err,
            }
        )
    )
    return 0


def soak(
    a: argparse.Namespace,
    node: "subprocess.Popen[str]",
    info_w: DataWriter,
    image_w: DataWriter,
    d3_r: DataReader,
    img: Image,
    k: List[float],
    w: int,
    h: int,
) -> int:
    """Publishes `img` at `a.rate` Hz for `a.soak` seconds (stamp seconds = the frame's
    index) and times each answer from its image's publication; per minute: frames published,
    answered, the answers' latency."""
    sent: Dict[int, float] = {}
    answered: Dict[int, float] = {}
    period = 1.0 / a.rate
    start = time.time()
    i = 0
    try:
        while time.time() - start < a.soak:
            due = start + i * period
            while time.time() < due:
                for m in d3_r.take(N=100):
                    if isinstance(m, Detection3DArray):
                        answered.setdefault(m.header.stamp.sec, time.time())
                time.sleep(0.002)
            info_w.write(camera_info(i, k, w, h))
            img.header = header(i)
            image_w.write(img)
            sent[i] = time.time()
            i += 1
        end = time.time() + 2.0
        while time.time() < end:
            for m in d3_r.take(N=100):
                if isinstance(m, Detection3DArray):
                    answered.setdefault(m.header.stamp.sec, time.time())
            time.sleep(0.01)
    finally:
        out, err = stop(node)
    minutes: List[Dict[str, Any]] = []
    for m in range(int(a.soak // 60) + 1):
        ids = [j for j, t in sent.items() if m * 60 <= t - start < (m + 1) * 60]
        if not ids:
            continue
        lat = sorted(answered[j] - sent[j] for j in ids if j in answered)
        minutes.append(
            {
                "minute": m,
                "published": len(ids),
                "answered": len(lat),
                "latency_median_ms": 1000 * lat[len(lat) // 2] if lat else None,
                "latency_p95_ms": 1000 * lat[int(0.95 * (len(lat) - 1))] if lat else None,
            }
        )
    Path(a.out).write_text(
        json.dumps(
            {
                "published": len(sent),
                "answered": len(answered),
                "minutes": minutes,
                "rc": node.returncode,
                "stdout": out,
                "stderr": err,
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
