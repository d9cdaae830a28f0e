"""Compose a town, its stop sign and the car into one compiled MuJoCo model.

The scene is fixed by (town, placement, layout seed, sign texture, camera and
vehicle config); the car's start pose is set later, on MjData, by the loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

from avsim.config import NO_SIGN, CameraConfig, SimConfig, VehicleConfig
from avsim.errors import ConfigError
from avsim.vehicle.assembly import CAR_PREFIX, add_tyre_contacts, load_car
from avsim.world import facade_windows, foliage, props, sky
from avsim.world.distractors import add_red_signs
from avsim.world.road import STOP_LINE_X_M, RoadLayout, add_road
from avsim.world import sign_materials
from avsim.world.signs import SIGN_SHAPES, PlacedSign, add_sign
from avsim.world.textures import CLEAN_TEXTURE_FILES, TEXTURE_DIR, load_texture_png
from avsim.world.towns import PLACEMENTS, TOWNS
from avsim.world.towns.base import SIGN_BOTTOM_M

STOP_SIGN_NAME = "stop_sign"
# The sign stands just past the stop line, as at a US junction.
SIGN_BEYOND_STOP_LINE_M = 1.0
# What stands on the junction's sign post when there is no stop sign (scenario.sign = "none").
NO_STOP_SIGN_KIND = "speed_limit"
# Depth range of the cameras [m]: near enough for the hood, far enough for the sky.
ZNEAR_M, ZFAR_M = 0.2, 1500.0
# MuJoCo scales znear/zfar/fog by the model extent; fixing it keeps them in metres / 100.
EXTENT_M = 100.0
# Sun shadows (scenario.sun_shadow_map_px > 0). MuJoCo draws a directional light's shadow map as an
# orthographic view along the light, +-shadowclip * extent square about the light's axis, which passes
# through the light's position. The sun follows the car (track mode: a fixed offset in the world frame)
# with its axis through a point SUN_SHADOW_AIM_AHEAD_M ahead of the car's origin, so the map covers the
# road ahead, where the cameras look (the realism frames are 10-60 m from the sign). It stands
# SUN_SHADOW_DISTANCE_M back along the sun's direction, above everything that can cast a shadow there.
SUN_SHADOW_HALF_WIDTH_M = 60.0
SUN_SHADOW_AIM_AHEAD_M = 50.0
SUN_SHADOW_DISTANCE_M = 300.0
# Tessellation of MuJoCo's curved geoms (tree crowns and trunks, posts, wheels): slices around, stacks
# from pole to pole, against MuJoCo's default 28 and 16. Software rasterisers are vertex-bound on our
# scenes, and these coarser ones save about a third of a frame. A crown is then a 12-sided outline;
# drawing it smooth did not change the COCO networks' false stop signs on it (docs/realism_foliage.md,
# "Not the crowns' facets").
CURVE_SLICES, CURVE_STACKS = 12, 6


@dataclass(frozen=True)
class SceneInfo:
    """Facts about a built scene that the loop, policies and metrics need (world frame, m).

    stop_sign: the sign on the junction's post, just past the stop line. A stop sign facing
    the car in every scenario that requires a stop; where none is required (`stop_required`
    false) it is whatever stands there instead: a speed-limit sign (scenario.sign = "none") or
    a stop sign turned to the cross street. Distances "to the sign" are to this post either way.
    stop_line_x_m: where the stop line is, or would be where none is painted.
    """

    town: str
    placement: str
    layout: RoadLayout
    stop_sign: PlacedSign
    signs: tuple[PlacedSign, ...]
    stop_line_x_m: float = STOP_LINE_X_M
    stop_required: bool = True


def resolve_sign_texture(sign: str) -> Path:
    """Path of the stop-sign texture named by `--sign`: 'clean', a name in textures/, or a path."""
    if sign == "clean":
        return TEXTURE_DIR / CLEAN_TEXTURE_FILES["stop_sign"]
    named = TEXTURE_DIR / f"{sign}.png"
    if "/" not in sign and not sign.endswith(".png"):
        if not named.is_file():
            available = sorted(p.stem for p in TEXTURE_DIR.glob("*.png"))
            raise ConfigError(f"unknown sign texture '{sign}'; use 'clean', a PNG path, or one of: {', '.join(available)}")
        return named
    return Path(sign)


def build_scene(config: SimConfig) -> tuple[mujoco.MjModel, SceneInfo]:
    """Build and compile the scene for `config`. Returns the model and its `SceneInfo`."""
    spec, info = compose_scene(config)
    return spec.compile(), info


def compose_scene(config: SimConfig, target_kind: str = "stop_sign",
                  add_extras: Callable[[mujoco.MjSpec, SceneInfo], None] | None = None) -> tuple[mujoco.MjSpec, SceneInfo]:
    """The uncompiled scene for `config`.

    target_kind: the sign at the stop line. It is a stop sign in every driving scenario (a
    speed-limit sign with scenario.sign = "none"); detector training data puts other kinds there
    too (a clean texture of that kind).
    add_extras: called before the car is attached, to add props (e.g. distractors).

    A junction that requires no stop of this car (`ScenarioConfig.stop_required` false: no stop
    sign, or one turned to the cross street) has no stop line painted on the approach: a stop
    line marks where a stop sign or signal requires a stop (MUTCD 3B.16), and a line with no
    sign would be a road that contradicts itself.
    """
    scenario = config.scenario
    town = TOWNS.get(scenario.town)
    lateral_offset_m = PLACEMENTS.get(scenario.placement)
    if target_kind == "stop_sign" and scenario.sign == NO_SIGN:
        target_kind = NO_STOP_SIGN_KIND
    sheeting = scenario.sign_materials == "sheeting"
    if target_kind == "stop_sign" and scenario.sign != "clean":
        # A user's texture is the printed face under test: its pixels are its colours, whatever the sheeting.
        target_texture = load_texture_png(resolve_sign_texture(scenario.sign), expected_aspect=1.0)
    else:
        target_texture = _clean_texture(target_kind, sheeting)

    spec = mujoco.MjSpec()
    spec.modelname = f"avsim_{town.name}_{scenario.placement}"
    _set_options(spec, config)
    sky.add_sky(spec, scenario)
    window_geometry = scenario.facade_windows == "geometry"
    props.add_materials(spec, textured=scenario.materials == "textured", worn_paint=scenario.road_paint == "worn",
                        window_geometry=window_geometry)
    if sheeting:
        sign_materials.add_metal_materials(spec)
    props.add_ground(spec, town.ground_material)
    shadows = scenario.sun_shadow_map_px > 0
    if not shadows:
        _add_sun(spec.worldbody, scenario.sun_elevation_deg, scenario.sun_azimuth_deg, scenario.sun_intensity)
    add_road(spec, town.layout, stop_line=scenario.stop_required)
    rng = np.random.default_rng(scenario.layout_seed)
    extra_signs = town.build_scenery(spec, town.layout, rng)
    if scenario.foliage == "clusters":
        foliage.replace_crowns_with_clusters(spec, scenario.layout_seed)
    if window_geometry:
        facade_windows.add_window_geometry(spec, props.FACADE_COLOURS)
    if scenario.distractors == "red_signs":
        add_red_signs(spec, town.layout)

    target = PlacedSign(
        STOP_SIGN_NAME if target_kind == "stop_sign" else f"target_{target_kind}", target_kind,
        (STOP_LINE_X_M + SIGN_BEYOND_STOP_LINE_M, town.layout.lane_edge_y_m - lateral_offset_m, 0.0),
        # Positive sign_yaw_deg turns the face towards the car's right (-y), to the cross street.
        math.radians(scenario.sign_yaw_deg), SIGN_BOTTOM_M,
    )
    add_sign(spec, target, target_texture, metal=sheeting)
    for sign in extra_signs:
        add_sign(spec, sign, _clean_texture(sign.kind, sheeting), metal=sheeting)
    info = SceneInfo(town.name, scenario.placement, town.layout, target, (target, *extra_signs),
                     stop_required=scenario.stop_required)
    if add_extras is not None:
        add_extras(spec, info)
    _attach_car(spec, config.vehicle, config.camera)
    if shadows:
        _add_sun(spec.body(f"{CAR_PREFIX}car"), scenario.sun_elevation_deg, scenario.sun_azimuth_deg, scenario.sun_intensity,
                 shadow=True)
    add_tyre_contacts(spec, props.GROUND_CONTACT_GEOM, scenario.road_friction)
    return spec, info


def _clean_texture(kind: str, sheeting: bool = False) -> np.ndarray:
    """The clean face of sign `kind`: in the sheeting's colours (drawn), or the design colours (textures/)."""
    if sheeting:
        return sign_materials.sheeting_face(kind)
    shape = SIGN_SHAPES[kind]
    return load_texture_png(TEXTURE_DIR / CLEAN_TEXTURE_FILES[kind], expected_aspect=shape.width_m / shape.height_m)


def _set_options(spec: mujoco.MjSpec, config: SimConfig) -> None:
    spec.option.timestep = config.loop.physics_dt_s
    # implicitfast keeps the stiff steering servos and wheel contacts stable at 2 ms.
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.stat.extent = EXTENT_M
    spec.stat.center = [0.0, 0.0, 0.0]
    spec.visual.map.znear = ZNEAR_M / EXTENT_M
    spec.visual.map.zfar = ZFAR_M / EXTENT_M
    # Fog is drawn only when scenario.fog_end_m > 0 (see CameraRig); colour of an overcast haze.
    if config.scenario.fog_end_m > 0:
        spec.visual.map.fogstart = config.scenario.fog_start_m / EXTENT_M
        spec.visual.map.fogend = config.scenario.fog_end_m / EXTENT_M
    spec.visual.rgba.fog = [0.78, 0.8, 0.83, 1.0]
    spec.visual.quality.offsamples = config.camera.offsamples
    if config.scenario.sun_shadow_map_px:
        spec.visual.quality.shadowsize = config.scenario.sun_shadow_map_px
        spec.visual.map.shadowclip = SUN_SHADOW_HALF_WIDTH_M / EXTENT_M
    spec.visual.quality.numslices = CURVE_SLICES
    spec.visual.quality.numstacks = CURVE_STACKS
    cam = config.camera
    spec.visual.global_.offwidth = cam.width_px * max(cam.seg_supersample, cam.supersample)
    spec.visual.global_.offheight = cam.height_px * max(cam.seg_supersample, cam.supersample)
    spec.visual.headlight.ambient = [0.35, 0.35, 0.35]
    spec.visual.headlight.diffuse = [0.25, 0.25, 0.25]
    spec.visual.headlight.specular = [0.0, 0.0, 0.0]


def _add_sun(body: mujoco.MjsBody, elevation_deg: float, azimuth_deg: float, intensity: float, shadow: bool = False) -> None:
    """The sun: a directional light in `body`. Without `shadow`, `body` is the world body (the default
    renders). With it, `body` is the car's, the light tracks it and casts shadows (see SUN_SHADOW_*)."""
    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    direction = [-math.cos(el) * math.cos(az), -math.cos(el) * math.sin(az), -math.sin(el)]
    light = body.add_light(
        name="sun", type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL, dir=direction, pos=[0, 0, 100],
        diffuse=[0.75 * intensity, 0.73 * intensity, 0.68 * intensity], ambient=[0.1, 0.1, 0.1],
        specular=[0.1, 0.1, 0.1], castshadow=shadow,
    )
    if shadow:
        light.mode = mujoco.mjtCamLight.mjCAMLIGHT_TRACK
        # The car's body frame is level and at the world's heading at its model pose, so this offset is in world axes.
        light.pos = (np.array([SUN_SHADOW_AIM_AHEAD_M, 0.0, 0.0]) - SUN_SHADOW_DISTANCE_M * np.asarray(direction)).tolist()


def _attach_car(spec: mujoco.MjSpec, vehicle: VehicleConfig, camera: CameraConfig) -> None:
    car = load_car(vehicle)
    car.camera("front").fovy = camera.fovy_deg
    side = car.camera("side")
    side.fovy = camera.side_fovy_deg
    side.quat = _camera_quat(yaw_right_deg=camera.side_yaw_deg)
    car.camera("front").quat = _camera_quat(yaw_right_deg=0.0)
    frame = spec.worldbody.add_frame()
    frame.attach_body(car.body("car"), CAR_PREFIX, "")


def _camera_quat(yaw_right_deg: float) -> list[float]:
    """Orientation of a car camera looking forward (body +x) turned right by `yaw_right_deg`.

    MuJoCo cameras look along their -z axis with +y up; the unturned camera has
    x_cam = body -y, y_cam = body +z, so -z_cam = body +x.
    """
    yaw = -math.radians(yaw_right_deg)
    c, s = math.cos(yaw), math.sin(yaw)
    x_cam = np.array([s, -c, 0.0])  # body -y turned by yaw
    y_cam = np.array([0.0, 0.0, 1.0])
    z_cam = np.cross(x_cam, y_cam)
    mat = np.column_stack([x_cam, y_cam, z_cam]).ravel()
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, mat)
    return quat.tolist()
