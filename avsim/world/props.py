"""Static scenery: materials, buildings, trees, barns, fields, parked cars, street furniture.

All props are visual only (no collision: the car drives on the road plane and never
leaves it). Sizes are in metres, positions in the world frame of `avsim.world.road`.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from avsim.world import surface_textures as st
from avsim.world.facade_windows import wall_material
from avsim.world.signs import set_texture_data

BOX = mujoco.mjtGeom.mjGEOM_BOX
CYL = mujoco.mjtGeom.mjGEOM_CYLINDER
ELLIPSOID = mujoco.mjtGeom.mjGEOM_ELLIPSOID

_FLAT_COLOURS = {
    "asphalt": (0.22, 0.22, 0.23),
    "paint_white": (0.92, 0.92, 0.9),
    "paint_yellow": (0.9, 0.75, 0.15),
    "kerb": (0.6, 0.6, 0.58),
    "sidewalk": (0.68, 0.67, 0.64),
    "grass": (0.30, 0.45, 0.20),
    "field_wheat": (0.78, 0.68, 0.35),
    "field_green": (0.38, 0.55, 0.22),
    "soil": (0.42, 0.32, 0.22),
    "bark": (0.35, 0.25, 0.15),
    "leaves": (0.18, 0.38, 0.14),
    "barn_red": (0.55, 0.12, 0.1),
    "roof_grey": (0.3, 0.3, 0.32),
    "metal": (0.5, 0.52, 0.55),
    "dark_metal": (0.2, 0.21, 0.22),
    "glass": (0.25, 0.32, 0.4),
    "plaza": (0.6, 0.58, 0.55),
}
CAR_PAINTS = ((0.1, 0.2, 0.5), (0.85, 0.85, 0.85), (0.1, 0.1, 0.1), (0.3, 0.35, 0.3), (0.6, 0.55, 0.4), (0.2, 0.45, 0.6))
FACADES = ("facade_brick", "facade_concrete", "facade_glass", "facade_sand")


FACADE_COLOURS = {  # wall, window
    "facade_brick": ((0.55, 0.3, 0.22), (0.2, 0.24, 0.3)),
    "facade_concrete": ((0.7, 0.7, 0.68), (0.25, 0.3, 0.36)),
    "facade_glass": ((0.35, 0.45, 0.55), (0.2, 0.28, 0.36)),
    "facade_sand": ((0.8, 0.72, 0.55), (0.28, 0.3, 0.34)),
}


PAINTS = ("paint_white", "paint_yellow")
# A textured facade repeats one bay by one storey (`surface_textures.facade`): repeats per metre, across and up.
_FACADE_REPEAT_PER_M = (1 / st.FACADE_BAY_M, 1 / st.FACADE_STOREY_M)


def add_materials(spec: mujoco.MjSpec, textured: bool = False, worn_paint: bool = False,
                  window_geometry: bool = False) -> None:
    """Register every material the builders use (the sky is `avsim.world.sky`'s).

    textured (scenario.materials): surfaces carry procedural texture at the scale a camera resolves
    (`avsim.world.surface_textures`) instead of one flat colour each, and facades a storey of wall and
    window instead of a checker.
    worn_paint (scenario.road_paint): the road's paint is worn through to the asphalt beneath it, the
    textured asphalt or the flat one.
    window_geometry (scenario.facade_windows = "geometry"): each facade's wall without its windows too
    (`facade_windows.wall_material`), its flat colour or its texture's wall, for facades whose windows are geometry.
    """
    if window_geometry and textured:
        for name, rgb in st.facade_textures(FACADE_COLOURS, windows=False).items():
            _add_textured_material(spec, wall_material(name), rgb, _FACADE_REPEAT_PER_M)
    elif window_geometry:
        for name, (wall, _) in FACADE_COLOURS.items():
            spec.add_material(name=wall_material(name), rgba=[*wall, 1.0])
    textures = st.ground_textures(_FLAT_COLOURS) if textured else {}
    if worn_paint:
        rng = np.random.default_rng((st.TEXTURE_SEED, 2))
        beneath = textures.get("asphalt", np.full((st.TEXELS, st.TEXELS, 3), np.rint(np.asarray(_FLAT_COLOURS["asphalt"]) * 255), np.uint8))
        textures.update({name: st.worn_paint(rng, _FLAT_COLOURS[name], beneath) for name in PAINTS})
    for name, rgb in _FLAT_COLOURS.items():
        if name not in textures:
            spec.add_material(name=name, rgba=[*rgb, 1.0])
        else:
            span_m = st.CONCRETE_REPEAT_M if name in st.CONCRETE else st.GROUND_REPEAT_M
            _add_textured_material(spec, name, textures[name], (1 / span_m, 1 / span_m))
    if textured:
        for name, rgb in st.facade_textures(FACADE_COLOURS).items():
            _add_textured_material(spec, name, rgb, _FACADE_REPEAT_PER_M)
        return
    # Facades: a checker texture repeated per metre reads as rows of windows.
    for name, (wall, window) in FACADE_COLOURS.items():
        spec.add_texture(name=f"{name}_tex", type=mujoco.mjtTexture.mjTEXTURE_2D, builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                         rgb1=list(wall), rgb2=list(window), width=64, height=64)
        mat = spec.add_material(name=name, texrepeat=[0.3, 0.3], texuniform=True)
        mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = f"{name}_tex"


def _add_textured_material(spec: mujoco.MjSpec, name: str, rgb: np.ndarray, repeat_per_m: tuple[float, float]) -> None:
    set_texture_data(spec.add_texture(name=f"{name}_tex", type=mujoco.mjtTexture.mjTEXTURE_2D), rgb)
    mat = spec.add_material(name=name, texrepeat=list(repeat_per_m), texuniform=True)
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = f"{name}_tex"


def _geom(spec: mujoco.MjSpec, name: str, kind: int, pos, size, material: str | None = None, rgba=None, quat=None) -> None:
    kwargs = dict(name=name, type=kind, pos=list(pos), size=list(size), contype=0, conaffinity=0)
    if material:
        kwargs["material"] = material
    if rgba is not None:
        kwargs["rgba"] = list(rgba)
    if quat is not None:
        kwargs["quat"] = list(quat)
    spec.worldbody.add_geom(**kwargs)


def _yaw_quat(yaw_rad: float) -> list[float]:
    return [math.cos(yaw_rad / 2), 0.0, 0.0, math.sin(yaw_rad / 2)]


GROUND_CONTACT_GEOM = "ground/contact"


def add_ground(spec: mujoco.MjSpec, material: str) -> None:
    """The physical road plane (hidden, group 3) and a visual ground just below it.

    The plane's friction is not used: the car's tyres touch it only through explicit contact
    pairs that carry the road's friction (`avsim.vehicle.assembly.add_tyre_contacts`).
    """
    spec.worldbody.add_geom(name=GROUND_CONTACT_GEOM, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[600, 600, 1],
                            group=3, rgba=[0, 0, 0, 0])
    _geom(spec, "ground/visual", BOX, (0, 0, -0.1), (600, 600, 0.05), material)


def add_building(spec: mujoco.MjSpec, name: str, x: float, y: float, size_xy: tuple[float, float], height: float, facade: str) -> None:
    """A building: a box of footprint `size_xy` [m] centred at (x, y) [m, world], `height` [m] tall, in
    the `facade` material, with a roof slab a little wider.
    """
    _geom(spec, name, BOX, (x, y, height / 2), (size_xy[0] / 2, size_xy[1] / 2, height / 2), facade)
    _geom(spec, f"{name}/roof", BOX, (x, y, height + 0.3), (size_xy[0] / 2 + 0.2, size_xy[1] / 2 + 0.2, 0.3), "roof_grey")


def add_building_row(spec: mujoco.MjSpec, name: str, rng: np.random.Generator, x_start: float, x_end: float,
                     y_front: float, side: int, heights_m: tuple[float, float]) -> None:
    """Buildings of random width, depth and height from x_start to x_end.

    Their street-facing walls stand at `y_front`; `side` (+1 left, -1 right) says
    which way they extend back from it.
    """
    x = x_start
    k = 0
    while x < x_end:
        width = float(rng.uniform(14, 30))
        depth = float(rng.uniform(15, 25))
        add_building(spec, f"{name}_{k}", x + width / 2, y_front + side * depth / 2, (width - 1.5, depth),
                     float(rng.uniform(*heights_m)), FACADES[int(rng.integers(len(FACADES)))])
        x += width
        k += 1


def add_tree(spec: mujoco.MjSpec, name: str, x: float, y: float, height: float) -> None:
    """A tree at (x, y) [m, world], `height` [m] tall: a trunk and an ellipsoid crown."""
    _geom(spec, f"{name}/trunk", CYL, (x, y, height * 0.3), (0.18, height * 0.3), "bark")
    _geom(spec, f"{name}/crown", ELLIPSOID, (x, y, height * 0.7), (height * 0.25, height * 0.25, height * 0.33), "leaves")


def add_barn(spec: mujoco.MjSpec, name: str, x: float, y: float, yaw_rad: float) -> None:
    """A red barn at (x, y) [m, world], its long axis at `yaw_rad` from +x, with a gable roof."""
    quat = _yaw_quat(yaw_rad)
    _geom(spec, name, BOX, (x, y, 3.0), (9.0, 6.0, 3.0), "barn_red", quat=quat)
    # Gable roof: two slabs pitched at 35 degrees about the barn's long axis.
    for side in (-1, 1):
        pitch = side * math.radians(35)
        q_pitch = [math.cos(pitch / 2), math.sin(pitch / 2), 0, 0]
        q = np.zeros(4)
        mujoco.mju_mulQuat(q, np.array(quat), np.array(q_pitch))
        off = np.array([0.0, side * 3.0, 0.0])
        c, s = math.cos(yaw_rad), math.sin(yaw_rad)
        off_w = (c * off[0] - s * off[1], s * off[0] + c * off[1])
        _geom(spec, f"{name}/roof_{side}", BOX, (x + off_w[0], y + off_w[1], 8.1), (9.3, 3.7, 0.12), "roof_grey", quat=q)


def add_field(spec: mujoco.MjSpec, name: str, x: float, y: float, size_xy: tuple[float, float], material: str) -> None:
    """A flat field of footprint `size_xy` [m] centred at (x, y) [m, world], just above the visual ground."""
    _geom(spec, name, BOX, (x, y, -0.04), (size_xy[0] / 2, size_xy[1] / 2, 0.01), material)


def add_parked_car(spec: mujoco.MjSpec, name: str, x: float, y: float, yaw_rad: float, paint: tuple[float, float, float]) -> None:
    """A parked car at (x, y) [m, world] heading `yaw_rad`, body in `paint` (RGB in [0, 1]), with a cabin and wheels."""
    quat = _yaw_quat(yaw_rad)
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    _geom(spec, name, BOX, (x, y, 0.65), (2.3, 0.9, 0.35), rgba=(*paint, 1), quat=quat)
    _geom(spec, f"{name}/cabin", BOX, (x - 0.3 * c, y - 0.3 * s, 1.22), (1.2, 0.8, 0.25), "glass", quat=quat)
    # One axle-long cylinder per axle shows both wheels (half the draw calls of four wheels).
    for k, dx in enumerate((1.4, -1.3)):
        _geom(spec, f"{name}/axle_{k}", CYL, (x + c * dx, y + s * dx, 0.33), (0.33, 0.9),
              "dark_metal", quat=_cyl_quat_lateral(yaw_rad))


def _cyl_quat_lateral(yaw_rad: float) -> list[float]:
    """Quaternion turning a cylinder's z axis to the car's lateral (y) axis after yaw."""
    q_roll = np.array([math.cos(math.pi / 4), math.sin(math.pi / 4), 0, 0])
    q = np.zeros(4)
    mujoco.mju_mulQuat(q, np.array(_yaw_quat(yaw_rad)), q_roll)
    return q.tolist()


def add_lamp_post(spec: mujoco.MjSpec, name: str, x: float, y: float, arm_dir: float) -> None:
    """A street lamp at (x, y) [m, world], 8 m tall, its arm reaching towards `arm_dir` (+1 left, -1 right)."""
    _geom(spec, name, CYL, (x, y, 4.0), (0.08, 4.0), "dark_metal")
    _geom(spec, f"{name}/arm", BOX, (x, y + arm_dir * 0.9, 7.9), (0.1, 0.9, 0.06), "dark_metal")


def add_bin(spec: mujoco.MjSpec, name: str, x: float, y: float) -> None:
    """A litter bin (1 m tall cylinder) at (x, y) [m, world]."""
    _geom(spec, name, CYL, (x, y, 0.5), (0.3, 0.5), "dark_metal")


def add_bollard(spec: mujoco.MjSpec, name: str, x: float, y: float) -> None:
    """A bollard (0.9 m tall post) at (x, y) [m, world]."""
    _geom(spec, name, CYL, (x, y, 0.45), (0.1, 0.45), "metal")


def add_red_distractor(spec: mujoco.MjSpec, name: str, x: float, y: float, size_xyz: tuple[float, float, float]) -> None:
    """A red box (a postbox, a kiosk) that is not a sign: a detector must not fire on it."""
    _geom(spec, name, BOX, (x, y, size_xyz[2] / 2), tuple(s / 2 for s in size_xyz), rgba=(0.75, 0.08, 0.1, 1))
