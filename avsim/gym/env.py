"""`avsim/StopSign-v0`: the closed loop as a Gymnasium environment, with an agent in the driver's seat.

    import gymnasium
    import avsim.gym  # registers avsim/StopSign-v0

    env = gymnasium.make("avsim/StopSign-v0", town="town07", perception="oracle")
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step([0.3, 0.0])   # throttle, brake

Each step is one control step of `avsim.loop.ClosedLoop` (20 Hz by default), in the loop's own
order: the observation the agent acted on was rendered and perceived at the step's start
(`ClosedLoop.perceive`), then its commands are applied, the physics runs and the step is
recorded (`ClosedLoop.actuate`), and the next observation is rendered and perceived. The agent
takes the braking policy's place; the policy in the config is never asked.

- Action: Box([0, 0], [1, 1]) float32, (throttle, brake); the built-in lane keeper steers. With
  full_control=True, Box([0, 0, -1], [1, 1, 1]): (throttle, brake, steer), steer a fraction of the
  front wheels' full lock (0.6 rad, left +). Actions are clipped to the box; throttle is not
  released when braking (the agent decides both).
- Observation: `avsim.gym.observation` (speed, each camera's image, the perception's detections).
- Reward: `avsim.gym.reward` (progress, stop bonus, running the sign, comfort).
- Episode ends: `terminated` when the car stops (below 0.1 m/s, having moved: a car held at
  rest at the start has not stopped at the sign yet) or when its front bumper passes the sign
  post; `truncated` when `loop.max_time_s` (60 s) of simulated time is up. Gymnasium defines
  truncation as an end outside the task (a time limit), termination as a terminal state of it.
  A diverged physics raises `avsim.errors.PhysicsError`.
- info: "time_s", the true "stop_line_dist_m" and "sign_dist_m" (front bumper to each [m], for
  evaluation: never in the observation), "reward_terms" after a step, "seed" after a reset, and
  on the last step "result": the `RunResult` fields as `avsim run --json` writes them.
  Its `config.policy` is unused except `conf_threshold`, which decides which detection counts as
  `first_detection_dist_m`.
- Seeding: `reset(seed=k)` runs scenario.seed k (start jitter and sensor noise), as `avsim run
  --seed k` does; the same seed and actions give the same episode bit for bit. `reset()` with
  no seed draws the episode's seed from the environment's generator, seeded by the last seed
  given.

Every reset builds a fresh `ClosedLoop` (scene, renderers, perception): about 0.2 s here, most
of it the renderer's first frame.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from avsim.config import MAX_SEED, SimConfig, check_seed, with_overrides
from avsim.config_owners import check_read, set_keys
from avsim.control.policy_base import BrakeDecision
from avsim.errors import ConfigError
from avsim.gym.observation import detections_array, observation_space
from avsim.gym.reward import reward_terms
from avsim.loop import ClosedLoop
from avsim.metrics import STOPPED_SPEED_MPS
from avsim.perception.base import Detection
from avsim.perception.factory import FrameDetectorCache
from avsim.sensors.camera import CAMERA_NAMES
from avsim.vehicle.physics import Controls

RENDER_CAMERA = "front"
# The steering actuators of models/car.xml, whose control range is the full lock.
_STEER_ACTUATOR = "car/steer_fl"
# The policy keys an episode reads: the threshold that decides which detection counts as the result's first one.
POLICY_KEYS_READ = ("conf_threshold",)


def env_config(*, town: str | None = None, placement: str | None = None, sign: str | None = None,
               speed_kmh: float | None = None, perception: str | None = None,
               config_overrides: Mapping[str, Any] | None = None, cameras: Sequence[str] = ("front",)) -> SimConfig:
    """The `SimConfig` an environment runs: `config_overrides` (nested, as in an experiment file or
    `--set`), then the named arguments, which may not be given twice.

    The car starts at scenario.speed_kmh (85 km/h, or speed_kmh), unless config_overrides sets
    scenario.start_speed_kmh: the agent, not the cruise control, holds the throttle, so an episode
    starts at the speed the car approaches at. perception None is the `none` perception; cameras:
    those the perception sees through (a region of interest of another is not read).
    """
    if not isinstance(config_overrides, Mapping | None):
        raise ConfigError(f"config_overrides must be a mapping of config sections, e.g. {{'scenario': {{'fog_end_m': 120}}}}, "
                          f"got {config_overrides!r}")
    overrides = dict(config_overrides or {})
    for section in ("scenario", "perception"):
        if not isinstance(overrides.get(section, {}), Mapping):
            raise ConfigError(f"config_overrides['{section}'] must be a mapping of its keys, got {overrides[section]!r}")
    scenario = dict(overrides.get("scenario", {}))
    if "seed" in scenario:
        raise ConfigError("config_overrides sets scenario.seed; the episode's seed is reset(seed=...)")
    if "kind" in overrides.get("perception", {}):
        raise ConfigError("config_overrides sets perception.kind; give perception=... instead")
    policy = overrides.get("policy", {})
    unread = sorted(f"policy.{key}" for key in (policy if isinstance(policy, Mapping) else {}) if key not in POLICY_KEYS_READ)
    if unread:  # the agent takes the braking policy's place, so no policy would read them
        raise ConfigError(f"config_overrides sets {', '.join(unread)}, which the environment never reads (the agent "
                          f"takes the braking policy's place); of the policy keys it reads only {', '.join(POLICY_KEYS_READ)}")
    for key, value in (("town", town), ("placement", placement), ("sign", sign), ("speed_kmh", speed_kmh)):
        if value is not None:
            if key in scenario:
                raise ConfigError(f"{key}= and config_overrides['scenario']['{key}'] are both given; give one")
            scenario[key] = value
    base = with_overrides(SimConfig(), {**overrides, "scenario": scenario,
                                        "perception": {**overrides.get("perception", {}), "kind": perception or "none"}})
    if "start_speed_kmh" not in scenario:
        base = with_overrides(base, {"scenario": {"start_speed_kmh": base.scenario.speed_kmh}})
    # A perception key the chosen perception does not read is refused, as with --set (the agent
    # takes the policy's place, so the policy keys are not checked; it names the cameras).
    check_read(base, set_keys({"perception": overrides.get("perception", {})}), cameras=tuple(cameras))
    return base


class StopSignEnv(gymnasium.Env):
    """Approach a stop sign and stop at its line (module docstring: actions, ends, info).

    town, placement, sign, speed_kmh: as `avsim run`'s flags (None: the config's default);
    cameras: the car cameras ("front", "side") the agent and the perception use;
    perception: None, "oracle", "detector", "coco" (or "onnx", configured in config_overrides);
    images: whether each camera's image is in the observation (False: speed and detections only);
    full_control: the agent steers too; render_mode: None or "rgb_array" (the front camera);
    config_overrides: any other `SimConfig` key, nested ({"loop": {"max_time_s": 30}}), checked as
    the CLI's `--set` is: a wrong key or value is a one-line `ConfigError`;
    detectors: where the perception takes its network from, shared with other environments
    (`avsim.gym.vector`); None builds this environment's own.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(self, town: str | None = None, placement: str | None = None, sign: str | None = None,
                 speed_kmh: float | None = None, cameras: Sequence[str] = ("front",), perception: str | None = None,
                 render_mode: str | None = None, full_control: bool = False, images: bool = True,
                 config_overrides: Mapping[str, Any] | None = None, detectors: FrameDetectorCache | None = None) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        for name, flag in (("images", images), ("full_control", full_control)):
            if not isinstance(flag, (bool, np.bool_)):  # bool("no") is True
                raise ConfigError(f"{name} must be True or False, got {flag!r}")
        if perception is not None and (not isinstance(perception, str) or not perception):
            raise ConfigError(f"perception must be None or a perception's name (oracle, detector, coco, ...), got {perception!r}")
        if isinstance(speed_kmh, (np.floating, np.integer)):
            speed_kmh = float(speed_kmh)  # the config takes Python floats; a numpy scalar is the same speed
        self.cameras = _checked_cameras(cameras)
        perception = None if perception == "none" else perception
        if not images and perception is None:
            raise ConfigError("images=False with perception=None leaves the agent only its speed; give a perception or images=True")
        self.config = env_config(town=town, placement=placement, sign=sign, speed_kmh=speed_kmh, perception=perception,
                                 config_overrides=config_overrides, cameras=self.cameras)
        self.render_mode = render_mode
        self.images = bool(images)
        self.full_control = bool(full_control)
        self.metadata = {**self.metadata, "render_fps": 1.0 / self.config.loop.control_dt_s}
        self.observation_space = observation_space(self.cameras, self.images, perception is not None, self.config.camera)
        if self.full_control:
            self.action_space = spaces.Box(np.array([0, 0, -1], np.float32), np.array([1, 1, 1], np.float32), dtype=np.float32)
        else:
            self.action_space = spaces.Box(np.zeros(2, np.float32), np.ones(2, np.float32), dtype=np.float32)
        # One loop built now checks the town, placement, sign texture and perception weights
        # before any episode runs; episodes build their own (`reset`).
        self._detectors = detectors
        probe = ClosedLoop(self.config, detectors)
        self._full_lock_rad = float(probe.model.actuator(_STEER_ACTUATOR).ctrlrange[1])
        probe.close()
        self._loop: ClosedLoop | None = None
        self._observation: dict[str, np.ndarray] = {}
        self._ended = False

    # ---- Gymnasium API ---------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start an episode (Gymnasium API): the first observation and the info dict (module docstring)."""
        info = self.begin_episode(seed, options)
        return self.observe(self._loop.perceive(self.cameras)), info

    def step(self, action: Any) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """One control step with `action` (Gymnasium API): observation, reward, terminated, truncated, info."""
        reward, terminated, truncated, info = self.act(action)
        return self.observe(self._loop.perceive(self.cameras)), reward, terminated, truncated, info

    # ---- the halves of reset and step, around perception (`avsim.gym.vector` perceives many at once) ----
    def begin_episode(self, seed: int | None, options: dict[str, Any] | None) -> dict[str, Any]:
        """`reset` up to perception: a fresh loop at the episode's seed; returns the reset's info.
        `observe` the loop's perception of `cameras` to complete it."""
        if seed is not None:
            seed = int(seed) if isinstance(seed, np.integer) else seed
            check_seed(seed, "reset(seed=...)")
        if options:
            raise ConfigError(f"avsim/StopSign-v0 takes no reset options, got {options!r}; configure it when making it")
        super().reset(seed=seed)
        episode_seed = seed if seed is not None else int(self.np_random.integers(0, MAX_SEED, endpoint=True))
        self._close_loop()
        self._loop = ClosedLoop(with_overrides(self.config, {"scenario": {"seed": episode_seed}}), self._detectors)
        self._speed_mps = self._loop.vehicle.speed_mps()
        self._accel_mps2 = 0.0
        self._moved = self._speed_mps >= STOPPED_SPEED_MPS
        self._ended = False
        return {**self._state_info(), "seed": episode_seed}

    def act(self, action: Any) -> tuple[float, bool, bool, dict[str, Any]]:
        """`step` up to perception: apply the action and run the physics; returns (reward, terminated,
        truncated, info). `observe` the loop's perception of `cameras` to complete it."""
        loop = self._require_episode()
        controls = self._controls(action)
        line_before_m, _ = self._distances_m()
        loop.actuate(controls, BrakeDecision(controls.brake), self._detections)
        speed_mps = loop.vehicle.speed_mps()
        accel_mps2 = (speed_mps - self._speed_mps) / self.config.loop.control_dt_s
        line_after_m, sign_after_m = self._distances_m()
        stopped = self._moved and speed_mps < STOPPED_SPEED_MPS
        ran_sign = not stopped and sign_after_m < 0
        terminated = stopped or ran_sign
        truncated = not terminated and loop.time_s >= self.config.loop.max_time_s
        terms = reward_terms(line_dist_before_m=line_before_m, line_dist_after_m=line_after_m,
                             accel_before_mps2=self._accel_mps2, accel_after_mps2=accel_mps2, stopped=stopped, ran_sign=ran_sign)
        self._moved = self._moved or speed_mps >= STOPPED_SPEED_MPS
        self._speed_mps, self._accel_mps2 = speed_mps, accel_mps2
        info = {**self._state_info(), "reward_terms": terms.to_dict()}
        if terminated or truncated:
            info["result"] = loop.result(stopped).to_json_dict()
            self._ended = True
        return terms.total, terminated, truncated, info

    def observe(self, detections: dict[str, list[Detection]]) -> dict[str, np.ndarray]:
        """Complete `begin_episode` or `act` with the perception of `cameras` at the current state
        (`loop.perceive(cameras)`'s detections): the next observation, the agent's own copy."""
        self._detections = detections
        loop = self._loop
        width, height = self.config.camera.width_px, self.config.camera.height_px
        observation = {"speed_mps": np.array([self._speed_mps], np.float32)}
        for camera in self.cameras:
            if self.images:
                observation[f"image_{camera}"] = loop.rig.render_rgb(loop.data, camera)
            if f"detections_{camera}" in self.observation_space.spaces:
                observation[f"detections_{camera}"] = detections_array(detections[camera], width, height)
        self._observation = observation
        return self._observation_copy()

    @property
    def loop(self) -> ClosedLoop | None:
        """The episode's closed loop (None before the first reset)."""
        return self._loop

    def render(self) -> np.ndarray | None:
        """The front camera's RGB image (H, W, 3) uint8 of the current state (render_mode "rgb_array")."""
        if self.render_mode is None:
            gymnasium.logger.warn("render() was called without a render_mode; make the environment with render_mode='rgb_array'")
            return None
        loop = self._loop if self._loop is not None else self._require_episode()
        image = self._observation.get(f"image_{RENDER_CAMERA}")
        return image.copy() if image is not None else loop.rig.render_rgb(loop.data, RENDER_CAMERA)

    def close(self) -> None:
        """Release the episode's closed loop (its renderers and perception); the environment can be reset again."""
        self._close_loop()

    # ---- one step's parts ----------------------------------------------------------------
    def _controls(self, action: Any) -> Controls:
        """The action as the car's commands: clipped to the action box; steer from the lane keeper
        unless full_control. Actions are read as float64, so a float64 action is applied as given."""
        try:
            values = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError):
            values = np.full(0, np.nan)
        if values.shape != self.action_space.shape or not np.isfinite(values).all():
            names = "(throttle, brake, steer)" if self.full_control else "(throttle, brake)"
            raise ConfigError(f"an action is {self.action_space.shape[0]} finite numbers {names}, got {action!r}")
        values = np.clip(values, self.action_space.low, self.action_space.high)
        loop = self._loop
        if self.full_control:
            steer_rad = float(values[2]) * self._full_lock_rad
        else:
            steer_rad = loop.lane_steer_rad(loop.vehicle.speed_mps())
        return Controls(throttle=float(values[0]), brake=float(values[1]), steer_rad=steer_rad)

    def _observation_copy(self) -> dict[str, np.ndarray]:
        # The caller owns what it is given; `render` reads the kept one.
        return {key: value.copy() for key, value in self._observation.items()}

    def _distances_m(self) -> tuple[float, float]:
        """Front bumper to the stop line and to the sign post, along the road [m]; > 0 before them."""
        loop = self._loop
        bumper_x_m = float(loop.vehicle.front_bumper_xy_m()[0])
        return loop.scene.stop_line_x_m - bumper_x_m, float(loop.scene.stop_sign.base_pos_m[0]) - bumper_x_m

    def _state_info(self) -> dict[str, Any]:
        line_m, sign_m = self._distances_m()
        return {"time_s": self._loop.time_s, "stop_line_dist_m": line_m, "sign_dist_m": sign_m}

    def _require_episode(self) -> ClosedLoop:
        if self._loop is None:
            raise ConfigError("call reset() before step() or render()")
        if self._ended:
            raise ConfigError("the episode has ended (terminated or truncated); call reset() to start another")
        return self._loop

    def _close_loop(self) -> None:
        if self._loop is not None:
            self._loop.close()
            self._loop = None


def _checked_cameras(cameras: Sequence[str]) -> tuple[str, ...]:
    if not isinstance(cameras, (str, Sequence)):
        raise ConfigError(f"cameras must be a camera's name or a list of them ({', '.join(CAMERA_NAMES)}), got {cameras!r}")
    names = (cameras,) if isinstance(cameras, str) else tuple(cameras)
    unknown = [name for name in names if name not in CAMERA_NAMES]
    if not names or unknown or len(set(names)) != len(names):
        raise ConfigError(f"cameras must name each of {', '.join(CAMERA_NAMES)} at most once, and at least one; got {cameras!r}")
    return names
