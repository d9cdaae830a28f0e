"""The rerun recording of a run, read back with rerun's own reader (rerun.chunk.RrdReader)."""

from __future__ import annotations

import cv2
import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader

from avsim import cli
from avsim.loop import ClosedLoop
from avsim.recording import paths
from avsim.recording.blueprint import SERIES_PANELS
from avsim.recording.rerun_log import RunRecorder
from helpers import make_config

# A rerun API misuse is only a warning by default; here it fails the test.
pytestmark = pytest.mark.filterwarnings("error::rerun.error_utils.RerunWarning")

STEPS = 20
# Close enough to the sign that the oracle sees it from the first step (box > 16 px).
SHORT_SCENARIO = {"start_dist_m": 35.0, "start_speed_kmh": 40.0}


def _temporal(path, entity: str, column: str) -> tuple[list[int], list[int], list]:
    """(frame, sim_time [ns], values) of an entity's temporal rows, sorted by frame."""
    rows = []
    for chunk in RrdReader(path).stream().to_chunks():
        if chunk.entity_path != "/" + entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        if column not in batch.schema.names:
            continue
        frames = batch.column("frame").to_pylist()
        times_ns = batch.column("sim_time").cast(pa.int64()).to_pylist()
        rows.extend(zip(frames, times_ns, batch.column(column).to_pylist()))
    rows.sort(key=lambda row: row[0])
    return [r[0] for r in rows], [r[1] for r in rows], [r[2] for r in rows]


def _entities(path) -> set[str]:
    return {chunk.entity_path.lstrip("/") for chunk in RrdReader(path).stream().to_chunks()}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A 20-step oracle run recorded to an .rrd; returns (path, the loop's StepRecords)."""
    out_dir = tmp_path_factory.mktemp("rrd")
    path = out_dir / "run.rrd"
    loop = ClosedLoop(make_config(scenario=SHORT_SCENARIO))
    try:
        with RunRecorder(loop, path) as recorder:
            for _ in range(STEPS):
                recorder.on_step(loop, loop.step())
    finally:
        loop.close()
    return path, list(loop.records)


def test_writes_one_recording_with_a_blueprint_and_no_temp_file(recorded):
    path, _ = recorded
    reader = RrdReader(path)
    assert len(reader.recordings()) == 1
    assert len(reader.blueprints()) == 1
    views = {c.entity_path for c in reader.stream(store=reader.blueprints()[0]).to_chunks() if c.entity_path.count("/") == 2
             and c.entity_path.startswith("/view/")}
    assert len(views) == 1 + 1 + len(SERIES_PANELS)  # front camera, 3D world, time series
    assert [p.name for p in path.parent.iterdir()] == ["run.rrd"]


def test_entities_exist(recorded):
    path, _ = recorded
    expected = {
        paths.WORLD, paths.CAR, paths.CAR_BODY, paths.TRAJECTORY, paths.STOP_SIGN, paths.STOP_LINE,
        paths.camera("front"), paths.camera_image("front"), paths.camera_detections("front"),
        *(paths.metric(field) for field in paths.METRIC_FIELDS if field not in ("required_decel_mps2", "max_brake_slip")),
    }
    assert expected <= _entities(path)
    assert paths.camera_image("side") not in _entities(path)  # the baseline policy uses no side camera


def test_speed_series_is_one_value_per_step_equal_to_the_records(recorded):
    path, records = recorded
    frames, times_ns, values = _temporal(path, paths.metric("speed_mps"), "Scalars:scalars")
    assert frames == list(range(STEPS))
    assert [v[0] for v in values] == [r.speed_mps for r in records]
    assert times_ns == [round(r.time_s * 1e9) for r in records]


def test_optional_series_skip_steps_without_a_value(recorded):
    path, records = recorded
    frames, _, values = _temporal(path, paths.metric("est_stop_line_dist_m"), "Scalars:scalars")
    expected = [(i, r.est_stop_line_dist_m) for i, r in enumerate(records) if r.est_stop_line_dist_m is not None]
    assert expected, "the scenario should give the policy a distance estimate"
    assert list(zip(frames, (v[0] for v in values))) == expected


def test_boxes_are_the_records_detections(recorded):
    path, records = recorded
    frames, _, labels = _temporal(path, paths.camera_detections("front"), "Boxes2D:labels")
    _, _, centres = _temporal(path, paths.camera_detections("front"), "Boxes2D:centers")
    # One batch per step plus an empty one for the final state, which no perception saw.
    assert frames == list(range(STEPS + 1))
    assert labels[-1] == []
    assert any(r.detections for r in records)
    for record, step_labels, step_centres in zip(records, labels, centres):
        dets = [d for d in record.detections if d.camera == "front"]
        assert step_labels == [f"{d.class_name} {d.confidence:.2f}" for d in dets]
        expected_centres = [((d.box_xyxy_px[0] + d.box_xyxy_px[2]) / 2, (d.box_xyxy_px[1] + d.box_xyxy_px[3]) / 2) for d in dets]
        np.testing.assert_allclose(np.reshape(step_centres, (-1, 2)), np.reshape(expected_centres, (-1, 2)), atol=1e-3)


def test_images_and_car_pose_are_from_each_records_sensing_time(recorded):
    path, records = recorded
    # The car pose is captured together with the images, so matching it to the record
    # (state at sensing time) shows the images are of that state too. Like the renders,
    # it comes from MuJoCo's derived kinematics, which after mj_step lag the record's
    # qpos by one physics step (not at step 0: placing the car refreshes them);
    # consecutive records are 25 physics steps apart.
    physics_dt_s = make_config().loop.physics_dt_s
    frames, _, translations = _temporal(path, paths.CAR, "Transform3D:translation")
    assert frames == list(range(STEPS + 1))  # plus the final state
    for i, (record, translation) in enumerate(zip(records, translations)):
        x_m, y_m = translation[0][:2]
        lag_m = record.speed_mps * physics_dt_s if i > 0 else 0.0
        assert record.x_m - x_m == pytest.approx(lag_m, abs=2e-3)
        assert y_m == pytest.approx(record.y_m, abs=2e-3)

    frames, _, blobs = _temporal(path, paths.camera_image("front"), "EncodedImage:blob")
    assert frames == list(range(STEPS + 1))
    image = cv2.imdecode(np.array(blobs[0][0], dtype=np.uint8), cv2.IMREAD_COLOR)
    assert image.shape == (480, 640, 3)


def test_front_camera_pose_looks_down_the_road(recorded):
    path, _ = recorded
    _, _, matrices = _temporal(path, paths.camera("front"), "Transform3D:mat3x3")
    # Stored column-major: the third column is the camera's z axis (backwards) in the world.
    z_axis = np.asarray(matrices[0][0])[6:9]
    np.testing.assert_allclose(-z_axis, [1.0, 0.0, 0.0], atol=0.02)


def test_recording_does_not_change_the_run(recorded):
    _, records = recorded
    loop = ClosedLoop(make_config(scenario=SHORT_SCENARIO))
    try:
        unrecorded = [loop.step() for _ in range(STEPS)]
    finally:
        loop.close()
    assert unrecorded == records


def test_on_step_after_a_missed_step_is_an_error(tmp_path):
    loop = ClosedLoop(make_config(scenario=SHORT_SCENARIO))
    try:
        with pytest.raises(RuntimeError, match="once after every loop step"), RunRecorder(loop, tmp_path / "run.rrd") as recorder:
            loop.step()  # not passed to the recorder
            recorder.on_step(loop, loop.step())
    finally:
        loop.close()
    assert list(tmp_path.iterdir()) == []  # the recorder deleted its partial file


def test_an_error_during_the_run_leaves_no_file(tmp_path):
    loop = ClosedLoop(make_config(scenario=SHORT_SCENARIO))
    try:
        with pytest.raises(KeyboardInterrupt), RunRecorder(loop, tmp_path / "run.rrd") as recorder:
            recorder.on_step(loop, loop.step())
            raise KeyboardInterrupt
    finally:
        loop.close()
    assert list(tmp_path.iterdir()) == []


def test_cli_run_writes_a_readable_rrd(tmp_path, capsys):
    rrd, result_json = tmp_path / "out.rrd", tmp_path / "out.json"
    code = cli.main(["run", "--perception", "oracle", "--speed-kmh", "20", "--set", "scenario.start_speed_kmh=20",
                     "--set", "scenario.start_dist_m=30", "--rrd", str(rrd), "--json", str(result_json)])
    assert code == 0
    assert capsys.readouterr().out.startswith("avsim run:")
    assert result_json.exists()
    frames, _, _ = _temporal(rrd, paths.metric("speed_mps"), "Scalars:scalars")
    image_frames, _, _ = _temporal(rrd, paths.camera_image("front"), "EncodedImage:blob")
    assert frames == list(range(len(frames))) and len(frames) > 0
    assert image_frames == list(range(len(frames) + 1))


def test_side_camera_is_recorded_when_the_policy_uses_it(tmp_path):
    loop = ClosedLoop(make_config(scenario=SHORT_SCENARIO, policy={"name": "side_camera"}))
    try:
        with RunRecorder(loop, tmp_path / "run.rrd") as recorder:
            recorder.on_step(loop, loop.step())
    finally:
        loop.close()
    assert recorder.cameras == ("front", "side")
    frames, _, _ = _temporal(tmp_path / "run.rrd", paths.camera_image("side"), "EncodedImage:blob")
    assert frames == [0, 1]
    assert {paths.camera("side"), paths.camera_detections("side")} <= _entities(tmp_path / "run.rrd")
