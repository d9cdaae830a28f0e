"""ROS 2 bags (`avsim run --mcap`), read back with the `mcap` reader and its own CDR decoder
(mcap-ros2-support), independent of rosbags, which wrote them; and replayed (`avsim replay`)."""

from __future__ import annotations

import json
import math
import sys
from collections import defaultdict

import cv2
import mujoco
import numpy as np
import pytest

pytest.importorskip("rosbags")
mcap_reader = pytest.importorskip("mcap.reader")
ros2_decoder = pytest.importorskip("mcap_ros2.decoder")

from avsim import cli  # noqa: E402
from avsim.config import focal_length_px  # noqa: E402
from avsim.errors import ConfigError  # noqa: E402
from avsim.loop import ClosedLoop  # noqa: E402
from avsim.recording import ros_types  # noqa: E402
from avsim.recording.ros_bag import DETECTIONS_TOPIC, camera_info_topic, image_topic, marker_topic  # noqa: E402
from avsim.recording.ros_replay import replay  # noqa: E402
from avsim.runner import run_recorded  # noqa: E402
from helpers import make_config  # noqa: E402

CAMERAS = ("front", "side")
PER_STEP_TOPICS = ("/clock", "/odom", "/tf", DETECTIONS_TOPIC, "/vehicle/command", "/vehicle/command/raw",
                   *(image_topic(c) for c in CAMERAS), *(camera_info_topic(c) for c in CAMERAS),
                   *(marker_topic(c) for c in CAMERAS))
# The learned detector on both cameras (the side-camera policy renders both), on a short approach.
CONFIG = make_config(scenario={"speed_kmh": 40.0, "start_speed_kmh": 40.0, "start_dist_m": 40.0},
                     policy={"name": "side_camera"}, perception={"kind": "detector"})


def _read(path) -> dict[str, list[tuple[int, object]]]:
    """topic -> [(log time [ns], decoded message)], in file order."""
    messages = defaultdict(list)
    with open(path, "rb") as f:
        reader = mcap_reader.make_reader(f, decoder_factories=[ros2_decoder.DecoderFactory()])
        for _, channel, message, decoded in reader.iter_decoded_messages():
            messages[channel.topic].append((message.log_time, decoded))
    return messages


def _stamp_ns(message) -> int:
    """A message's header stamp [ns]."""
    return message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec


def _rotation(q) -> np.ndarray:
    """3x3 rotation of a geometry_msgs/Quaternion."""
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, np.array([q.w, q.x, q.y, q.z]))
    return m.reshape(3, 3)


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    """(bag path, the run's output, the messages by topic, each step's frames from a second, plain run)."""
    path = tmp_path_factory.mktemp("bag") / "run.mcap"
    output = run_recorded(CONFIG, mcap_path=path)
    # The same run again, unrecorded: its frames, rendered by its own renderer, at each sensing state.
    frames = []
    loop = ClosedLoop(CONFIG)
    try:
        def keep(loop_, record):
            frames.append({c: loop_.rig.render_rgb(loop_.data, c) for c in CAMERAS})

        first = {c: loop.rig.render_rgb(loop.data, c) for c in CAMERAS}
        loop.run(on_step=keep)
    finally:
        loop.close()
    return path, output, _read(path), [first, *frames[:-1]]


def test_every_message_deserialises_and_each_step_has_one_per_topic(bag):
    path, output, messages, _ = bag
    steps = len(output.records)
    assert steps > 20
    for topic in PER_STEP_TOPICS:
        assert len(messages[topic]) == steps, topic
        times = [t for t, _ in messages[topic]]
        assert times == sorted(set(times)), topic  # stamps increase
        assert times == [round(r.time_s * 1e9) for r in output.records]
        # Each message's own stamp is that simulated time too: /clock's value, every header's stamp.
        for log_ns, message in messages[topic]:
            if topic == "/clock":
                assert message.clock.sec * 1_000_000_000 + message.clock.nanosec == log_ns
            elif hasattr(message, "header"):
                assert _stamp_ns(message) == log_ns, topic
    assert len(messages["/tf_static"]) == 1 and len(messages["/avsim/run"]) == 1 and len(messages["/scene"]) == 1
    (_, scene), = messages["/scene"]
    assert {m.ns for m in scene.markers} == {"road", "stop_line", "stop_sign", "car"}
    assert [p.name for p in path.parent.iterdir()] == ["run.mcap"]  # no temporary left


def test_rosbags_reads_it_too(bag):
    from rosbags.highlevel import AnyReader

    path, output, _, _ = bag
    with AnyReader([path]) as reader:
        count = sum(1 for c, _, raw in reader.messages() if reader.deserialize(raw, c.msgtype) is not None)
    assert count == len(PER_STEP_TOPICS) * len(output.records) + 3


def test_images_decode_bit_for_bit_to_the_rendered_frames(bag):
    _, _, messages, frames = bag
    for camera in CAMERAS:
        for (_, image), frame in zip(messages[image_topic(camera)], frames, strict=True):
            assert image.format == "png" and image.header.frame_id == f"{camera}_camera_optical_frame"
            decoded = cv2.imdecode(np.frombuffer(bytes(image.data), np.uint8), cv2.IMREAD_COLOR)[..., ::-1]
            assert np.array_equal(decoded, frame[camera])


def test_camera_info_holds_the_intrinsics_the_pinhole_estimate_uses(bag):
    _, _, messages, _ = bag
    loop = ClosedLoop(CONFIG)
    try:
        for camera in CAMERAS:
            intrinsics = loop.rig.intrinsics(camera)
            _, info = messages[camera_info_topic(camera)][0]
            assert list(info.k) == list(intrinsics.matrix().ravel())
            assert (info.width, info.height) == (intrinsics.width_px, intrinsics.height_px)
            assert info.k[0] == intrinsics.f_px == focal_length_px(intrinsics.height_px, intrinsics.fovy_deg)
    finally:
        loop.close()


def test_detections_are_the_runs_records(bag):
    _, output, messages, _ = bag
    assert any(r.detections for r in output.records)
    for record, (_, array) in zip(output.records, messages[DETECTIONS_TOPIC], strict=True):
        got = []
        for d in array.detections:
            (hypothesis,) = d.results
            cx, cy, w, h = d.bbox.center.position.x, d.bbox.center.position.y, d.bbox.size_x, d.bbox.size_y
            got.append((d.header.frame_id, hypothesis.hypothesis.class_id, hypothesis.hypothesis.score, (cx, cy, w, h)))
        want = [(f"{d.camera}_camera_optical_frame", d.class_name, d.confidence,
                 ((d.box_xyxy_px[0] + d.box_xyxy_px[2]) / 2, (d.box_xyxy_px[1] + d.box_xyxy_px[3]) / 2,
                  d.box_xyxy_px[2] - d.box_xyxy_px[0], d.box_xyxy_px[3] - d.box_xyxy_px[1])) for d in record.detections]
        assert got == want
    # The image markers hold the same boxes: four edges (eight points) each, in the camera's pixels.
    for record, (_, marker) in zip(output.records, messages[marker_topic("front")], strict=True):
        boxes = [d.box_xyxy_px for d in record.detections if d.camera == "front"]
        corners = [(p.x, p.y) for p in marker.points[::2]]
        assert corners == [c for x0, y0, x1, y1 in boxes for c in ((x0, y0), (x1, y0), (x1, y1), (x0, y1))]


def test_odom_is_the_trace_and_tf_carries_the_same_pose(bag):
    _, output, messages, _ = bag
    for record, (_, odom), (_, tf) in zip(output.records, messages["/odom"], messages["/tf"], strict=True):
        p, q = odom.pose.pose.position, odom.pose.pose.orientation
        assert (p.x, p.y) == (record.x_m, record.y_m)
        assert math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y ** 2 + q.z ** 2)) == pytest.approx(record.yaw_rad, abs=1e-12)
        # The twist is in base_link; back in the world, along the heading, it is the record's speed.
        v = odom.twist.twist.linear
        v_world = _rotation(q) @ np.array([v.x, v.y, v.z])
        assert v_world[0] * math.cos(record.yaw_rad) + v_world[1] * math.sin(record.yaw_rad) == pytest.approx(record.speed_mps, abs=1e-9)
        assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_link")
        (transform,) = tf.transforms
        assert transform.transform.translation.x == p.x and transform.child_frame_id == "base_link"
    (static,) = [m for _, m in messages["/tf_static"]]
    pairs = {(t.header.frame_id, t.child_frame_id) for t in static.transforms}
    assert {("map", "odom"), ("base_link", "front_camera_link"), ("front_camera_link", "front_camera_optical_frame")} <= pairs


def test_optical_frame_looks_forward_from_the_cameras_mount(bag):
    """base_link -> front optical frame: its z axis (the optical axis) is the car's x axis (REP 103)."""
    _, _, messages, _ = bag
    (static,) = [m for _, m in messages["/tf_static"]]
    by_child = {t.child_frame_id: t.transform.rotation for t in static.transforms}

    r = _rotation(by_child["front_camera_link"]) @ _rotation(by_child["front_camera_optical_frame"])
    np.testing.assert_allclose(r[:, 2], [1, 0, 0], atol=1e-9)  # optical z: forward
    np.testing.assert_allclose(r[:, 1], [0, 0, -1], atol=1e-9)  # optical y: down


def test_commands_and_the_run_record(bag):
    _, output, messages, _ = bag
    for record, (_, raw), (_, ackermann) in zip(output.records, messages["/vehicle/command/raw"],
                                                messages["/vehicle/command"], strict=True):
        assert list(raw.data) == [record.throttle, record.brake, record.steer_rad]
        assert ackermann.drive.steering_angle == pytest.approx(record.steer_rad, abs=1e-6)  # float32
    (_, run), = messages["/avsim/run"]
    assert json.loads(run.data) == json.loads(json.dumps({"config": CONFIG.to_dict(), "result": output.result.to_json_dict()}))


def test_replaying_the_bag_with_its_perception_gives_its_detections_exactly(bag):
    path, output, _, _ = bag
    lines = list(replay(path))
    assert len(lines) == len(CAMERAS) * len(output.records)
    by_key = {(line["camera"], line["stamp_ns"]): line["detections"] for line in lines}
    for record in output.records:
        for camera in CAMERAS:
            want = [{"class": d.class_name, "confidence": d.confidence, "box_xyxy_px": list(d.box_xyxy_px)}
                    for d in record.detections if d.camera == camera]
            assert by_key[camera, round(record.time_s * 1e9)] == want


def test_replay_cli_writes_json_lines_and_refuses_a_bad_bag_in_one_line(bag, tmp_path, capsys):
    path, output, _, _ = bag
    out = tmp_path / "dets.jsonl"
    assert cli.main(["replay", str(path), "--perception", "detector", "--out", str(out)]) == 0
    assert len(out.read_text().splitlines()) == len(CAMERAS) * len(output.records)
    capsys.readouterr()
    (tmp_path / "junk.mcap").write_bytes(b"not a bag")
    for bad in (tmp_path / "missing.mcap", tmp_path / "junk.mcap"):
        target = tmp_path / f"{bad.stem}.jsonl"
        assert cli.main(["replay", str(bad), "--out", str(target)]) == 2
        err = capsys.readouterr().err
        assert len(err.splitlines()) == 1 and str(bad) in err, err
        assert not target.exists()


def test_a_bag_without_images_is_one_line_and_exit_2(tmp_path, capsys):
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = ros_types.typestore()
    with Writer(tmp_path / "clock_only", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection("/clock", "rosgraph_msgs/msg/Clock", typestore=store)
        writer.write(connection, 0, store.serialize_cdr(store.types["rosgraph_msgs/msg/Clock"](clock=ros_types.stamp(0.0)),
                                                        "rosgraph_msgs/msg/Clock"))
    out = tmp_path / "dets.jsonl"
    assert cli.main(["replay", str(tmp_path / "clock_only"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "no sensor_msgs/msg/CompressedImage topic" in err and "/clock" in err
    assert not out.exists()


def test_replay_prints_a_foreign_bags_images_one_json_line_each(bag, tmp_path, capsys):
    """Someone else's bag: no /avsim/run (avsim's default perception), a camera avsim does not know
    (searched whole), and no --out: one JSON line per image on stdout."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    _, _, _, frames = bag
    store, topic = ros_types.typestore(), "/usb_cam/image_raw/compressed"
    image_type = "sensor_msgs/msg/CompressedImage"
    png = np.frombuffer(cv2.imencode(".png", frames[-1]["front"][..., ::-1])[1].tobytes(), np.uint8)
    with Writer(tmp_path / "foreign", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection(topic, image_type, typestore=store)
        message = store.types[image_type](header=ros_types.header(1.5, "usb_cam"), format="png", data=png)
        writer.write(connection, 1_500_000_000, store.serialize_cdr(message, image_type))
    capsys.readouterr()
    assert cli.main(["replay", str(tmp_path / "foreign"), "--perception", "detector"]) == 0
    (line,) = capsys.readouterr().out.splitlines()
    record = json.loads(line)
    assert (record["topic"], record["camera"], record["stamp_ns"], record["width"]) == (topic, topic, 1_500_000_000, 640)
    assert [d["class"] for d in record["detections"]] == ["stop_sign"]


def test_run_mcap_refuses_a_bad_path_before_running(tmp_path, capsys):
    for bad in (tmp_path / "run.bag", tmp_path / "a_file" / "run.mcap"):
        (tmp_path / "a_file").write_text("")
        assert cli.main(["run", "--perception", "oracle", "--mcap", str(bad)]) == 2
        err = capsys.readouterr().err
        assert len(err.splitlines()) == 1 and "--mcap" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]


def test_an_error_mid_run_leaves_no_bag(tmp_path, monkeypatch):
    from avsim.recording.ros_bag import BagRecorder

    loop = ClosedLoop(make_config(scenario={"start_dist_m": 40.0}))
    path = tmp_path / "run.mcap"
    try:
        with pytest.raises(RuntimeError, match="boom"):
            with BagRecorder(loop, path) as recorder:
                recorder.on_step(loop, loop.step())
                raise RuntimeError("boom")
    finally:
        loop.close()
    assert list(tmp_path.iterdir()) == []


def test_the_bags_metadata_names_its_own_file(bag):
    """The rosbag2 metadata record inside names the bag's final file, not the hidden folder it was
    written in (whose name holds the process id), so the same run gives the same bytes."""
    path, _, _, _ = bag
    with open(path, "rb") as f:
        (metadata,) = mcap_reader.make_reader(f).iter_metadata()
    assert f"path: {path.name}\n" in metadata.metadata["serialized_metadata"]


def test_jpeg_images_are_smaller_and_decode(tmp_path):
    config = make_config(scenario={"start_dist_m": 30.0, "speed_kmh": 40.0, "start_speed_kmh": 40.0})
    sizes = {}
    for fmt in ("png", "jpeg"):
        run_recorded(config, mcap_path=tmp_path / f"{fmt}.mcap", mcap_images=fmt)
        sizes[fmt] = (tmp_path / f"{fmt}.mcap").stat().st_size
        (_, image), *_ = _read(tmp_path / f"{fmt}.mcap")[image_topic("front")]
        assert image.format == fmt
        assert cv2.imdecode(np.frombuffer(bytes(image.data), np.uint8), cv2.IMREAD_COLOR).shape == (480, 640, 3)
    assert sizes["jpeg"] < sizes["png"]


def test_without_the_ros_extra_the_error_names_it_before_any_run(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "rosbags.rosbag2", None)  # import fails as if not installed
    with pytest.raises(ConfigError, match=r"avsim\[ros\]"):
        ros_types.require_rosbags()
    import avsim.runner

    monkeypatch.setattr(avsim.runner, "ClosedLoop", None)  # a run would fail differently
    for argv in (["run", "--mcap", str(tmp_path / "r.mcap")], ["sweep", "experiments/sweeps/sweep_smoke.toml", "--out", str(tmp_path / "o"), "--mcap", "all"]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert len(err.splitlines()) == 1 and "avsim[ros]" in err, err
    assert list(tmp_path.iterdir()) == []


def test_the_foxglove_layout_names_only_topics_and_fields_the_bag_has(bag):
    from pathlib import Path

    _, _, messages, _ = bag
    layout = json.loads((Path(__file__).resolve().parents[2] / "docs" / "foxglove_layout.json").read_text())
    panels = layout["configById"]
    topics = set()
    for name, config in panels.items():
        mode = config.get("imageMode", {})
        topics |= {mode.get("imageTopic"), mode.get("calibrationTopic"), *mode.get("annotations", {})} - {None}
        topics |= set(config.get("topics", {}))
        for path in config.get("paths", []):
            topic, _, fields = path["value"].partition(".")
            topics.add(topic)
            _, message = messages[topic][0]
            value = message
            for field in fields.split("."):  # e.g. data[1]
                key, _, index = field.partition("[")
                value = getattr(value, key)
                value = value[int(index.rstrip("]"))] if index else value
            assert isinstance(value, float), path["value"]
            # A header stamp on a message without a header plots nothing (Foxglove drew an empty
            # throttle/brake plot so); the receive time is the bag's log time, the sensing time.
            if path.get("timestampMethod") == "headerStamp":
                assert hasattr(message, "header"), f"{path['value']}: {topic} has no header; use receiveTime"
            else:
                assert path.get("timestampMethod") == "receiveTime", path
                assert [t for t, _ in messages[topic]] == [_stamp_ns(m) for _, m in messages["/odom"]], topic
    assert topics <= set(messages), topics - set(messages)

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(node["second"])

    assert sorted(leaves(layout["layout"])) == sorted(panels)
