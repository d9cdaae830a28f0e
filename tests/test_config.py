"""Typed, frozen configuration: overrides, type checks and range checks."""

import dataclasses
import math

import pytest

from avsim.config import (
    CameraConfig,
    LoopConfig,
    PerceptionConfig,
    PolicyConfig,
    ScenarioConfig,
    SimConfig,
    VehicleConfig,
    with_overrides,
)
from avsim.errors import ConfigError


def _one_line(excinfo) -> str:
    msg = str(excinfo.value)
    assert "\n" not in msg
    return msg


# ---- with_overrides ----------------------------------------------------------------

def test_with_overrides_applies_nested_values():
    cfg = with_overrides(SimConfig(), {"scenario": {"speed_kmh": 60.0, "town": "town03"}, "policy": {"baseline_brake": 0.9}})
    assert cfg.scenario.speed_kmh == 60.0
    assert cfg.scenario.town == "town03"
    assert cfg.policy.baseline_brake == 0.9
    # untouched fields keep their defaults
    assert cfg.scenario.placement == ScenarioConfig().placement
    assert cfg.loop == LoopConfig()


def test_with_overrides_returns_copy_and_leaves_original_unchanged():
    base = SimConfig()
    with_overrides(base, {"scenario": {"speed_kmh": 60.0}})
    assert base.scenario.speed_kmh == 85.0


def test_with_overrides_unknown_key_names_dotted_key():
    with pytest.raises(ConfigError) as excinfo:
        with_overrides(SimConfig(), {"scenario": {"sped": 50.0}})
    assert "scenario.sped" in _one_line(excinfo)


def test_with_overrides_unknown_top_level_section():
    with pytest.raises(ConfigError) as excinfo:
        with_overrides(SimConfig(), {"scenaro": {"speed_kmh": 50.0}})
    assert "scenaro" in _one_line(excinfo)


def test_with_overrides_section_must_be_a_mapping():
    with pytest.raises(ConfigError) as excinfo:
        with_overrides(SimConfig(), {"scenario": 5})
    assert "scenario" in _one_line(excinfo)


@pytest.mark.parametrize(
    "overrides, dotted",
    [
        ({"scenario": {"speed_kmh": "fast"}}, "scenario.speed_kmh"),  # string for a float
        ({"scenario": {"seed": True}}, "scenario.seed"),  # bool for an int
        ({"scenario": {"seed": 1.5}}, "scenario.seed"),  # float for an int
        ({"scenario": {"seed": 1.0}}, "scenario.seed"),  # integral float is still a float
        ({"scenario": {"town": 3}}, "scenario.town"),  # int for a str
        ({"policy": {"baseline_brake": True}}, "policy.baseline_brake"),  # bool for a float
    ],
)
def test_with_overrides_rejects_wrong_types(overrides, dotted):
    with pytest.raises(ConfigError) as excinfo:
        with_overrides(SimConfig(), overrides)
    assert dotted in _one_line(excinfo)


def test_with_overrides_accepts_int_for_float_and_stores_float():
    cfg = with_overrides(SimConfig(), {"scenario": {"speed_kmh": 60}})
    assert cfg.scenario.speed_kmh == 60.0
    assert type(cfg.scenario.speed_kmh) is float


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_with_overrides_rejects_non_finite_floats(bad):
    with pytest.raises(ConfigError) as excinfo:
        with_overrides(SimConfig(), {"policy": {"a_max_mps2": bad}})
    assert "policy.a_max_mps2" in _one_line(excinfo)


# ---- range checks --------------------------------------------------------------------

@pytest.mark.parametrize(
    "factory",
    [
        lambda: ScenarioConfig(speed_kmh=-5.0),
        lambda: ScenarioConfig(speed_kmh=0.0),
        lambda: ScenarioConfig(speed_kmh=250.0),
        lambda: ScenarioConfig(start_dist_m=10.0),
        lambda: ScenarioConfig(seed=-1),
        lambda: ScenarioConfig(sun_elevation_deg=0.0),
        lambda: VehicleConfig(max_drive_torque_nm=0.0),
        lambda: VehicleConfig(drag_area_m2=-0.1),
        lambda: ScenarioConfig(road_friction=3.0),
        lambda: ScenarioConfig(road_friction=0.0),
        lambda: VehicleConfig(brake_balance_front=1.2),
        lambda: VehicleConfig(brake_rise_time_s=0.0),
        lambda: VehicleConfig(abs_target_slip=0.9),
        lambda: VehicleConfig(suspension_frequency_hz=0.1),
        lambda: VehicleConfig(suspension_damping_ratio=0.0),
        lambda: VehicleConfig(tyre_sliding_ratio=1.5),
        lambda: CameraConfig(width_px=32),
        lambda: CameraConfig(height_px=5000),
        lambda: CameraConfig(fovy_deg=0.5),
        lambda: CameraConfig(offsamples=3),
        lambda: CameraConfig(seg_supersample=5),
        lambda: CameraConfig(texture_anisotropy=3),
        lambda: LoopConfig(physics_dt_s=0.003),  # 0.05 / 0.003 is not whole
        lambda: LoopConfig(control_dt_s=0.051),
        lambda: LoopConfig(physics_dt_s=0.0),
        lambda: LoopConfig(control_dt_s=0.2),
        lambda: LoopConfig(physics_dt_s=0.01, control_dt_s=0.005),  # control faster than physics
        lambda: LoopConfig(max_time_s=0.0),
        lambda: PerceptionConfig(min_box_height_px=0.5),
        lambda: PolicyConfig(brake_multiplier=0.5),
        lambda: PolicyConfig(brake_multiplier=1.1),
        lambda: PolicyConfig(conf_threshold=0.0),
        lambda: PolicyConfig(conf_threshold=1.0),
        lambda: PolicyConfig(baseline_brake=0.0),
        lambda: PolicyConfig(a_max_mps2=0.0),
        lambda: PolicyConfig(autopilot_decel_fraction=1.5),  # more than the car's full brake
        lambda: PolicyConfig(stop_margin_m=-1.0),
    ],
)
def test_range_checks_raise_one_line_config_error(factory):
    with pytest.raises(ConfigError) as excinfo:
        factory()
    _one_line(excinfo)


def test_range_check_via_overrides_names_the_field():
    with pytest.raises(ConfigError) as excinfo:
        with_overrides(SimConfig(), {"loop": {"physics_dt_s": 0.003}})
    msg = _one_line(excinfo)
    assert "loop.control_dt_s" in msg and "loop.physics_dt_s" in msg


def test_range_checks_accept_boundaries():
    assert PolicyConfig(brake_multiplier=0.6).brake_multiplier == 0.6
    assert PolicyConfig(brake_multiplier=1.0).brake_multiplier == 1.0
    assert CameraConfig(width_px=64, height_px=4096).height_px == 4096


# ---- derived values and serialisation ------------------------------------------------

def test_loop_substeps_default_is_25():
    assert LoopConfig().substeps == 25


def test_loop_substeps_other_ratio():
    assert LoopConfig(physics_dt_s=0.005, control_dt_s=0.1).substeps == 20


def test_camera_focal_length_default():
    assert abs(CameraConfig().f_px - (480 / 2) / math.tan(math.radians(15))) < 1e-9


def test_camera_focal_length_follows_height_and_fovy():
    cam = CameraConfig(height_px=720, fovy_deg=60.0)
    assert abs(cam.f_px - 360 / math.tan(math.radians(30))) < 1e-9


def test_the_study_preset_is_the_camera_of_every_existing_result():
    assert CameraConfig() == CameraConfig(preset="study", width_px=640, height_px=480, fovy_deg=30.0, side_fovy_deg=30.0)


def test_the_automotive_preset_is_1920x1080_at_55_deg_horizontal():
    cam = CameraConfig(preset="automotive_1080p")
    assert (cam.width_px, cam.height_px) == (1920, 1080)
    assert cam.fovy_deg == cam.side_fovy_deg
    assert cam.f_px == pytest.approx(960 / math.tan(math.radians(27.5)), rel=1e-12)
    assert cam.f_px == pytest.approx(540 / math.tan(math.radians(cam.fovy_deg / 2)), rel=1e-12)


def test_a_preset_set_by_override_fills_the_keys_not_set_beside_it():
    automotive = with_overrides(SimConfig(), {"camera": {"preset": "automotive_1080p", "fovy_deg": 20.0}}).camera
    assert (automotive.width_px, automotive.height_px, automotive.fovy_deg) == (1920, 1080, 20.0)
    assert automotive.side_fovy_deg == CameraConfig(preset="automotive_1080p").side_fovy_deg
    # Switching back takes the study's values, not the automotive ones left behind.
    back = with_overrides(SimConfig(camera=automotive), {"camera": {"preset": "study"}}).camera
    assert back == CameraConfig()
    # A key without a preset keeps the default preset and overrides it.
    assert with_overrides(SimConfig(), {"camera": {"width_px": 800}}).camera.height_px == 480


def test_an_unknown_camera_preset_is_a_clear_error():
    with pytest.raises(ConfigError, match="camera.preset must be one of study, automotive_1080p, got 'hd'"):
        with_overrides(SimConfig(), {"camera": {"preset": "hd"}})


def test_to_dict_round_trips_through_with_overrides():
    cfg = with_overrides(SimConfig(), {"scenario": {"town": "town10", "seed": 7}, "policy": {"name": "adjusted"}})
    d = cfg.to_dict()
    assert isinstance(d["scenario"], dict)
    assert with_overrides(SimConfig(), d) == cfg


def test_default_to_dict_round_trips():
    assert with_overrides(SimConfig(), SimConfig().to_dict()) == SimConfig()
    automotive = with_overrides(SimConfig(), {"camera": {"preset": "automotive_1080p"}})
    assert with_overrides(SimConfig(), automotive.to_dict()) == automotive


@pytest.mark.parametrize(
    "obj, attr, value",
    [
        (SimConfig(), "scenario", ScenarioConfig()),
        (ScenarioConfig(), "speed_kmh", 10.0),
        (VehicleConfig(), "brake_balance_front", 0.5),
        (CameraConfig(), "width_px", 100),
        (LoopConfig(), "physics_dt_s", 0.001),
        (PerceptionConfig(), "kind", "x"),
        (PolicyConfig(), "name", "adjusted"),
    ],
)
def test_configs_are_frozen(obj, attr, value):
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(obj, attr, value)


def test_a_region_of_interest_is_a_list_of_four_ints():
    config = with_overrides(SimConfig(), {"perception": {"front_roi_px": [0, 0, 640, 480]}})
    assert config.perception.front_roi_px == (0, 0, 640, 480)
    assert with_overrides(SimConfig(), config.to_dict()) == config  # survives the JSON round trip


@pytest.mark.parametrize("value, message", [
    ([0, 0, 640], r"must be \[\] \(the camera's deployed region\) or \[x0, y0, x1, y1\]"),
    ([0, 0, 640.0, 480], "must be a list of ints"),
    ("0,0,640,480", "must be a list of ints"),
    ([300, 0, 200, 480], "0 <= x0 < x1"),
    ([0, -1, 640, 480], "0 <= y0 < y1"),
])
def test_a_bad_region_of_interest_is_a_clear_error(value, message):
    with pytest.raises(ConfigError, match=message):
        with_overrides(SimConfig(), {"perception": {"side_roi_px": value}})


def test_onnx_classes_take_a_list_of_names_of_any_length():
    config = with_overrides(SimConfig(), {"perception": {"onnx_classes": ["stop_sign", "yield", "person", "car"]}})
    assert config.perception.onnx_classes == ("stop_sign", "yield", "person", "car")
    with pytest.raises(ConfigError, match="perception.onnx_classes' must be a list of strs"):
        with_overrides(SimConfig(), {"perception": {"onnx_classes": ["stop_sign", 3]}})
    with pytest.raises(ConfigError, match="non-empty names"):
        with_overrides(SimConfig(), {"perception": {"onnx_classes": ["stop_sign", " "]}})


@pytest.mark.parametrize("key,value,message", [("coco_input", "zoom", "coco_input must be one of resize, crop, upscale"),
                                               ("coco_upscale", 8.0, "coco_upscale must be in [1, 4]"),
                                               ("coco_precision", "fp16", "coco_precision must be one of auto, fp32, bf16")])
def test_coco_keys_are_checked(key, value, message):
    with pytest.raises(ConfigError, match=message.replace("[", r"\[").replace("]", r"\]")):
        with_overrides(SimConfig(), {"perception": {key: value}})
