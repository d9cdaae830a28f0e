"""The scene, camera and vehicle keys a run reads only under a condition (`avsim.config_sight`):
refused exactly where the run does not read them, across every policy and perception kind, with
and without a recorder; and a key declared unread really changes nothing in a run (a few steps)."""

from __future__ import annotations

import re

import pytest

from avsim import cli
from avsim.config import PolicyConfig, SimConfig, with_overrides
from avsim.config_owners import check_read, check_read_by_some, check_snapshot_reads, keys_read, readers
from avsim.config_sight import RUN_CONDITIONS
from avsim.control.policies import POLICIES
from avsim.errors import ConfigError
from avsim.experiments.spec import load_experiment
from avsim.experiments.sweep import load_sweep
from avsim.gym.env import env_config
from avsim.loop import ClosedLoop
from avsim.perception.factory import FRAME_DETECTORS, PERCEPTIONS
from tests.test_config_owners import KIND_CONFIGS, _write

PIXEL = set(FRAME_DETECTORS.names())
# The conditional keys by what reads them; together every key of RUN_CONDITIONS (checked below).
PICTURE_KEYS = ("camera.preset", "camera.width_px", "camera.height_px", "camera.fovy_deg", "camera.offsamples",
                "scenario.distractors", "scenario.layout_seed", "scenario.sign_materials", "scenario.foliage",
                "scenario.facade_windows")
COLOUR_KEYS = ("camera.supersample", "camera.texture_anisotropy", "camera.lens_mtf50_cyc_per_px", "camera.jpeg_quality", "scenario.sun_elevation_deg",
               "scenario.sun_azimuth_deg", "scenario.sun_intensity", "scenario.fog_end_m", "scenario.materials",
               "scenario.sun_shadow_map_px", "scenario.sky", "scenario.road_paint", "scenario.sky_exposure_ev")
SIDE_KEYS = ("camera.side_fovy_deg", "camera.side_yaw_deg")
# Keys every run reads, whatever it draws (a sample of each section).
ALWAYS = ("scenario.town", "scenario.placement", "scenario.sign_yaw_deg", "scenario.speed_kmh",
          "scenario.start_dist_m", "scenario.road_friction", "vehicle.abs_enabled", "vehicle.brake_rise_time_s",
          "loop.physics_dt_s", "loop.max_time_s")


def test_every_conditional_key_is_in_one_group_here():
    grouped = [*PICTURE_KEYS, *COLOUR_KEYS, *SIDE_KEYS, "camera.seg_supersample", "scenario.fog_start_m", "scenario.seed",
               "vehicle.abs_target_slip", "scenario.sign", "scenario.sky_turbidity", "scenario.cloud_oktas",
               "scenario.cloud_base_m", "scenario.cloud_visibility_km"]
    assert sorted(grouped) == sorted(RUN_CONDITIONS)


def _expected(name: str, kind: str, recorded: bool) -> dict[str, bool]:
    """Which keys a run of policy `name` and perception `kind` reads, from the loop's rules: the
    perception sees through the policy's cameras (colour for a pixel perception, segmentation for
    the oracle, nothing for none), and a recorder draws the front camera and the policy's in colour."""
    cameras = POLICIES.get(name).cameras
    sees = bool(cameras) and kind != "none"
    expected = dict.fromkeys(PICTURE_KEYS, sees or recorded)
    expected |= dict.fromkeys(COLOUR_KEYS, (sees and kind in PIXEL) or recorded)
    expected |= dict.fromkeys(SIDE_KEYS, "side" in cameras and (kind != "none" or recorded))
    expected |= {"camera.seg_supersample": sees and kind == "oracle",
                 "scenario.sign": (sees and kind in PIXEL) or recorded,  # a texture (the default clean one)
                 "scenario.fog_start_m": False,  # no fog by default
                 "scenario.sky_turbidity": False,  # the gradient sky by default
                 "scenario.cloud_oktas": False,
                 "scenario.cloud_base_m": False, "scenario.cloud_visibility_km": False,  # no clouds by default
                 "vehicle.abs_target_slip": True, "scenario.seed": True,  # the default start jitter is 2 m
                 "perception.front_roi_px": "front" in cameras and kind in PIXEL,
                 "perception.side_roi_px": "side" in cameras and kind in PIXEL,
                 # a perception's keys, read only where it sees through a camera (the autopilot uses none)
                 "perception.threads": bool(cameras) and kind in PIXEL,
                 "perception.oracle_min_box_height_px": bool(cameras) and kind == "oracle"}
    return expected | dict.fromkeys(ALWAYS, True)


@pytest.mark.parametrize("kind", PERCEPTIONS.names())
@pytest.mark.parametrize("name", POLICIES.names())
def test_a_scene_or_camera_key_is_refused_exactly_where_the_run_does_not_draw_it(name, kind):
    config = SimConfig(policy=PolicyConfig(name=name), perception=KIND_CONFIGS[kind])
    for recorded in (False, True):
        for key, read in _expected(name, kind, recorded).items():
            if read:
                check_read(config, {key}, recorded=recorded)
            else:
                with pytest.raises(ConfigError, match=rf"^{re.escape(key)} is read only by .*, and this run's .*, so it would be "
                                                      r"ignored; remove it, or \w"):
                    check_read(config, {key}, recorded=recorded)


def test_conditions_on_other_keys_fog_seed_and_slip_control():
    foggy = with_overrides(SimConfig(), {"scenario": {"fog_end_m": 120.0}})
    check_read(foggy, {"scenario.fog_start_m"}, recorded=False)
    with pytest.raises(ConfigError, match=r"this run's scenario\.fog_end_m is 0 \(clear air"):
        check_read(SimConfig(), {"scenario.fog_start_m"}, recorded=False)
    no_slip_control = with_overrides(SimConfig(), {"vehicle": {"abs_enabled": False, "traction_control_enabled": False}})
    with pytest.raises(ConfigError, match=r"vehicle\.abs_target_slip is read only by the anti-lock brakes .* both false"):
        check_read(no_slip_control, {"vehicle.abs_target_slip"})
    check_read(with_overrides(no_slip_control, {"vehicle": {"traction_control_enabled": True}}), {"vehicle.abs_target_slip"})
    with pytest.raises(ConfigError, match=r"this run's scenario\.sky is gradient \(no daylight sky"):
        check_read(SimConfig(), {"scenario.sky_turbidity"}, recorded=False)
    check_read(with_overrides(SimConfig(), {"scenario": {"sky": "daylight"}}), {"scenario.sky_turbidity"}, recorded=False)
    no_jitter = with_overrides(SimConfig(), {"scenario": {"start_jitter_m": 0.0}})
    with pytest.raises(ConfigError, match=r"scenario\.seed .* this run's scenario\.start_jitter_m is 0, it draws no sensor noise and no clouds"):
        check_read(no_jitter, {"scenario.seed"})
    check_read(with_overrides(no_jitter, {"perception": {"sensor_noise_std": 2.0}}), {"scenario.seed"})
    with pytest.raises(ConfigError, match=r"scenario\.seed"):  # the oracle draws no noise
        check_read(with_overrides(no_jitter, {"perception": {"kind": "oracle"}}), {"scenario.seed"})
    # Clouds are drawn from the seed; the noise-free own detector then reads it through them alone.
    cloudy = with_overrides(no_jitter, {"perception": {"sensor_noise_std": 0.0}, "scenario": {"sky": "daylight", "cloud_oktas": 4}})
    check_read(cloudy, {"scenario.seed", "scenario.cloud_oktas", "scenario.cloud_base_m", "scenario.cloud_visibility_km"})
    with pytest.raises(ConfigError, match=r"scenario\.seed .* no clouds"):
        check_read(with_overrides(cloudy, {"scenario": {"cloud_oktas": 0}}), {"scenario.seed"})
    # The layer's height and the air's visibility matter only where clouds are drawn.
    with pytest.raises(ConfigError, match=r"scenario\.cloud_base_m .* this run's scenario\.cloud_oktas is 0 \(a clear sky"):
        check_read(with_overrides(cloudy, {"scenario": {"cloud_oktas": 0}}), {"scenario.cloud_base_m"})
    with pytest.raises(ConfigError, match=r"scenario\.cloud_visibility_km .* this run's scenario\.sky is gradient"):
        check_read(no_jitter, {"scenario.cloud_visibility_km"}, recorded=False)


def test_no_stop_sign_is_read_by_every_run_and_a_texture_only_where_colour_is_drawn(tmp_path, capsys):
    oracle = with_overrides(SimConfig(), {"perception": {"kind": "oracle"}})
    with pytest.raises(ConfigError, match=r"^scenario\.sign is read only by every run for none .* this run's perception is "
                                          r"oracle, which draws no colour image"):
        check_read(with_overrides(oracle, {"scenario": {"sign": "eykholt"}}), {"scenario.sign"}, recorded=False)
    check_read(with_overrides(oracle, {"scenario": {"sign": "none", "sign_yaw_deg": 0.0}}), {"scenario.sign"}, recorded=False)
    check_read(with_overrides(oracle, {"scenario": {"sign": "eykholt"}}), {"scenario.sign"}, recorded=True)
    assert cli.main(["run", "--policy", "autopilot", "--sign", "eykholt"]) == 2
    assert "scenario.sign is read only by every run for none" in capsys.readouterr().err
    # over a cell with no stop sign, a texture puts one there: read, and it runs (a second of the autopilot)
    cell = _write(tmp_path, 'title = "t"\n[[cells]]\nname = "a"\npolicy = { name = "autopilot" }\nscenario = { sign = "none" }')
    assert cli.main(["run", "--config", str(cell), "--cell", "a", "--sign", "eykholt", "--set", "loop.max_time_s=1"]) == 0
    assert "sign eykholt" in capsys.readouterr().out


def test_a_preset_set_beside_every_key_it_fills_is_refused():
    keys = {"camera.preset", "camera.width_px", "camera.height_px", "camera.fovy_deg"}
    with pytest.raises(ConfigError, match=r"^camera\.preset fills only .* camera\.width_px, camera\.height_px, camera\.fovy_deg are "
                                          r"all set here"):
        check_read(SimConfig(), keys, recorded=False)  # baseline: the side camera's field of view is not read
    check_read(SimConfig(policy=PolicyConfig(name="combined")), keys, recorded=False)  # the preset fills side_fovy_deg


def test_the_messages_say_why_in_one_line():
    autopilot = SimConfig(policy=PolicyConfig(name="autopilot"))
    with pytest.raises(ConfigError) as refused:
        check_read(autopilot, {"scenario.fog_end_m"}, recorded=False)
    assert str(refused.value) == (
        "scenario.fog_end_m is read only by " + readers("scenario.fog_end_m") + ", and this run's policy is autopilot, which "
        "uses no camera, and nothing records it, so it would be ignored; remove it, or choose a pixel perception and a policy "
        "that uses a camera, or record the run")
    with pytest.raises(ConfigError, match=r"^perception\.min_confidence is read only by .* this run's policy is autopilot, "
                                          r"which uses no camera, .* choose a policy that uses a camera$"):
        check_read(autopilot, {"perception.min_confidence"})
    with pytest.raises(ConfigError, match=r"^camera\.side_yaw_deg .*policy is baseline, which does not use the side camera, "
                                          r"so it would be ignored; remove it, or choose a policy that uses the side camera "
                                          r"\(combined, side_camera, study_stack\)$"):
        check_read(SimConfig(), {"camera.side_yaw_deg"})


def test_avsim_run_refuses_what_nothing_draws_unless_it_records(capsys):
    assert cli.main(["run", "--policy", "autopilot", "--set", "scenario.sun_intensity=0.5"]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "scenario.sun_intensity is read only by a run that draws colour images" in err, err
    assert cli.main(["run", "--set", "camera.side_yaw_deg=30", "--mp4", "/nonexistent-dir/x.mp4"]) == 2
    assert "camera.side_yaw_deg is read only by a run that draws the side camera" in capsys.readouterr().err


def test_a_gym_agent_names_the_cameras_its_perception_sees_through():
    side_region = {"perception": {"side_roi_px": [0, 0, 64, 64]}}
    assert env_config(perception="detector", config_overrides=side_region, cameras=("front", "side")).perception.side_roi_px
    with pytest.raises(ConfigError, match=r"perception sees through the front camera only"):
        env_config(perception="detector", config_overrides=side_region)


# ---- files: a batch may record its runs ------------------------------------------------------

def test_a_file_key_no_run_draws_is_refused_and_a_recorded_one_loads(tmp_path):
    cells = '[[cells]]\nname = "a"\npolicy = {{ name = "baseline" }}\n{extra}'
    with pytest.raises(ConfigError, match=r'cells\[0\] "a": camera\.side_yaw_deg is read only by a run that draws the side camera'):
        load_experiment(_write(tmp_path, 'title = "t"\n' + cells.format(extra="camera = { side_yaw_deg = 30.0 }")))
    # the autopilot draws nothing itself, but a batch may record it (--rrd failed by default)
    experiment = load_experiment(_write(tmp_path, 'title = "t"\n[[cells]]\nname = "a"\npolicy = { name = "autopilot" }\n'
                                                  'scenario = { fog_end_m = 80.0 }'))
    assert experiment.cells[0].config.scenario.fog_end_m == 80.0
    with pytest.raises(ConfigError, match=r"\[grid\]: camera\.seg_supersample is read only by the oracle perception"):
        load_sweep(_write(tmp_path, 'title = "s"\n[grid]\n"policy.name" = ["baseline", "adjusted"]\n"camera.seg_supersample" = [1, 2]'))


def test_a_sweep_of_side_camera_angles_under_a_front_policy_is_one_run_twice(tmp_path):
    grid = '"policy.name" = ["baseline", "side_camera"]\n"camera.side_yaw_deg" = [20.0, 30.0]'
    with pytest.raises(ConfigError, match=r"are the same run: camera\.side_yaw_deg is not read"):
        load_sweep(_write(tmp_path, f'title = "s"\n[grid]\n{grid}'))
    with pytest.raises(ConfigError, match="no run here"):
        check_read_by_some([SimConfig()], {"camera.side_fovy_deg"})
    with pytest.raises(ConfigError, match=r"perception\.side_roi_px .* no cell here .* choose a pixel perception and a policy "
                                          r"that uses the side camera$"):
        check_read_by_some([SimConfig()], {"perception.side_roi_px"}, runs="cell")


# ---- avsim snapshot -----------------------------------------------------------------------

@pytest.mark.parametrize("argv, message", [
    (["--set", "policy.vote_k=4"], "policy.vote_k is not read by avsim snapshot (it draws the cameras' pictures, and no policy"),
    (["--speed-kmh", "50"], "scenario.speed_kmh is not read by avsim snapshot (it places the car at rest at --dist-m"),
    (["--physics-dt-s", "0.001"], "loop.physics_dt_s is not read by avsim snapshot"),
    (["--set", "vehicle.abs_enabled=false"], "vehicle.abs_enabled is not read by avsim snapshot"),
    (["--set", "scenario.map_error=phantom_stop", "--sign", "none"], "scenario.map_error is not read by avsim snapshot"),
    (["--seed", "3"], "scenario.seed is not read by avsim snapshot (it seeds the start jitter"),
    (["--set", "camera.seg_supersample=3"], "camera.seg_supersample is not read by avsim snapshot (only the oracle"),
    (["--set", "perception.coco_input=crop"], "perception.coco_input is not read by avsim snapshot (read only by perception coco"),
    (["--towns", "town07,town03", "--strip", "--town", "town10"], "scenario.town is not read by avsim snapshot (--towns names"),
])
def test_avsim_snapshot_refuses_a_key_it_does_not_read_before_any_picture(tmp_path, capsys, argv, message):
    assert cli.main(["snapshot", *argv, "--set", "perception.kind=none", "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and message in err, err
    assert not list(tmp_path.iterdir())


def test_avsim_snapshot_reads_the_scene_the_cameras_and_its_perception():
    overrides = {"scenario": {"town": "town03", "fog_end_m": 90.0, "fog_start_m": 5.0, "distractors": "red_signs", "seed": 4},
                 "camera": {"side_yaw_deg": 30.0, "preset": "automotive_1080p", "jpeg_quality": 80},
                 "perception": {"kind": "detector", "side_roi_px": [0, 0, 64, 64], "sensor_noise_std": 2.0}}
    check_snapshot_reads(with_overrides(SimConfig(), overrides), overrides, towns=False)
    oracle = {"perception": {"kind": "oracle"}, "camera": {"seg_supersample": 3}}
    check_snapshot_reads(with_overrides(SimConfig(), oracle), oracle, towns=False)


# ---- a key declared unread changes nothing in the run -----------------------------------------

SHORT = {"scenario": {"start_dist_m": 25.0, "start_speed_kmh": 40.0}}
UNREAD = [
    ("autopilot draws nothing", {"policy": {"name": "autopilot"}, "perception": {"kind": "oracle"}},
     {"scenario": {"fog_end_m": 60.0, "fog_start_m": 2.0, "sun_intensity": 0.3, "materials": "textured",
                   "distractors": "red_signs", "layout_seed": 7},
      "camera": {"preset": "automotive_1080p", "side_yaw_deg": 40.0, "jpeg_quality": 40, "seg_supersample": 4},
      "perception": {"oracle_min_box_height_px": 30.0}, "policy": {"conf_threshold": 0.2}}),
    ("the oracle draws no colour nor the side camera", {"perception": {"kind": "oracle"}},
     {"scenario": {"fog_end_m": 30.0, "sun_elevation_deg": 10.0},
      "camera": {"supersample": 2, "lens_mtf50_cyc_per_px": 0.2, "jpeg_quality": 40, "side_fovy_deg": 50.0, "side_yaw_deg": 45.0}}),
    ("none draws nothing", {"perception": {"kind": "none"}},
     {"scenario": {"distractors": "red_signs", "layout_seed": 3}, "camera": {"width_px": 320, "fovy_deg": 60.0},
      "policy": {"conf_threshold": 0.2, "trigger_dist_m": 90.0, "baseline_brake": 0.3}}),
    ("a sign texture under the oracle", {"perception": {"kind": "oracle"}}, {"scenario": {"sign": "eykholt"}}),
    ("a sign texture under the autopilot", {"policy": {"name": "autopilot"}}, {"scenario": {"sign": "yang"}}),
    ("none gives map_prior no detection", {"policy": {"name": "map_prior"}, "perception": {"kind": "none"}},
     {"policy": {"conf_threshold": 0.2, "trigger_dist_m": 90.0, "stop_margin_m": 4.0}}),
    ("no slip control", {"policy": {"name": "autopilot"}, "vehicle": {"abs_enabled": False, "traction_control_enabled": False}},
     {"vehicle": {"abs_target_slip": 0.3}}),
    ("no jitter, no noise", {"scenario": {"start_jitter_m": 0.0}, "perception": {"kind": "oracle"}}, {"scenario": {"seed": 9}}),
]


def _records(config: SimConfig, steps: int = 3) -> list:
    loop = ClosedLoop(config)
    try:
        return [loop.step() for _ in range(steps)]
    finally:
        loop.close()


@pytest.mark.parametrize("label, base, change", UNREAD, ids=[case[0] for case in UNREAD])
def test_a_key_declared_unread_leaves_the_run_bit_identical(label, base, change):
    config = with_overrides(with_overrides(SimConfig(), SHORT), base)
    changed = with_overrides(config, change)
    unread = {f"{section}.{key}" for section, table in change.items() for key in table}
    assert not unread & keys_read(config, recorded=False)
    records = _records(config)
    assert _records(changed) == records
    if config.perception.kind == "oracle" and config.policy.name != "autopilot":
        assert all(record.detections for record in records)  # the oracle saw the sign in every step compared


def test_a_key_the_oracle_reads_changes_its_run():
    # The comparison above can fail: segmentation at a finer scale moves the oracle's box edges.
    config = with_overrides(with_overrides(SimConfig(), SHORT), {"perception": {"kind": "oracle"}})
    assert "camera.seg_supersample" in keys_read(config, recorded=False)
    assert _records(with_overrides(config, {"camera": {"seg_supersample": 3}})) != _records(config)
