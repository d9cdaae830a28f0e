"""Typed, frozen configuration.

`SimConfig` groups one dataclass per concern (scenario, vehicle, camera, loop,
perception, policy). Overrides arrive as nested mappings (from the CLI or a TOML
file); `with_overrides` rejects unknown keys and values of the wrong type, naming
the key, so a misspelt override can never be silently ignored. Each dataclass
checks its own value ranges in `__post_init__`.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, TypeVar

from avsim.errors import ConfigError
from avsim.validation import check_ranges, ranged

C = TypeVar("C")
# Values of PerceptionConfig.coco_input (perception/coco/preprocess.py says what each does).
COCO_INPUTS = ("resize", "crop", "upscale")
# The arithmetics a network runs in: float32, or bfloat16 (each network as a bfloat16 copy: the own detector in
# perception/detector/infer.py, the COCO CenterNet in perception/coco/bf16.py, YOLO in perception/yolo/bf16.py).
ARITHMETICS = ("fp32", "bf16")
# Values of PerceptionConfig.detector_precision, coco_precision and yolo_precision: "auto" (bf16 where the
# CPU runs it, else fp32; perception/cpu_bf16.py) or either arithmetic.
PRECISIONS = ("auto",) + ARITHMETICS
# Values of PerceptionConfig.purify (perception/purify.py) and .ensemble_fusion (perception/ensemble.py).
PURIFIERS = ("none", "jpeg", "median")
ENSEMBLE_FUSIONS = ("or", "and", "k_of_n")
# Values of PerceptionConfig.ensemble_members (the FRAME_DETECTORS networks an ensemble may hold).
ENSEMBLE_NETWORKS = ("detector", "coco", "yolo")
# Values of CameraConfig.offsamples and .seg_supersample, and of PerceptionConfig.purify_median_kernel_px.
OFFSAMPLES = (0, 1, 2, 4, 8, 16)
SEG_SUPERSAMPLES = (1, 2, 3, 4)
TEXTURE_ANISOTROPIES = (1, 2, 4, 8, 16)
SUPERSAMPLES = (1, 2, 3, 4)
MEDIAN_KERNELS_PX = (3, 5, 7, 9)
# scenario.sign = NO_SIGN: no stop sign at the junction (a speed-limit sign stands on its post).
NO_SIGN = "none"
# Values of ScenarioConfig.distractors (world/distractors.py) and .map_error (world/hd_map.py).
DISTRACTORS = ("none", "red_signs")
MAP_ERRORS = ("none", "missing_stop", "phantom_stop")
# Values of ScenarioConfig.materials (world/props.py, world/surface_textures.py).
MATERIALS = ("flat", "textured")
# Values of ScenarioConfig.sign_materials (world/sign_materials.py) and .sun_shadow_map_px (world/scene.py; 0: no shadow).
SIGN_MATERIALS = ("flat", "sheeting")
SHADOW_MAP_SIZES_PX = (0, 1024, 2048, 4096, 8192)
# Values of ScenarioConfig.foliage (world/foliage.py), .sky (world/sky.py) and .road_paint (world/surface_textures.py).
FOLIAGES = ("solid", "clusters")
# Values of ScenarioConfig.facade_windows (world/facade_windows.py).
FACADE_WINDOWS = ("texture", "geometry")
SKIES = ("gradient", "daylight")
ROAD_PAINTS = ("fresh", "worn")
# A stop sign turned at most this far from facing the car is for the car; one turned at least
# SIGN_YAW_NOT_OURS_DEG faces the cross street. In between it is ambiguous, and refused.
SIGN_YAW_FACING_DEG = 30.0
SIGN_YAW_NOT_OURS_DEG = 60.0

# perception.oracle_min_box_height_px = f H / d50 with the default front camera (f = 895.7 px), the
# stop sign's H = 0.762 m and d50 = 100.4 m, the distance at which the learned detector's clean
# stop-sign recall on 3000 held-out renders falls below 0.5 (0.775 at 80-100 m, 0.247 at
# 100-120 m): `avsim detector make-data --out data/signs_range --train 0 --val 3000 --max-dist-m 160`,
# then `avsim detector eval --data data/signs_range`.
ORACLE_MIN_BOX_HEIGHT_PX = 6.8


def _require(ok: bool, message: str) -> None:
    if not ok:
        raise ConfigError(message)


# A seed seeds numpy's default_rng, torch.Generator.manual_seed and OpenCV alike: 0 .. 2**32 - 1
# is the range every one of them takes as it is.
MAX_SEED = 2**32 - 1


def check_seed(seed: int, name: str) -> None:
    """A one-line ConfigError unless `seed` is an int in 0 .. MAX_SEED; name: the key or flag, for the message."""
    _require(type(seed) is int and 0 <= seed <= MAX_SEED, f"{name} must be an integer in 0 .. {MAX_SEED} (2**32 - 1), got {seed!r}")


@dataclass(frozen=True)
class ScenarioConfig:
    """Where and how fast the car drives.

    Distances are along the road (world +x); the stop line is at x = 0.
    """

    town: str = "town07"  # the town (world/towns/): rural town07, urban town03, downtown town10
    placement: str = "standard"  # the sign post beyond the lane edge: near 0.5 m, standard 2.0 m, far 5.5 m
    # Name of a texture in textures/ ("clean" is the generated stop sign) or a path to a PNG;
    # "none" (NO_SIGN): no stop sign, a speed-limit sign on its post and no stop line painted.
    sign: str = "clean"
    # The junction's sign turned about its post [deg], positive to the right: 0 faces the car;
    # 60-90 faces the cross street, so the sign is visible but not for this car (no stop required).
    sign_yaw_deg: float = ranged(0.0, -90, 90, unit="deg")
    # Red sign-like props along the approach that are no traffic sign ("red_signs": red and white
    # round and hexagonal adverts of a stop sign's size, world/distractors.py), or "none".
    distractors: str = "none"
    speed_kmh: float = ranged(85.0, 0, 200, lo_open=True, unit="km/h")  # cruise target
    start_speed_kmh: float = ranged(0.0, 0, 200, unit="km/h")  # the study starts from rest and accelerates
    # Front bumper to stop line at t = 0 [m]; the approach road is 300 m long.
    start_dist_m: float = ranged(230.0, 20, 300, unit="m", note="the approach road is 300 m")
    seed: int = ranged(0, 0, MAX_SEED, note="2**32 - 1")  # seeds the start jitter, the sensor noise and the clouds
    # Seeds the town's scenery (building heights, trees, parked cars); fixed per study town.
    layout_seed: int = ranged(0, 0, MAX_SEED, note="2**32 - 1")
    # Seeded jitter of the start position [m]; varies runs of one scenario across seeds.
    start_jitter_m: float = ranged(2.0, 0, 10, unit="m")
    sun_elevation_deg: float = ranged(50.0, 5, 90, unit="deg")  # the sun above the horizon
    sun_azimuth_deg: float = ranged(30.0, -360, 360, unit="deg")  # the sun's bearing about the vertical
    sun_intensity: float = ranged(1.0, 0.1, 2.0)  # scales the sun's diffuse light
    # Linear fog from fog_start_m to fog_end_m [m] of distance; fog_end_m = 0 means clear air.
    fog_start_m: float = ranged(0.0, 0, 10000, unit="m")
    fog_end_m: float = ranged(0.0, 0, 10000, unit="m")
    # Tyre-road friction coefficient (the tyre's peak): dry asphalt 0.9, wet 0.5-0.6, packed
    # snow about 0.2, ice about 0.1. It is the friction of MuJoCo's tyre-road contacts.
    road_friction: float = ranged(0.9, 0.05, 1.5, note="dry 0.9, wet 0.5, snow 0.2")
    # Error of the car's HD map: its stop line lies this far beyond the real one along the road
    # [m] (negative: before it). Only map-reading policies (autopilot, map_prior) are affected.
    map_stop_line_offset_m: float = ranged(0.0, -50, 50, unit="m")
    # The map's failure modes: "missing_stop", the junction's stop is not on the map (needs a
    # stop in the world); "phantom_stop", the map lists a stop the world does not have (needs a
    # junction where no stop is required); "none", the map matches the world.
    map_error: str = "none"
    # Surfaces: "flat", one colour each (the default renders); "textured", procedural texture at
    # the scale a camera resolves (world/surface_textures.py, docs/realism_scene.md).
    materials: str = "flat"
    # Signs: "flat", the faces' design colours on a plain grey plate and post (the default renders);
    # "sheeting", the faces in the standard's sheeting colours on an aluminium blank and a galvanised post
    # (world/sign_materials.py, docs/realism_scene.md).
    sign_materials: str = "flat"
    # The sun's shadows: 0, none (the default renders); else the side of the shadow map [texels].
    sun_shadow_map_px: int = 0
    # Tree crowns: "solid", one opaque ellipsoid each (the default renders); "clusters", leaf clusters
    # filling the same envelope with gaps, at a broadleaf crown's optical porosity (world/foliage.py,
    # docs/realism_foliage.md).
    foliage: str = "solid"
    # Facade windows: "texture", painted into the facade's material (a checker under flat materials, a storey's
    # window under textured ones; the default renders); "geometry", the wall alone with the textured facade's
    # windows built as quads in front of it, sharp at a grazing view where a texture is smeared by its
    # filtering (world/facade_windows.py, docs/realism_filtering.md).
    facade_windows: str = "texture"
    # The sky: "gradient", MuJoCo's built-in light-blue gradient (the default renders); "daylight", a clear
    # sky that follows the sun, from Preetham et al.'s model at sky_turbidity (world/sky.py, docs/realism_sky.md).
    sky: str = "gradient"
    # The atmosphere's turbidity for sky = "daylight": 2 very clear, 3 clear, 6 hazy (Preetham et al. 1999).
    sky_turbidity: float = ranged(3.0, 2, 10)
    # The sky's brightness against the scene, in stops: 0 is the gradient's colours, and the daylight sky at the
    # gradient's mean luminance; +1 doubles the sky's light (more of it clips to white), -1 halves it. The
    # classic renderer has no exposure, so this level is a choice (docs/realism_sky.md measures what it decides).
    sky_exposure_ev: float = ranged(0.0, -3, 3, unit="EV")
    # Fair-weather cumulus over the daylight sky, in oktas (eighths of the sky covered, as weather observers
    # report cover): 0 a clear sky (the default), 3-4 scattered, 5-6 broken. Not 7-8: the scene's sun always
    # shines, which a sky that closed would not let it. A fresh field for each scenario.seed (world/clouds.py).
    cloud_oktas: int = ranged(0, 0, 6, unit="oktas", note="7-8 would hide the sun, which the lighting does not model")
    # The cloud base's height above the road (world/clouds.py): cumulus bases lie a few hundred metres up in
    # humid sea air, 1-2 km over land in summer, 3 km and more over deserts. A lower layer is nearer, so its
    # clouds look larger and less hazy near the horizon, where the sign stands against the sky.
    cloud_base_m: float = ranged(1500.0, 300, 4000, unit="m")
    # The meteorological visibility of the air between the camera and the clouds (Koschmieder's law fades a
    # cloud's contrast over its slant range). It fades the clouds only: the scene is not fogged, and the clear
    # sky keeps scenario.sky_turbidity (hazier air would raise both; here they are set apart).
    cloud_visibility_km: float = ranged(30.0, 5, 150, unit="km")
    # Lane lines, stop line and crosswalk: "fresh", solid paint (the default renders); "worn", paint
    # abraded off the aggregate and flaked, showing the asphalt through it (world/surface_textures.py).
    road_paint: str = "fresh"

    def __post_init__(self) -> None:
        check_ranges(self, "scenario")
        _require(self.materials in MATERIALS, f"scenario.materials must be one of {', '.join(MATERIALS)}, got {self.materials!r}")
        _require(self.sign_materials in SIGN_MATERIALS,
                 f"scenario.sign_materials must be one of {', '.join(SIGN_MATERIALS)}, got {self.sign_materials!r}")
        _require(self.foliage in FOLIAGES, f"scenario.foliage must be one of {', '.join(FOLIAGES)}, got {self.foliage!r}")
        _require(self.facade_windows in FACADE_WINDOWS,
                 f"scenario.facade_windows must be one of {', '.join(FACADE_WINDOWS)}, got {self.facade_windows!r}")
        _require(self.sky in SKIES, f"scenario.sky must be one of {', '.join(SKIES)}, got {self.sky!r}")
        _require(self.cloud_oktas == 0 or self.sky == "daylight",
                 f"scenario.cloud_oktas = {self.cloud_oktas} needs scenario.sky = \"daylight\" (the gradient sky has no clouds); set both")
        _require(self.road_paint in ROAD_PAINTS, f"scenario.road_paint must be one of {', '.join(ROAD_PAINTS)}, got {self.road_paint!r}")
        _require(type(self.sun_shadow_map_px) is int and self.sun_shadow_map_px in SHADOW_MAP_SIZES_PX,
                 f"scenario.sun_shadow_map_px must be one of {', '.join(map(str, SHADOW_MAP_SIZES_PX))} (0: no shadows), "
                 f"got {self.sun_shadow_map_px!r}")
        _require(self.fog_end_m == 0 or 0 <= self.fog_start_m < self.fog_end_m,
                 f"scenario.fog_start_m must be >= 0 and below fog_end_m (or fog_end_m = 0 for no fog), got {self.fog_start_m}, {self.fog_end_m}")
        yaw = abs(self.sign_yaw_deg)
        _require(not SIGN_YAW_FACING_DEG < yaw < SIGN_YAW_NOT_OURS_DEG,
                 f"scenario.sign_yaw_deg must be within {SIGN_YAW_FACING_DEG:g} deg of 0 (a sign for this car) or at least "
                 f"{SIGN_YAW_NOT_OURS_DEG:g} deg (a sign for the cross street); {self.sign_yaw_deg} leaves open whom it is for")
        _require(self.distractors in DISTRACTORS,
                 f"scenario.distractors must be one of {', '.join(DISTRACTORS)}, got {self.distractors!r}")
        _require(self.map_error in MAP_ERRORS, f"scenario.map_error must be one of {', '.join(MAP_ERRORS)}, got {self.map_error!r}")
        _require(self.map_error != "missing_stop" or self.stop_required,
                 "scenario.map_error = missing_stop needs a stop in the world (a stop sign facing the car); "
                 "with no stop required the map has no stop to miss")
        _require(self.map_error != "phantom_stop" or not self.stop_required,
                 "scenario.map_error = phantom_stop needs a junction where no stop is required (scenario.sign = none, "
                 "or scenario.sign_yaw_deg of 60-90); here the world has the stop the map lists")

    @property
    def stop_required(self) -> bool:
        """Whether the junction requires this car to stop: a stop sign stands there and faces it."""
        return self.sign != NO_SIGN and abs(self.sign_yaw_deg) <= SIGN_YAW_FACING_DEG


@dataclass(frozen=True)
class VehicleConfig:
    """Powertrain, brakes, anti-lock control, suspension, tyre and resistances.

    Mass and geometry live in models/car.xml; the road's friction is the scenario's.
    """

    max_drive_torque_nm: float = ranged(900.0, 0, 20000, lo_open=True, unit="N m")  # per driven (rear) wheel
    # Total brake force at brake = 1 as a multiple of the car's weight. At 1.0 a brake command
    # b asks the tyres for b * 9.81 m/s^2, the a_max of the study's b = a / a_max law; on a dry
    # road the tyres give less than that, and the anti-lock controller takes over.
    brake_force_at_full_g: float = ranged(1.0, 0, 3, lo_open=True, unit="g")
    # Share of the brake force on the front axle. Under a 0.9 g stop about two thirds of the
    # car's weight rests on the front wheels, so real cars bias their brakes forward.
    brake_balance_front: float = ranged(0.70, 0, 1)
    # Time for the hydraulics to build from no brake to full brake [s]; release is immediate.
    brake_rise_time_s: float = ranged(0.15, 0, 2, lo_open=True, unit="s")
    # Anti-lock brakes and traction control: each wheel's slip is held near abs_target_slip.
    abs_enabled: bool = True
    traction_control_enabled: bool = True  # limits the drive torque when a rear wheel spins
    abs_target_slip: float = ranged(0.10, 0.02, 0.5)
    # Body bounce: undamped ride frequency [Hz] and damping ratio of each corner's spring.
    suspension_frequency_hz: float = ranged(1.4, 0.5, 4, unit="Hz", note="a sedan rides at 1.2-1.5")
    suspension_damping_ratio: float = ranged(0.45, 0.05, 2)  # of each corner's spring and damper
    # Tyre friction against slip: flat up to the peak slip, then falling linearly to this share
    # of the road's friction for a locked wheel (avsim/vehicle/tyre.py).
    tyre_peak_slip: float = ranged(0.15, 0.02, 0.5)
    tyre_sliding_ratio: float = ranged(0.75, 0.2, 1)  # a locked wheel's share of the road's friction
    rolling_resistance_coeff: float = ranged(0.012, 0, 0.5)  # C_rr, a friction torque at each wheel
    drag_area_m2: float = ranged(0.65, 0, 20, unit="m^2")  # Cd * frontal area of a sedan (0.29 * 2.2 m^2)
    air_density_kgpm3: float = ranged(1.2, 0, 5, unit="kg/m^3")  # for the aerodynamic drag

    def __post_init__(self) -> None:
        check_ranges(self, "vehicle")


@dataclass(frozen=True)
class CameraPreset:
    """A camera's sensor and lens: resolution [px] and vertical field of view [deg] (MuJoCo's fovy)."""

    width_px: int
    height_px: int
    fovy_deg: float  # its intrinsics: sensors.camera.Intrinsics


def vertical_fov_deg(width_px: int, height_px: int, hfov_deg: float) -> float:
    """The vertical field of view [deg] of a square-pixel pinhole camera with horizontal field of view `hfov_deg`."""
    return math.degrees(2 * math.atan(math.tan(math.radians(hfov_deg) / 2) * height_px / width_px))


# The camera presets (camera.preset). "study": the study's 640x480 at a 30 deg vertical field of view
# (39.3 deg horizontal), today's default. "automotive_1080p": a modern automotive front camera, 1920x1080
# (a 2 MP sensor) at a stated 55 deg horizontal field of view, the middle of the 50-60 deg that the main
# (not the wide, not the narrow) front cameras of ADAS units span; f = 1844 px, 2.06x the study's 896 px.
AUTOMOTIVE_HFOV_DEG = 55.0
CAMERA_PRESETS = {
    "study": CameraPreset(640, 480, 30.0),
    "automotive_1080p": CameraPreset(1920, 1080, vertical_fov_deg(1920, 1080, AUTOMOTIVE_HFOV_DEG)),
}


@dataclass(frozen=True)
class CameraConfig:
    """Both cameras share a resolution. fovy is MuJoCo's vertical field of view.

    `preset` names the sensor and lens (CAMERA_PRESETS); width_px, height_px, fovy_deg and
    side_fovy_deg left at 0 take the preset's values, and one set beside the preset overrides it.
    At the default ("study") f_px = 240 / tan(15 deg) = 896 px, so the 0.762 m stop sign is
    17 px tall at 40 m.
    """

    # The sensor and lens (CAMERA_PRESETS): "study" is the study's 640x480 at fovy 30 deg (39.3 deg
    # horizontal, f = 896 px), every existing result's camera; "automotive_1080p" a modern automotive
    # front camera, 1920x1080 at 55 deg horizontal (fovy 32.6 deg, f = 1844 px). The intrinsics, the
    # pinhole range estimate, the regions of interest and the recorders follow it (docs/realism_camera.md).
    preset: str = "study"
    # width_px, height_px, fovy_deg, side_fovy_deg: 0 takes the preset's value (resolved on construction,
    # so a saved config holds the numbers); another value overrides the preset's.
    width_px: int = ranged(0, 0, 4096, unit="px", note="0 = the preset's; else at least 64")
    height_px: int = ranged(0, 0, 4096, unit="px", note="0 = the preset's; else at least 64")
    fovy_deg: float = ranged(0.0, 0, 150, unit="deg", note="0 = the preset's")
    side_fovy_deg: float = ranged(0.0, 0, 150, unit="deg", note="0 = the preset's")
    side_yaw_deg: float = ranged(20.0, -90, 90, unit="deg")  # towards the right-hand roadside
    # Multisampling costs about half the frame rate on llvmpipe; off by default.
    offsamples: int = 0
    # Segmentation is rendered at this multiple of the resolution so that
    # ground-truth boxes have sub-pixel edges (a 60 m sign is only 11 px tall).
    seg_supersample: int = 2
    # The photographic model (sensors/photo.py, docs/realism_camera.md), all off by default:
    # RGB rendered at this multiple of the resolution and area-averaged down, as a photosite
    # integrates the light over its area (anti-aliasing at the sensor).
    supersample: int = 1
    # Texture filtering: 1 is MuJoCo's trilinear mip-mapping, which blurs a texture seen at a grazing angle
    # along both of a pixel's axes by its footprint's long one; N samples the footprint along its long axis
    # up to N:1 (anisotropic filtering), closer to what a photosite integrates on a facade seen edge-on.
    # How is the GL's own: llvmpipe (Mesa 22.3) filters each pixel's whole footprint (an elliptical
    # Gaussian) at any N > 1, the same pixels from 2 to 16, at 50-100x a frame's render time (one Mesa thread).
    texture_anisotropy: int = 1
    # Lens blur: a Gaussian point-spread function with this MTF50 [cycles/px] (0: an ideal lens).
    lens_mtf50_cyc_per_px: float = ranged(0.0, 0, 1.0, unit="cycles/px")
    # The ISP's JPEG encoding at this quality, after the sensor noise (0: frames stay uncompressed).
    jpeg_quality: int = ranged(0, 0, 100)

    # The keys that a preset fills (with_overrides resets those not set beside a new preset).
    PRESET_KEYS: typing.ClassVar[tuple[str, ...]] = ("width_px", "height_px", "fovy_deg", "side_fovy_deg")

    def __post_init__(self) -> None:
        _require(self.preset in CAMERA_PRESETS, f"camera.preset must be one of {', '.join(CAMERA_PRESETS)}, got {self.preset!r}")
        preset = CAMERA_PRESETS[self.preset]
        for key, value in (("width_px", preset.width_px), ("height_px", preset.height_px),
                           ("fovy_deg", preset.fovy_deg), ("side_fovy_deg", preset.fovy_deg)):
            if getattr(self, key) == 0:
                object.__setattr__(self, key, value)
        check_ranges(self, "camera")
        for key in ("width_px", "height_px"):
            _require(getattr(self, key) >= 64, f"camera.{key} must be 0 (the preset's) or an integer in [64, 4096], got {getattr(self, key)}")
        for key in ("fovy_deg", "side_fovy_deg"):
            _require(getattr(self, key) >= 1, f"camera.{key} must be 0 (the preset's) or in [1, 150], got {getattr(self, key)}")
        _require(self.offsamples in OFFSAMPLES, f"camera.offsamples must be 0, 1, 2, 4, 8 or 16, got {self.offsamples}")
        _require(self.seg_supersample in SEG_SUPERSAMPLES, f"camera.seg_supersample must be 1..4, got {self.seg_supersample}")
        _require(self.supersample in SUPERSAMPLES, f"camera.supersample must be 1, 2, 3 or 4, got {self.supersample}")
        _require(self.texture_anisotropy in TEXTURE_ANISOTROPIES,
                 f"camera.texture_anisotropy must be 1, 2, 4, 8 or 16, got {self.texture_anisotropy}")
        _require(self.lens_mtf50_cyc_per_px == 0 or self.lens_mtf50_cyc_per_px >= 0.05,
                 f"camera.lens_mtf50_cyc_per_px must be 0 (an ideal lens) or in [0.05, 1], got {self.lens_mtf50_cyc_per_px}")

    @property
    def f_px(self) -> float:
        """Front camera focal length [px]: (H/2) / tan(fovy/2)."""
        return focal_length_px(self.height_px, self.fovy_deg)


def focal_length_px(height_px: int, fovy_deg: float) -> float:
    """Pinhole focal length [px] for an image `height_px` tall with vertical FOV `fovy_deg`."""
    return (height_px / 2) / math.tan(math.radians(fovy_deg) / 2)


@dataclass(frozen=True)
class LoopConfig:
    """Fixed time steps. Control and sensing run every `control_dt_s`; physics in between."""

    # Below 0.1 ms a control step would be over 1000 physics steps: no car needs it, and a
    # tiny dt (1e-300) would make the step count absurd.
    physics_dt_s: float = ranged(0.002, 1e-4, 0.01, unit="s")
    control_dt_s: float = ranged(0.05, 0, 0.1, lo_open=True, unit="s", note="CARLA warns above 0.1 s")  # 20 Hz, CARLA's synchronous default
    max_time_s: float = ranged(60.0, 0, 600, lo_open=True, unit="s")  # simulated time after which a run ends

    def __post_init__(self) -> None:
        check_ranges(self, "loop")
        ratio = self.control_dt_s / self.physics_dt_s
        _require(abs(ratio - round(ratio)) < 1e-9 and round(ratio) >= 1,
                 f"loop.control_dt_s ({self.control_dt_s}) must be a whole multiple of loop.physics_dt_s ({self.physics_dt_s})")

    @property
    def substeps(self) -> int:
        """Physics steps per control step: control_dt_s / physics_dt_s, rounded (25 at the defaults)."""
        return round(self.control_dt_s / self.physics_dt_s)


@dataclass(frozen=True)
class PerceptionConfig:
    """How signs are perceived.

    `detector` runs the trained sign detector on each rendered RGB frame; `oracle`
    reads ground-truth boxes from segmentation (an explicitly named shortcut); `coco` runs
    the COCO-trained CenterNet of @vladmandic/human (ported to PyTorch, fetched at install);
    `yolo` runs YOLOv3-tiny (COCO, Darknet's files read into PyTorch, fetched at install);
    `onnx` runs a user's YOLOv8/YOLO11-layout ONNX detector with onnxruntime; `none` sees
    nothing (for the autopilot, or a Gymnasium agent without a perception).
    """

    kind: str = "detector"  # the perception (class docstring; perception/factory.py)
    # A sensor-model knob for the learned detector: boxes shorter than this are dropped. The
    # default keeps every box the network reports; where to start acting on a far sign is the
    # policy's decision (policy.trigger_dist_m), not the perception's.
    min_box_height_px: float = ranged(1.0, 1, 4096, unit="px")
    # The oracle's range. A ground-truth box has no range of its own, so the oracle reports a
    # sign only once its box is this tall: calibrated to where the learned detector's clean
    # stop-sign recall on held-out renders falls below 0.5 (docs/architecture.md, "Perception").
    oracle_min_box_height_px: float = ranged(ORACLE_MIN_BOX_HEIGHT_PX, 1, 4096, unit="px")
    # Detector weights file; "" means the shipped models/sign_detector.pt.
    weights_path: str = ""
    # The detector reports every box at least this confident. The policy's own
    # conf_threshold decides braking; lower-scored boxes are kept in the records
    # so a run shows what an attack left of the sign.
    min_confidence: float = ranged(0.1, 0, 1, lo_open=True, hi_open=True)
    # Torch intra-op threads for the detector. Part of the config because oneDNN splits a
    # convolution's sums by thread, so 1 and 2 threads differ in the last bits of a score:
    # a run is bit-identical only at the same count. One thread also lets a pool of
    # worker processes use every core without oversubscribing them.
    threads: int = ranged(1, 1, 64)
    # `detector`: the arithmetic of the own network. "bf16" runs a bfloat16 copy of it, what bfloat16
    # autocast computes, about 1.5x faster than "fp32" here, and lets the lock-step batch share one network
    # call among cars (perception/detector/infer.py); it needs a CPU on which oneDNN runs bf16
    # (AVX-512). "auto" is bf16 on such a CPU and fp32 elsewhere, and a batch's manifest says which.
    # bf16 scores differ from fp32's by bf16 rounding: `python -m avsim.perception.detector.precision_agreement`
    # measures recall per 5-m bin under both, and docs/performance.md what it changes in the closed loop.
    detector_precision: str = "auto"
    # `detector`, under a camera larger than the network's trained input (camera.preset =
    # "automotive_1080p"): also search the region of interest at the camera's own pixels, besides the
    # frame letterboxed down to the input, and merge the two by NMS (perception/detector/infer.py).
    # The letterbox alone shrinks a 1920x1080 frame 3x, so the sharper camera saw less far than the
    # study's (first detection 68 m against 130 m); the native pass finds the far signs, at the cost of a
    # second, larger network pass, and near signs, larger at full resolution than any in the training
    # frames, still come from the letterboxed pass. False: the letterbox alone, as before. No effect at
    # the study's 640x480, where the frame is the input.
    detector_native_pixels: bool = True
    # Gaussian read noise added to every frame the detector sees [8-bit levels, 1 sigma]; the
    # pattern is drawn from scenario.seed, so seeds differ in their noise. The oracle reads
    # segmentation and has none.
    sensor_noise_std: float = ranged(0.0, 0, 50, unit="levels")
    # Regions of interest (x0, y0, x1, y1) [px] of the front and side images: the detector
    # reports only boxes whose network cell centre lies inside, and runs its network on the
    # region plus `detector.roi.CONTEXT_PX` of context instead of the whole frame. Inside the
    # region every score and box equals the whole-frame network's, bit for bit (the context
    # covers the receptive field); non-maximum suppression then runs among the region's boxes.
    # [] (the default) is the camera's deployed region (avsim/sensors/regions.py), an angular region
    # that follows camera.preset: every stop sign of the study's towns and placements stands right
    # of the road and above the camera, so the front region spans from 2.0 deg left of the optical
    # axis to the frame's right edge, and both regions from the frame's top to 1.0 deg below the
    # horizon (the car's nose dive under braking only lifts the signs). In the study camera's
    # 640x480 pixels that is [288, 0, 640, 256] (front) and [0, 0, 640, 256] (side). A set region is
    # in the camera's pixels ([0, 0, width, height] is the whole frame) and is clipped to the image.
    front_roi_px: tuple[int, ...] = ()
    side_roi_px: tuple[int, ...] = ()  # the side camera's region, as front_roi_px
    # `coco`: how a frame becomes the network's input. "resize": the whole frame squeezed to
    # 512x512, exactly as @vladmandic/human feeds the graph; "crop": the region of interest at
    # the camera's resolution; "upscale": that region enlarged by coco_upscale. Boxes are
    # reported only when centred in the region, in every mode (see perception/coco/preprocess).
    # Upscale is the default because it finds the most stop signs: front-camera recall at 0.5
    # over 10-45 m on 3000 make-data frames was 0.56 (upscale x2) against 0.33 (resize) and
    # 0.20 (crop) (`python -m avsim.perception.coco.realism`). It is also the slowest.
    coco_input: str = "upscale"
    coco_upscale: float = ranged(2.0, 1, 4)
    # `coco`: the arithmetic of the network. "fp32" is the port checked against TF.js; "bf16"
    # runs a bfloat16 copy (perception/coco/bf16.py), faster (`avsim bench` times both), whose
    # scores differ from fp32's by bf16 rounding: on 3000 make-data frames its stop-sign recall
    # in every 5-m bin of both cameras and its rate of false stop signs in every town lay inside
    # fp32's Wilson 95% intervals (27 of 27); over 3985 stop-sign detections paired with their
    # fp32 twins the score moved by 0.0066 (median), 0.144 at most
    # (`python -m avsim.perception.coco.realism --precisions fp32,bf16`). "bf16" needs a CPU on
    # which oneDNN runs bf16 (AVX-512); "auto" is bf16 on such a CPU and fp32 elsewhere, as for the
    # own detector, and a batch's manifest says which.
    coco_precision: str = "auto"
    # `onnx`: a YOLOv8/YOLO11-style ONNX detector (output [1, 4 + C, N]: cx, cy, w, h, C class
    # scores) and its class names, index = class id; "stop_sign" is the class the policies act on.
    onnx_path: str = ""
    onnx_classes: tuple[str, ...] = ()  # its class names, index = class id
    # `yolo`: YOLOv3-tiny (COCO-80, Darknet's files, perception/yolo/), or a user's own Darknet
    # YOLOv3/v4-tiny style files: yolo_cfg + yolo_weights (both or neither; "" = the fetched
    # YOLOv3-tiny) and yolo_names (its class names, one a line; "" = the fetched coco.names).
    # yolo_input as coco_input, but "resize" squeezes the whole frame to the cfg's [net] size
    # (416x416), as OpenCV's blobFromImage feeds Darknet models; "upscale" enlarges the region of
    # interest by yolo_upscale. "bf16" runs a bfloat16 copy (perception/yolo/bf16.py); agreement
    # with fp32, measured, is in docs/yolo.md.
    yolo_cfg: str = ""
    yolo_weights: str = ""
    yolo_names: str = ""
    yolo_input: str = "upscale"
    yolo_upscale: float = ranged(2.0, 1, 4)
    yolo_precision: str = "fp32"  # "bf16": a bfloat16 copy (perception/yolo/bf16.py); "auto" as coco_precision
    # Input purification before the network (a defence, perception/purify.py): "jpeg" re-compresses
    # each frame at purify_jpeg_quality, "median" median-blurs it with a purify_median_kernel_px
    # square kernel; "none" leaves it as rendered. Any pixel perception; not the oracle.
    purify: str = "none"
    purify_jpeg_quality: int = ranged(75, 1, 100)
    purify_median_kernel_px: int = 3
    # `ensemble` (the own detector and the COCO CenterNet on the same frame, perception/ensemble.py):
    # "or" reports every detection of either network; "and" reports a stop sign only where both
    # networks report one (boxes whose centres lie inside each other), at the lower confidence.
    ensemble_fusion: str = "or"
    # `ensemble`: its member networks, the first giving fused boxes (any of ENSEMBLE_NETWORKS, each
    # once, at least two), and for "k_of_n" fusion how many must report a stop sign on one object.
    ensemble_members: tuple[str, ...] = ("detector", "coco")
    ensemble_k: int = ranged(2, 1, 3)  # with ensemble_fusion = "k_of_n": how many members must agree

    def __post_init__(self) -> None:
        check_ranges(self, "perception")
        for key in ("front_roi_px", "side_roi_px"):
            if getattr(self, key) == ():
                continue  # the camera's deployed region
            _require(len(getattr(self, key)) == 4, f"perception.{key} must be [] (the camera's deployed region) or "
                     f"[x0, y0, x1, y1] [px], got {list(getattr(self, key))}")
            x0, y0, x1, y1 = getattr(self, key)
            _require(0 <= x0 < x1 and 0 <= y0 < y1,
                     f"perception.{key} must be [x0, y0, x1, y1] with 0 <= x0 < x1 and 0 <= y0 < y1 [px], got {list(getattr(self, key))}")
        for key in ("detector_precision", "coco_precision", "yolo_precision"):
            _require(getattr(self, key) in PRECISIONS,
                     f"perception.{key} must be one of {', '.join(PRECISIONS)}, got {getattr(self, key)!r}")
        _require(self.coco_input in COCO_INPUTS,
                 f"perception.coco_input must be one of {', '.join(COCO_INPUTS)}, got {self.coco_input!r}")
        _require(self.yolo_input in COCO_INPUTS,
                 f"perception.yolo_input must be one of {', '.join(COCO_INPUTS)}, got {self.yolo_input!r}")
        _require(bool(self.yolo_cfg) == bool(self.yolo_weights),
                 "perception.yolo_cfg and perception.yolo_weights go together: give both (your own Darknet files) or "
                 "neither (the fetched YOLOv3-tiny)")
        _require(all(name.strip() for name in self.onnx_classes),
                 f"perception.onnx_classes must be non-empty names, got {list(self.onnx_classes)}")
        _require(self.purify in PURIFIERS, f"perception.purify must be one of {', '.join(PURIFIERS)}, got {self.purify!r}")
        _require(self.kind != "oracle" or self.purify == "none",
                 "perception.purify works on pixels, and the oracle reads ground truth from the scene; choose a pixel "
                 "perception (detector, coco, yolo, ensemble, onnx) or perception.purify = none")
        _require(self.purify_median_kernel_px in MEDIAN_KERNELS_PX,
                 f"perception.purify_median_kernel_px must be 3, 5, 7 or 9 (an odd square kernel), got {self.purify_median_kernel_px}")
        _require(self.ensemble_fusion in ENSEMBLE_FUSIONS,
                 f"perception.ensemble_fusion must be one of {', '.join(ENSEMBLE_FUSIONS)}, got {self.ensemble_fusion!r}")
        _require(len(self.ensemble_members) >= 2 and len(set(self.ensemble_members)) == len(self.ensemble_members)
                 and set(self.ensemble_members) <= set(ENSEMBLE_NETWORKS),
                 f"perception.ensemble_members must be two or more of {', '.join(ENSEMBLE_NETWORKS)}, each once, got "
                 f"{list(self.ensemble_members)}")
        _require(1 <= self.ensemble_k <= len(self.ensemble_members),
                 f"perception.ensemble_k must be in [1, {len(self.ensemble_members)}] (the number of ensemble_members), "
                 f"got {self.ensemble_k}")
        _require(self.kind != "onnx" or (self.onnx_path and self.onnx_classes),
                 "perception kind 'onnx' needs perception.onnx_path (the .onnx file) and perception.onnx_classes "
                 "(its class names, index = class id, e.g. ['stop_sign', 'yield'])")


@dataclass(frozen=True)
class PolicyConfig:
    """Braking policy and its parameters (see avsim/control/policies.py)."""

    name: str = "baseline"  # the braking policy (control/policies.py and its neighbours)
    conf_threshold: float = ranged(0.5, 0, 1, lo_open=True, hi_open=True)  # a detection counts above this confidence
    # The braking gate: a perceiving policy acts on a stop sign only once its pinhole estimate of
    # the distance to the stop line is at most this [m]; 40 m is the study stack's gate. None (in
    # TOML `inf`, on the command line `none`) is no gate. The autopilot reads the map, not a gate.
    trigger_dist_m: float | None = ranged(40.0, 0, 1000, lo_open=True, unit="m", note="or none for no gate")
    baseline_brake: float = ranged(0.85, 0, 1, lo_open=True)  # constant brake level of the `baseline` rule
    brake_multiplier: float = ranged(1.0, 0.6, 1.0)  # M in b = min(a / a_max * M, 1)
    a_max_mps2: float = ranged(9.81, 1, 20, unit="m/s^2")  # a_max in `adjusted`'s b = min(a / a_max * M, 1)
    sign_height_m: float = ranged(0.762, 0.1, 3, unit="m")  # H_real of the stop sign, flat to flat
    # The sign height the study's stack assumes in its pinhole estimate (`study_stack` only).
    study_sign_height_m: float = ranged(1.0, 0.1, 3, unit="m")
    # The road convention the policies assume: the stop line is this far before the sign.
    stop_line_before_sign_m: float = ranged(1.0, 0, 20, unit="m")
    # Distance the `adjusted` policy aims to stop short of the line. Its distance comes
    # from a box height, and 1 px of box error at 15 m is about 0.4 m of range, so it
    # keeps 2 m in hand; with 0.5 m a detected (not oracle) box ran 0.4 m past the sign.
    stop_margin_m: float = ranged(2.0, 0, 10, unit="m")
    # The autopilot knows the line from the map and aims this far short of it.
    autopilot_stop_margin_m: float = ranged(0.5, 0, 10, unit="m")
    # The autopilot starts braking when stopping at the line needs this share of the car's
    # full-brake deceleration, measured at the run's road friction (avsim.vehicle.brake_test),
    # and maps a deceleration to a brake level with that measured figure.
    autopilot_decel_fraction: float = ranged(0.7, 0.1, 1)
    # `temporal_vote`: brake once a stop sign, tracked with the car's odometry, has been seen in
    # vote_k of the last vote_n frames at vote_conf_threshold or above (a lower per-frame threshold
    # than conf_threshold). Its pinhole range must shrink as the car advances: fitted over the
    # votes, range lost per metre driven within 1 +- vote_range_rate_tol, once the votes span at
    # least vote_min_travel_m of driving.
    vote_conf_threshold: float = ranged(0.3, 0, 1, lo_open=True, hi_open=True)
    vote_k: int = ranged(3, 1, 100)
    vote_n: int = ranged(5, 1, 100)
    vote_range_rate_tol: float = ranged(0.5, 0, 1, lo_open=True)
    vote_min_travel_m: float = ranged(1.0, 0, 50, unit="m")

    def __post_init__(self) -> None:
        check_ranges(self, "policy")
        _require(self.vote_k <= self.vote_n,
                 f"policy.vote_k and policy.vote_n must satisfy 1 <= vote_k <= vote_n <= 100, got {self.vote_k} and {self.vote_n}")


@dataclass(frozen=True)
class SimConfig:
    """Everything that determines a run. Same config, same result, bit for bit."""

    scenario: ScenarioConfig = field(default_factory=ScenarioConfig)
    vehicle: VehicleConfig = field(default_factory=VehicleConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    loop: LoopConfig = field(default_factory=LoopConfig)
    perception: PerceptionConfig = field(default_factory=PerceptionConfig)
    policy: PolicyConfig = field(default_factory=PolicyConfig)

    def to_dict(self) -> dict[str, Any]:
        """The whole config as nested plain dicts (section -> key -> value), as saved beside every result."""
        return dataclasses.asdict(self)


def with_overrides(config: C, overrides: Mapping[str, Any], _path: str = "") -> C:
    """Return a copy of the dataclass `config` with nested `overrides` applied.

    Raises ConfigError naming the dotted key for unknown keys and mistyped values.
    """
    if not isinstance(overrides, Mapping):
        raise ConfigError(f"config section '{_path.rstrip('.') or 'root'}' must be a table of keys, got {overrides!r}")
    fields = {f.name: f for f in dataclasses.fields(config)}  # type: ignore[arg-type]
    hints = typing.get_type_hints(type(config))
    changes: dict[str, Any] = {}
    for key, value in overrides.items():
        dotted = f"{_path}{key}"
        if key not in fields:
            raise ConfigError(f"unknown config key '{dotted}'; valid keys here: {', '.join(sorted(fields))}")
        current = getattr(config, key)
        if dataclasses.is_dataclass(current):
            changes[key] = with_overrides(current, value, f"{dotted}.")
        else:
            changes[key] = _coerce(value, hints[key], dotted)
    if "preset" in overrides:  # a new preset fills the keys not set beside it (CameraConfig.PRESET_KEYS)
        for key in getattr(config, "PRESET_KEYS", ()):
            changes.setdefault(key, type(getattr(config, key))(0))
    return dataclasses.replace(config, **changes)  # type: ignore[type-var]


def _coerce(value: Any, annotation: Any, dotted: str) -> Any:
    """Check `value` against a scalar field type; ints are accepted for floats."""
    expected = [a for a in typing.get_args(annotation)] if isinstance(annotation, types.UnionType) else [annotation]
    # An optional field's None is written `none` on the command line or `inf` in TOML (which has
    # no null), e.g. policy.trigger_dist_m = none: no gate.
    if type(None) in expected and (value is None or value == "none" or value == math.inf):
        return None
    for kind in expected:
        if kind is float and isinstance(value, (int, float)) and not isinstance(value, bool):
            if not math.isfinite(value):
                raise ConfigError(f"config key '{dotted}' must be a finite number, got {value!r}")
            return float(value)
        if kind in (int, str, bool) and type(value) is kind:
            return value
        item_kinds = typing.get_args(kind)
        if len(item_kinds) == 2 and item_kinds[1] is Ellipsis:  # tuple[str, ...]: any length, one item type
            if isinstance(value, (list, tuple)) and all(type(v) is item_kinds[0] for v in value):
                return tuple(value)
            continue
        if (typing.get_origin(kind) is tuple and isinstance(value, (list, tuple)) and len(value) == len(item_kinds)
                and all(type(v) is k for v, k in zip(value, item_kinds))):
            return tuple(value)
    names = " or ".join(type_name(k) for k in expected)
    raise ConfigError(f"config key '{dotted}' must be {names}, got {value!r}")


def type_name(kind: Any) -> str:
    """'float', or 'a list of 4 ints' for tuple[int, int, int, int]."""
    if typing.get_origin(kind) is tuple:
        items = typing.get_args(kind)
        if len(items) == 2 and items[1] is Ellipsis:
            return f"a list of {items[0].__name__}s"
        return f"a list of {len(items)} {items[0].__name__}s"
    return getattr(kind, "__name__", str(kind))
