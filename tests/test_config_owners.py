"""Every policy and perception key has an owner: the declarations match the keys the code reads,
and a key set where nothing reads it is refused, across every policy and perception kind (no simulation)."""

from __future__ import annotations

import ast
import inspect
import textwrap
from pathlib import Path

import pytest

from avsim import cli
from avsim.config import PerceptionConfig, PolicyConfig, SimConfig
from avsim.config_owners import (DETECT_UNREAD, EVERY_RUN_READS, REPLAY_UNREAD, as_run, check_read, check_read_by_some,
                                 check_read_on_images, identical_runs, keys_read, readers, set_keys)
from avsim.control.policies import POLICIES
from avsim.errors import ConfigError
from avsim.experiments.leaderboard import load_leaderboard
from avsim.experiments.spec import load_experiment
from avsim.experiments.sweep import load_sweep
from avsim.perception import factory
from avsim.perception.factory import CONDITIONAL_KEYS, FRAME_DETECTORS, PERCEPTION_KEYS, PERCEPTIONS, perception_keys
from avsim.perception.purify import build_purifier
from tests.control.test_policies import BUMPER, CTX, F_PX, det, obs

ROOT = Path(__file__).resolve().parents[1]
POLICY_KEYS = sorted(f.name for f in PolicyConfig.__dataclass_fields__.values() if f.name != "name")
PERCEPTION_FIELDS = sorted(f.name for f in PerceptionConfig.__dataclass_fields__.values() if f.name != "kind")
# A valid PerceptionConfig of every kind (onnx needs its file's name and classes to be valid).
KIND_CONFIGS = {kind: PerceptionConfig(kind=kind, **({"onnx_path": "model.onnx", "onnx_classes": ("stop_sign",)} if kind == "onnx" else {}))
                for kind in PERCEPTIONS.names()}


# ---- the declarations are what the code reads ---------------------------------------------

class RecordingConfig:
    """A PolicyConfig that records which keys are read."""

    def __init__(self, config: PolicyConfig) -> None:
        self._config = config
        self.read: set[str] = set()

    def __getattr__(self, name: str):
        self.read.add(name)
        return getattr(self._config, name)


def _approach():
    """A drive at 20 m/s towards a stop sign, as the cameras see it: boxes that grow as the range
    shrinks with the odometry (1 m a step), a weaker box beside each, the side camera from 25 m, a
    truncated box, then frames without the sign."""
    frames = []
    for step in range(30):
        sign_m = 45.0 - step
        h_px = 0.762 * F_PX / sign_m
        front = [det(h_px, 0.9, truncated=step == 20), det(h_px, 0.4)]
        side = [det(h_px, 0.9, camera="side")] if sign_m < 25 else []
        frames.append(obs(speed=20.0, front=front, side=side, stop_line=sign_m - 2.75, t=step * 0.05))
    return frames + [obs(speed=5.0, stop_line=10.0, t=2.0)] * 3


@pytest.mark.parametrize("name", POLICIES.names())
def test_each_policy_declares_exactly_the_policy_keys_it_reads(name):
    factory_ = POLICIES.get(name)
    recording = RecordingConfig(PolicyConfig(name=name, trigger_dist_m=200.0))
    from avsim.world.hd_map import HdMap, MapHandle

    extra = {"map_handle": MapHandle(HdMap((0.0,)), BUMPER)} if factory_.uses_map else {}
    policy = factory_(recording, CTX, **extra)
    for observation in _approach():
        policy.decide(observation)
    assert recording.read - {"name"} == set(factory_.config_keys)


def _config_reads(function) -> set[str]:
    """The attributes a function reads from its config argument (named config or cfg), by its source."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(function)))
    return {node.attr for node in ast.walk(tree)
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in ("config", "cfg")}


@pytest.mark.parametrize("kind", PERCEPTIONS.names())
def test_each_perception_declares_exactly_the_perception_keys_it_reads(kind):
    if kind in FRAME_DETECTORS:  # the frame perception around the network, the purifier in front of it, the network
        read = _config_reads(factory._frame_perception) | _config_reads(build_purifier) | _config_reads(FRAME_DETECTORS.get(kind))
        declared = set(PERCEPTION_KEYS[kind]) | {key for key, (switch, _) in CONDITIONAL_KEYS.items() if switch == "purify"}
    else:  # the oracle and none: their lambdas in the registry
        read = _config_reads(PERCEPTIONS.get(kind))
        declared = set(PERCEPTION_KEYS[kind])
    assert read - {"kind"} == declared


def test_conditional_keys_are_read_only_under_their_switch():
    assert "coco_upscale" in perception_keys(PerceptionConfig(kind="coco", coco_input="upscale"))
    assert "coco_upscale" not in perception_keys(PerceptionConfig(kind="coco", coco_input="resize"))
    assert "purify_jpeg_quality" in perception_keys(PerceptionConfig(purify="jpeg"))
    assert "purify_median_kernel_px" not in perception_keys(PerceptionConfig(purify="jpeg"))
    assert "ensemble_k" in perception_keys(PerceptionConfig(kind="ensemble", ensemble_fusion="k_of_n"))
    ensemble = perception_keys(PerceptionConfig(kind="ensemble", ensemble_members=("detector", "yolo")))
    assert {"weights_path", "yolo_input"} <= ensemble and "coco_input" not in ensemble and "ensemble_k" not in ensemble


def test_every_key_has_an_owner():
    for key in POLICY_KEYS:
        assert "no policy" not in readers(f"policy.{key}"), key
    for key in PERCEPTION_FIELDS:
        assert "no perception" not in readers(f"perception.{key}"), key


# ---- refusals, for every policy and perception kind ---------------------------------------

@pytest.mark.parametrize("kind", ["detector", "none"])
@pytest.mark.parametrize("name", POLICIES.names())
def test_a_policy_key_is_refused_exactly_where_the_policy_does_not_read_it(name, kind):
    # A policy that gets no detection (perception none, or the autopilot's no camera) reads only its blind keys.
    policy = POLICIES.get(name)
    config = SimConfig(policy=PolicyConfig(name=name), perception=KIND_CONFIGS[kind])
    detects = bool(policy.cameras) and kind != "none"
    declared = set(policy.config_keys) | {"conf_threshold"} if detects else set(policy.blind_keys)
    for key in POLICY_KEYS:
        if key in declared:
            check_read(config, {f"policy.{key}"})
        elif key in policy.config_keys or key == "conf_threshold":
            with pytest.raises(ConfigError, match=rf"^policy\.{key} is read only by .* this run's .*gets no detection, so it "
                                                  r"would be ignored; remove it, or choose a (perception other than none|policy "
                                                  r"that uses a camera)$"):
                check_read(config, {f"policy.{key}"})
        else:
            with pytest.raises(ConfigError, match=rf"^policy\.{key} is read only by polic.* this run's policy is {name}, "):
                check_read(config, {f"policy.{key}"})


def _blind_decisions(name: str, config: PolicyConfig) -> list:
    """The decisions of policy `name` over a drive at 20 m/s that gets no detection (as perception none gives)."""
    from avsim.world.hd_map import HdMap, MapHandle

    factory_ = POLICIES.get(name)
    extra = {"map_handle": MapHandle(HdMap((0.0,)), BUMPER)} if factory_.uses_map else {}
    policy = factory_(config, CTX, **extra)
    return [policy.decide(obs(speed=20.0, stop_line=40.0 - step, t=step * 0.05)) for step in range(30)]


# A valid value other than the default of every policy key (vote_k within the default vote_n).
OTHER_VALUES = {"conf_threshold": 0.2, "trigger_dist_m": 90.0, "sign_height_m": 0.9, "stop_line_before_sign_m": 3.0,
                "baseline_brake": 0.3, "stop_margin_m": 4.0, "a_max_mps2": 5.0, "brake_multiplier": 0.7,
                "autopilot_stop_margin_m": 6.0, "autopilot_decel_fraction": 0.3, "vote_conf_threshold": 0.1, "vote_k": 1,
                "vote_n": 9, "vote_range_rate_tol": 0.05, "vote_min_travel_m": 0.1, "study_sign_height_m": 0.5}


@pytest.mark.parametrize("name", POLICIES.names())
def test_a_policy_key_refused_without_detections_changes_no_decision_and_a_blind_key_does(name):
    assert sorted(OTHER_VALUES) == POLICY_KEYS
    policy = POLICIES.get(name)
    base = _blind_decisions(name, PolicyConfig(name=name))
    for key in POLICY_KEYS:
        changed = _blind_decisions(name, PolicyConfig(name=name, **{key: OTHER_VALUES[key]}))
        assert (changed != base) == (key in policy.blind_keys), key


@pytest.mark.parametrize("kind", PERCEPTIONS.names())
def test_a_perception_key_is_refused_exactly_where_the_perception_does_not_read_it(kind):
    config = SimConfig(perception=KIND_CONFIGS[kind], policy=PolicyConfig(name="combined"))  # both cameras: both regions
    for key in PERCEPTION_FIELDS:
        if key in perception_keys(config.perception):
            check_read(config, {f"perception.{key}"})
        else:
            with pytest.raises(ConfigError, match=rf"^perception\.{key} is read only by .* this run's perception is {kind}"):
                check_read(config, {f"perception.{key}"})


@pytest.mark.parametrize("name", POLICIES.names())
def test_the_maps_keys_are_read_exactly_by_the_policies_that_read_the_map(name):
    config = SimConfig(policy=PolicyConfig(name=name))
    keys = {"scenario.map_stop_line_offset_m", "scenario.map_error"}
    if POLICIES.get(name).uses_map:
        check_read(config, keys)
    else:
        with pytest.raises(ConfigError, match=r"scenario\.map_error is read only by the policies that read the map "
                                              r"\(autopilot, map_prior\), and this run's policy is " + name):
            check_read(config, keys)


def test_a_sweep_of_map_offsets_under_a_camera_policy_is_refused_as_one_run_twice(tmp_path):
    grid = '"policy.name" = ["baseline", "map_prior"]\n"scenario.map_stop_line_offset_m" = [0, 5]'
    with pytest.raises(ConfigError, match=r"are the same run: scenario\.map_stop_line_offset_m is not read"):
        load_sweep(_write(tmp_path, SWEEP.format(grid=grid)))


def test_the_every_run_keys_are_never_refused():
    # (the scene, camera and vehicle keys read under a condition: tests/test_config_sight.py)
    for name in POLICIES.names():
        config = SimConfig(policy=PolicyConfig(name=name), perception=PerceptionConfig(kind="none"))
        check_read(config, set(EVERY_RUN_READS) | {"scenario.speed_kmh", "vehicle.abs_enabled", "loop.max_time_s"}, recorded=False)


def test_avsim_run_refuses_an_unread_key_in_one_line_with_exit_2(capsys):
    assert cli.main(["run", "--policy", "baseline", "--set", "policy.vote_k=4"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("avsim: error: policy.vote_k is read only by policy temporal_vote, and this run's policy is baseline, "
                   "so it would be ignored; remove it, or choose a policy that reads it")


@pytest.mark.parametrize("argv, message", [
    (["--set", "policy.vote_k=4"], "policy.vote_k is not read by avsim detect, which runs a perception on images"),
    (["--set", "scenario.town=town03"], "scenario.town is not read by avsim detect"),
    (["--set", "perception.sensor_noise_std=2"], "perception.sensor_noise_std is not read by avsim detect (a simulated camera's setting)"),
    (["--set", "perception.front_roi_px=[0,0,64,64]"], "perception.front_roi_px is not read by avsim detect"),
    (["--perception", "detector", "--set", "perception.coco_input=crop"], "perception.coco_input is not read by avsim detect (read only by perception coco"),
])
def test_avsim_detect_refuses_a_key_it_does_not_read_before_any_image(tmp_path, capsys, argv, message):
    assert cli.main(["detect", str(tmp_path / "missing.png"), *argv]) == 2  # refused before the missing image
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and message in err, err


def test_a_perception_on_images_accepts_the_keys_it_reads():
    coco = PerceptionConfig(kind="coco", coco_input="crop")
    check_read_on_images(coco, {"kind": "coco", "coco_input": "crop", "min_confidence": 0.2}, "avsim detect", DETECT_UNREAD)
    check_read_on_images(coco, {"front_roi_px": [0, 0, 64, 64]}, "avsim replay", REPLAY_UNREAD)  # a bag's frames have regions
    with pytest.raises(ConfigError, match="sensor_noise_std is not read by avsim replay"):
        check_read_on_images(coco, {"sensor_noise_std": 2.0}, "avsim replay", REPLAY_UNREAD)


def test_set_keys_are_the_owned_keys_a_mapping_sets():
    assert set_keys({"policy": {"name": "x", "vote_k": 3}, "scenario": {"town": "t"}, "perception": {}}) == {"policy.name", "policy.vote_k"}
    assert set_keys({"scenario": {"town": "t", "map_error": "phantom_stop"}}) == {"scenario.map_error"}


# ---- experiment files, sweeps: where a key is written decides which runs must read it -------

EXPERIMENT = """
title = "t"
[defaults]
scenario = {{ town = "town07" }}
{defaults}
[[cells]]
name = "baseline"
policy = {{ name = "baseline" {baseline} }}
[[cells]]
name = "vote"
policy = {{ name = "temporal_vote" }}
"""


def _write(tmp_path, text):
    path = tmp_path / "file.toml"
    path.write_text(text)
    return path


def test_an_experiment_default_read_by_one_cell_loads(tmp_path):
    experiment = load_experiment(_write(tmp_path, EXPERIMENT.format(defaults="policy = { vote_k = 4 }", baseline="")))
    assert [cell.config.policy.vote_k for cell in experiment.cells] == [4, 4]


def test_an_experiment_default_no_cell_reads_is_refused(tmp_path):
    with pytest.raises(ConfigError, match=r"\[defaults\]: perception\.coco_input is read only by .* no cell here has one"):
        load_experiment(_write(tmp_path, EXPERIMENT.format(defaults='perception = { coco_input = "crop" }', baseline="")))


def test_a_cell_key_its_policy_does_not_read_is_refused(tmp_path):
    with pytest.raises(ConfigError, match=r'cells\[0\] "baseline": policy\.vote_k is read only by policy temporal_vote'):
        load_experiment(_write(tmp_path, EXPERIMENT.format(defaults="", baseline=", vote_k = 4")))


SWEEP = """
title = "s"
[defaults]
scenario = {{ town = "town07" }}
[grid]
{grid}
"""


def test_a_sweep_axis_no_run_reads_is_refused(tmp_path):
    with pytest.raises(ConfigError, match=r"\[grid\]: policy\.vote_k is read only by policy temporal_vote, and no run of the grid"):
        load_sweep(_write(tmp_path, SWEEP.format(grid='"policy.name" = ["baseline", "adjusted"]\n"policy.vote_k" = [3, 4]')))


def test_a_sweep_whose_points_make_the_same_run_is_refused(tmp_path):
    grid = '"policy.name" = ["baseline", "temporal_vote"]\n"policy.vote_k" = [3, 4]'
    with pytest.raises(ConfigError, match=r"points policy\.name=baseline, policy\.vote_k=3 and policy\.name=baseline, "
                                          r"policy\.vote_k=4 are the same run: policy\.vote_k is not read"):
        load_sweep(_write(tmp_path, SWEEP.format(grid=grid)))


def test_a_sweep_of_keys_every_run_reads_loads(tmp_path):
    sweep = load_sweep(_write(tmp_path, SWEEP.format(grid='"policy.name" = ["temporal_vote"]\n"policy.vote_k" = [3, 4]')))
    assert sweep.size == 2


def test_as_run_and_identical_runs():
    baseline = SimConfig(policy=PolicyConfig(name="baseline"))
    voted = SimConfig(policy=PolicyConfig(name="baseline", vote_k=4))
    assert as_run(voted) == as_run(baseline) and keys_read(voted) == keys_read(baseline)
    assert identical_runs([("a", baseline), ("b", voted)]) == ("a", "b", ["policy.vote_k"])
    assert identical_runs([("a", baseline), ("b", SimConfig(policy=PolicyConfig(name="baseline", baseline_brake=0.9)))]) is None
    with pytest.raises(ConfigError, match="no run here"):
        check_read_by_some([baseline], {"policy.vote_k"})


# ---- every shipped file still loads ------------------------------------------------------

SHIPPED = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "experiments").rglob("*.toml"))


@pytest.mark.parametrize("name", SHIPPED)
def test_every_shipped_experiment_sweep_and_leaderboard_file_loads(name):
    path = ROOT / name
    if path.parent.name == "sweeps":
        load_sweep(path, yes=True)
    elif path.parent.name == "leaderboards":
        load_leaderboard(path)
    else:
        load_experiment(path)
