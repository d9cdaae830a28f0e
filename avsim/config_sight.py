"""What a run draws, and so which `scenario`, `camera` and `vehicle` keys it reads (`avsim.config_owners`).

A closed-loop run renders only for its perception and its recorders (`avsim.loop`,
`avsim.runner`): the perception sees through the cameras its policy uses (`BrakingPolicy.cameras`;
the autopilot uses none, so its perception never runs; a Gymnasium agent names its own), in colour
for a pixel perception, as segmentation for the oracle, not at all for `none`; a recorder
(`--rrd`, `--mp4`, `--mcap`) draws the front camera and the policy's in colour. A key that only
changes a picture no one draws changes nothing: nothing touches the car but its four tyre-road
contact pairs (`avsim.vehicle.assembly`), so scenery, signs, light and fog never reach the physics.

`scenario.sign` is read by every run when it is `none` (no stop sign), but a texture only where
colour is drawn (the texture is the one thing it changes).

Some keys are read only under a value of another: `scenario.fog_start_m` only in fog
(`fog_end_m` > 0), `scenario.seed` only where it seeds something (a start jitter, or a pixel
perception's sensor noise), `vehicle.abs_target_slip` only with the anti-lock brakes or the
traction control on (both hold each wheel's slip near it).

`RUN_CONDITIONS` maps each such key to the `Condition` under which a run reads it; every other
`scenario`, `vehicle`, `camera` and `loop` key is read by every run.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from avsim.config import NO_SIGN, SimConfig
from avsim.control.policies import POLICIES
from avsim.perception.factory import FRAME_DETECTORS

RECORDERS = "a recorder (avsim run --rrd, --mp4, --mcap; a batch's --rrd, --mcap)"


@dataclass(frozen=True)
class Sight:
    """What one run draws.

    policy, kind: the run's policy and perception names; cameras: the cameras the perception is
    run on (the policy's, or a Gymnasium agent's: then `agent`); recorded: whether a recorder draws
    the run (the front camera and the policy's, in colour).
    """

    policy: str
    kind: str
    cameras: tuple[str, ...]
    recorded: bool
    agent: bool = False

    @classmethod
    def of(cls, config: SimConfig, *, recorded: bool = True, cameras: tuple[str, ...] | None = None) -> Sight:
        """The sight of the run of `config`; cameras: those an agent names, None for those its policy uses."""
        if cameras is None:
            return cls(config.policy.name, config.perception.kind, POLICIES.get(config.policy.name).cameras, recorded)
        return cls(config.policy.name, config.perception.kind, tuple(cameras), recorded, agent=True)

    @property
    def perceives(self) -> bool:
        """Whether the perception draws anything: it runs on a camera and is not `none`."""
        return bool(self.cameras) and self.kind != "none"

    @property
    def drawn_cameras(self) -> frozenset[str]:
        """The cameras drawn in some modality, by the perception or a recorder."""
        recorded = ("front", *POLICIES.get(self.policy).cameras) if self.recorded else ()
        return frozenset((self.cameras if self.perceives else ()) + recorded)

    @property
    def colour(self) -> bool:
        """Whether a colour image is drawn: by a pixel perception, or a recorder."""
        return (self.perceives and self.kind in FRAME_DETECTORS) or self.recorded

    @property
    def segmentation(self) -> bool:
        """Whether a segmentation image is drawn: by the oracle (its ground-truth boxes)."""
        return self.perceives and self.kind == "oracle"

    def nothing_drawn(self) -> str:
        """Why this run draws no picture, in words ("policy is autopilot, which uses no camera, ...")."""
        if not self.cameras:
            return f"policy is {self.policy}, which uses no camera, and nothing records it"
        return f"perception is {self.kind}, which draws no picture, and nothing records it"


@dataclass(frozen=True)
class Condition:
    """When a run reads a key: `holds(config, sight)`; `readers`, who does, in words; `unmet(config,
    sight)`, what this run has instead ("policy is baseline, which does not use the side camera");
    `fix`, how to make a run read it."""

    holds: Callable[[SimConfig, Sight], bool]
    readers: str
    unmet: Callable[[SimConfig, Sight], str]
    fix: str


def _side_cameras() -> list[str]:
    return [name for name in POLICIES.names() if "side" in POLICIES.get(name).cameras]


def _side_unmet(config: SimConfig, sight: Sight) -> str:
    if "side" not in POLICIES.get(sight.policy).cameras and "side" not in sight.cameras:
        return f"policy is {sight.policy}, which does not use the side camera"
    return sight.nothing_drawn()


def _colour_unmet(config: SimConfig, sight: Sight) -> str:
    if sight.perceives:
        return f"perception is {sight.kind}, which draws no colour image (it reads segmentation), and nothing records it"
    return sight.nothing_drawn()


def _fog_start_unmet(config: SimConfig, sight: Sight) -> str:
    return _colour_unmet(config, sight) if not sight.colour else "scenario.fog_end_m is 0 (clear air: no fog is drawn)"


def _daylight_sky_unmet(config: SimConfig, sight: Sight) -> str:
    return _colour_unmet(config, sight) if not sight.colour else f"scenario.sky is {config.scenario.sky} (no daylight sky is drawn)"


def _clouds_unmet(config: SimConfig, sight: Sight) -> str:
    if not sight.colour or config.scenario.sky != "daylight":
        return _daylight_sky_unmet(config, sight)
    return "scenario.cloud_oktas is 0 (a clear sky: no clouds are drawn)"


_PIXEL_PERCEPTIONS = ", ".join(FRAME_DETECTORS.names())
PICTURE = Condition(
    lambda config, sight: bool(sight.drawn_cameras),
    f"a run that draws a picture: a perception other than none through its policy's camera, or {RECORDERS}",
    lambda config, sight: sight.nothing_drawn(),
    "choose a policy that uses a camera and a perception that sees, or record the run")
COLOUR = Condition(
    lambda config, sight: sight.colour,
    f"a run that draws colour images: a pixel perception ({_PIXEL_PERCEPTIONS}) through its policy's camera, or {RECORDERS}",
    _colour_unmet, "choose a pixel perception and a policy that uses a camera, or record the run")
SEGMENTATION = Condition(
    lambda config, sight: sight.segmentation,
    "the oracle perception through its policy's camera (it alone draws segmentation)",
    lambda config, sight: sight.nothing_drawn() if not sight.perceives else f"perception is {sight.kind}",
    "choose perception.kind = oracle")
SIDE_CAMERA = Condition(
    lambda config, sight: "side" in sight.drawn_cameras,
    f"a run that draws the side camera: a policy that uses it ({', '.join(_side_cameras())}) with a perception other "
    f"than none or a recorder",
    _side_unmet, f"choose a policy that uses the side camera ({', '.join(_side_cameras())})")
FOG_START = Condition(
    lambda config, sight: sight.colour and config.scenario.fog_end_m > 0,
    "a run in fog (scenario.fog_end_m > 0) that draws colour images (see scenario.fog_end_m)",
    _fog_start_unmet, "set scenario.fog_end_m beyond it, in a run that draws colour images")
DAYLIGHT_SKY = Condition(
    lambda config, sight: sight.colour and config.scenario.sky == "daylight",
    "a run under the daylight sky (scenario.sky = daylight) that draws colour images",
    _daylight_sky_unmet, "set scenario.sky = daylight, in a run that draws colour images")
CLOUDS = Condition(
    lambda config, sight: sight.colour and config.scenario.sky == "daylight" and config.scenario.cloud_oktas > 0,
    "a run under clouds (scenario.cloud_oktas > 0 with scenario.sky = daylight) that draws colour images",
    _clouds_unmet, "set scenario.cloud_oktas above 0 and scenario.sky = daylight, in a run that draws colour images")
SEEDED = Condition(
    lambda config, sight: config.scenario.start_jitter_m > 0 or (
        sight.perceives and sight.kind in FRAME_DETECTORS and config.perception.sensor_noise_std > 0) or (
        sight.colour and config.scenario.sky == "daylight" and config.scenario.cloud_oktas > 0),
    "the start jitter (scenario.start_jitter_m > 0), a pixel perception's sensor noise (perception.sensor_noise_std > 0) "
    "and the clouds of a daylight sky drawn in colour (scenario.cloud_oktas > 0)",
    lambda config, sight: "scenario.start_jitter_m is 0, it draws no sensor noise and no clouds",
    "set scenario.start_jitter_m or a pixel perception's perception.sensor_noise_std above 0")
SIGN_TEXTURE = Condition(
    lambda config, sight: sight.colour or config.scenario.sign == NO_SIGN,
    f"every run for {NO_SIGN} (no stop sign: segmentation and the map see that); a texture, which changes only the "
    f"sign's colour pixels, only a run that draws colour images: a pixel perception ({_PIXEL_PERCEPTIONS}) through "
    f"its policy's camera, or {RECORDERS}",
    _colour_unmet, "choose a pixel perception and a policy that uses a camera, or record the run")
SLIP_CONTROL = Condition(
    lambda config, sight: config.vehicle.abs_enabled or config.vehicle.traction_control_enabled,
    "the anti-lock brakes (vehicle.abs_enabled) and the traction control (vehicle.traction_control_enabled)",
    lambda config, sight: "vehicle.abs_enabled and vehicle.traction_control_enabled are both false",
    "set vehicle.abs_enabled or vehicle.traction_control_enabled = true")

# Keys read only under a condition: dotted key -> its Condition. The picture keys shape every
# image (its size, lens, multisampling and what stands in the scene: distractors, scenery);
# the colour keys change only colour pixels (segmentation draws flat ids, without light or fog).
RUN_CONDITIONS: dict[str, Condition] = {
    **dict.fromkeys(("camera.preset", "camera.width_px", "camera.height_px", "camera.fovy_deg", "camera.offsamples",
                     "scenario.distractors", "scenario.layout_seed", "scenario.sign_materials",
                     "scenario.foliage", "scenario.facade_windows"), PICTURE),
    **dict.fromkeys(("camera.supersample", "camera.texture_anisotropy", "camera.lens_mtf50_cyc_per_px", "camera.jpeg_quality", "scenario.sun_elevation_deg",
                     "scenario.sun_azimuth_deg", "scenario.sun_intensity", "scenario.fog_end_m", "scenario.materials",
                     "scenario.sun_shadow_map_px", "scenario.sky", "scenario.road_paint", "scenario.sky_exposure_ev"), COLOUR),
    "scenario.fog_start_m": FOG_START,
    "scenario.sky_turbidity": DAYLIGHT_SKY,
    "scenario.cloud_oktas": DAYLIGHT_SKY,
    "scenario.cloud_base_m": CLOUDS,
    "scenario.cloud_visibility_km": CLOUDS,
    # A texture over another (alpha dropped, the same square face) changes only colour pixels; over
    # `none` it puts a stop sign where there was none, read by every run: `avsim run --config`
    # leaves scenario.sign out of its check where the cell has none (`avsim.cli.run`).
    "scenario.sign": SIGN_TEXTURE,
    "scenario.seed": SEEDED,
    "camera.seg_supersample": SEGMENTATION,
    "camera.side_fovy_deg": SIDE_CAMERA,
    "camera.side_yaw_deg": SIDE_CAMERA,
    "vehicle.abs_target_slip": SLIP_CONTROL,
}
