"""`avsim replay BAG --perception KIND`: a pixel perception run over a ROS bag's camera images.

    for line in replay("run.mcap", perception_overrides={"kind": "coco"}):
        print(json.dumps(line))

Any bag rosbags reads (an `.mcap` file, a ROS 2 bag folder, a ROS 1 `.bag`) with one or more
`sensor_msgs/msg/CompressedImage` topics: avsim's own (`avsim run --mcap`) or someone else's.
Each image gives one JSON-ready record, in the bag's order:
    {"topic", "camera", "stamp_ns", "width", "height", "perception",
     "detections": [{"class", "confidence", "box_xyxy_px", ["source"]}]}
with boxes in the image's pixels (avsim's convention: pixel i covers [i, i + 1)) and values
unrounded, so they compare exactly with the bag's `/perception/detections`.

The perception runs as it does in the closed loop: on the camera's region of interest, with
boxes shorter than `perception.min_box_height_px` dropped. The settings start from the bag's
own run (its `/avsim/run` config) when it has one, else from avsim's defaults; `--perception`
and `--set perception.KEY=VALUE` apply on top. A topic `/camera/<name>/image/compressed` is
camera <name>; the front and side cameras get their regions of interest, any other camera is
searched whole. Replaying an avsim bag with its own perception therefore gives its detections
bit for bit, except under `perception.sensor_noise_std` > 0: the bag holds the clean render,
not the noisy frame the network saw.
"""

from __future__ import annotations

import contextlib
import json
import os
import struct
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from avsim.config import PerceptionConfig, SimConfig, with_overrides
from avsim.config_owners import REPLAY_UNREAD, check_read_on_images
from avsim.errors import ConfigError
from avsim.perception.base import Detection
from avsim.recording import ros_types

IMAGE_TYPE = "sensor_msgs/msg/CompressedImage"
RUN_TOPIC = "/avsim/run"


class BagError(ConfigError):
    """A bag that does not exist, cannot be read, or has no camera images."""


def replay(bag: str | os.PathLike, perception_overrides: Mapping[str, Any] | None = None) -> Iterator[dict[str, Any]]:
    """One record per image of `bag` (see the module docstring); checks the bag and builds the
    perception before the first image."""
    ros_types.require_rosbags()
    from rosbags.highlevel import AnyReader, AnyReaderError

    path = Path(bag)
    if not path.exists():
        raise BagError(f"bag {path} does not exist; pass an .mcap file or a ROS bag folder")
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        raise BagError(f"{path} is a folder without a metadata.yaml, so no ROS bag; pass an .mcap file or a ROS bag folder")
    if path.is_file() and path.suffix.lower() != ".mcap":  # rosbags picks a lone file's reader by its suffix
        raise BagError(f"bag {path} does not end in .mcap, the one bag file avsim reads alone; rename it to "
                       f"{path.with_suffix('.mcap').name}, or pass its ROS bag folder")
    # rosbags' readers raise more than AnyReaderError on a cut or foreign file (its MCAP reader
    # reads past the end of a truncated one): only the bag's own reading is guarded by these.
    unreadable = (AnyReaderError, EOFError, IndexError, KeyError, TypeError, ValueError, struct.error)
    with _reading(path, unreadable):  # a file of another kind (a .png) is refused by the constructor
        reader = AnyReader([path], default_typestore=ros_types.typestore())
        reader.open()
    try:
        images = [c for c in reader.connections if c.msgtype == IMAGE_TYPE]
        if not images:
            topics = ", ".join(sorted({c.topic for c in reader.connections})) or "none"
            raise BagError(f"bag {path} has no {IMAGE_TYPE} topic to replay (its topics: {topics})")
        runs = [c for c in reader.connections if c.topic == RUN_TOPIC]
        config = _run_config(_messages(reader, runs, path, unreadable), perception_overrides or {})
        # A key the user set that this perception does not read on a bag's images is refused
        # before the first image (the bag's run decides the kind when the user names none).
        check_read_on_images(config.perception, perception_overrides or {}, "avsim replay", REPLAY_UNREAD)
        from avsim.perception.factory import build_frame_detector
        from avsim.sensors.regions import regions_px

        detector = build_frame_detector(config.perception)
        regions = regions_px(config.perception, config.camera)
        for topic, message in _messages(reader, images, path, unreadable):
            yield _record(topic, message, config.perception, regions, detector)
    finally:
        reader.close()


@contextlib.contextmanager
def _reading(path: Path, unreadable: tuple[type[BaseException], ...]) -> Iterator[None]:
    """Turn what a bag reader raises on a truncated or foreign file into one BagError line."""
    try:
        yield
    except unreadable as exc:
        raise BagError(f"cannot read bag {path}: {type(exc).__name__}: {exc}; it is cut short or no bag: pass an "
                       ".mcap file or a ROS bag folder") from None


def _messages(reader: Any, connections: list[Any], path: Path, unreadable: tuple[type[BaseException], ...]
              ) -> Iterator[tuple[str, Any]]:
    """(topic, deserialized message) of `connections`, in the bag's order, each read inside `_reading`;
    none when `connections` is empty."""
    if not connections:
        return  # rosbags reads every message of the bag when given no connections (someone else's bag has no run)
    messages = reader.messages(connections=connections)
    while True:
        with _reading(path, unreadable):
            try:
                connection, _, raw = next(messages)
            except StopIteration:
                return
            message = reader.deserialize(raw, connection.msgtype)
        yield connection.topic, message


def camera_of(topic: str) -> str:
    """The camera a topic's images come from: <name> for /camera/<name>/..., else the topic."""
    parts = topic.strip("/").split("/")
    return parts[1] if len(parts) > 2 and parts[0] == "camera" else topic


def detection_json(detection: Detection) -> dict[str, Any]:
    """A detection as `avsim detect` and `avsim replay` print it: class, confidence, box_xyxy_px
    [image px] and, from an ensemble, source.
    """
    return {"class": detection.class_name, "confidence": detection.confidence, "box_xyxy_px": list(detection.box_xyxy_px),
            **({"source": detection.source} if detection.source else {})}


def _run_config(run_messages: Iterator[tuple[str, Any]], overrides: Mapping[str, Any]) -> SimConfig:
    """The bag's own run's camera and perception settings (avsim's defaults without one: no
    `RUN_TOPIC` message), `overrides` on the perception's."""
    base = SimConfig()
    for _, message in run_messages:
        recorded = json.loads(message.data)["config"]
        base = with_overrides(base, {"camera": recorded["camera"], "perception": recorded["perception"]})
    return with_overrides(base, {"perception": dict(overrides)})


def _record(topic: str, message: Any, config: PerceptionConfig, regions: Mapping[str, tuple[int, int, int, int]],
            detector: Any) -> dict[str, Any]:
    bgr = cv2.imdecode(np.asarray(message.data, dtype=np.uint8), cv2.IMREAD_COLOR)
    if bgr is None:
        raise BagError(f"an image on {topic} (format '{message.format}') cannot be decoded")
    rgb = np.ascontiguousarray(bgr[..., ::-1])
    camera = camera_of(topic)
    detections = detector.detect(rgb, camera, region_px=regions.get(camera))
    kept = [d for d in detections if d.height_px >= config.min_box_height_px]
    stamp = message.header.stamp
    return {"topic": topic, "camera": camera, "stamp_ns": stamp.sec * 1_000_000_000 + stamp.nanosec,
            "width": int(rgb.shape[1]), "height": int(rgb.shape[0]), "perception": config.kind,
            "detections": [detection_json(d) for d in kept]}
