"""Facade windows drawn as geometry (`scenario.facade_windows = "geometry"`), not painted into the wall's texture.

A window painted into a facade texture is filtered with the texture. MuJoCo's classic renderer filters
textures with trilinear mip-maps, which choose one level of detail per pixel from the longer axis of the pixel's
footprint. Seen down a street, at 10-14:1, that blurs the windows across the short axis as well, into vertical
streaks. Anisotropic filtering removes the streaks, but llvmpipe pays about 150x a frame for it
(docs/realism_filtering.md). A window that is geometry is rasterised instead, with sharp edges at any angle.

Each building box in a facade material (`props.add_building`) takes the wall alone (`<facade>_wall`: the flat
wall colour, or under `scenario.materials = "textured"` the facade texture's wall and grain without its
window). Windows go on its street face and on both ends, one per bay (2.5 m) and storey (3.5 m), with the bays
centred on the face. They are the texture's windows, at the texture's size and place (`surface_textures`:
1.4 x 1.6 m, a 6 cm frame, a mullion and a transom). Each one is flat quads standing proud of the wall:

- a frame, FRAME_PROUD_M out, in the texture's frame colour;
- four panes, PANE_PROUD_M out, in the glass colour. The upper two are lighter, the lower two darker: each
  pane takes the mean over its rows of the texture's sky reflection.

The sill is not drawn. A building gets three mesh geoms: its frames, its upper panes and its lower panes.
A render pays three more draw calls a building, and four vertices a quad.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from avsim.world import surface_textures as st

# How far the quads stand in front of the wall [m]. The depth buffer must keep them apart from the wall out to
# the far facades: at 300 m a 24-bit buffer with the cameras' 0.2 m near plane resolves about 3 cm.
FRAME_PROUD_M, PANE_PROUD_M = 0.03, 0.06
_UP = np.array([0.0, 0.0, 1.0])

Rect = tuple[float, float, float, float]  # (u0, v0, u1, v1) [m] on a face: along it, and up from the ground


def wall_material(facade: str) -> str:
    """The material of `facade`'s wall without its windows."""
    return f"{facade}_wall"


def pane_gains() -> tuple[float, float]:
    """(upper, lower) panes' factors on the glass colour: the means of the texture's sky reflection, which runs
    from GLASS_GAIN_HEAD at the head to GLASS_GAIN_SILL at the sill, over the rows above and below the transom."""
    head_to_sill_m = st.WINDOW_SILL_M - st.WINDOW_HEAD_M
    def mean_gain(from_m: float, to_m: float) -> float:  # from and to: below the head [m]
        mid = (from_m + to_m) / 2 / head_to_sill_m
        return st.GLASS_GAIN_HEAD + (st.GLASS_GAIN_SILL - st.GLASS_GAIN_HEAD) * mid
    transom = st.WINDOW_TRANSOM_BELOW_HEAD_M
    return mean_gain(0.0, transom), mean_gain(transom, head_to_sill_m)


def window_rects(width_m: float, height_m: float) -> tuple[list[Rect], list[Rect], list[Rect]]:
    """(frames, upper panes, lower panes) of every window on a face `width_m` wide and `height_m` tall, in the
    face's metres (u along it from its left edge seen from outside, v up from the ground). Whole bays and
    storeys only; the bays are centred on the face."""
    bays, storeys = int(width_m // st.FACADE_BAY_M), int(height_m // st.FACADE_STOREY_M)
    left_m = (width_m - st.FACADE_BAY_M * bays) / 2
    frame, half_bar = st.WINDOW_FRAME_M, st.WINDOW_BAR_M / 2
    frames, upper, lower = [], [], []
    for storey in range(storeys):
        top = st.FACADE_STOREY_M * (storey + 1)
        head, sill = top - st.WINDOW_HEAD_M, top - st.WINDOW_SILL_M
        transom = head - st.WINDOW_TRANSOM_BELOW_HEAD_M
        for bay in range(bays):
            u0 = left_m + st.FACADE_BAY_M * bay + st.WINDOW_LEFT_M
            u1 = left_m + st.FACADE_BAY_M * bay + st.WINDOW_RIGHT_M
            mullion = (u0 + u1) / 2
            frames.append((u0, sill, u1, head))
            for a, b in ((u0 + frame, mullion - half_bar), (mullion + half_bar, u1 - frame)):
                upper.append((a, transom + half_bar, b, head - frame))
                lower.append((a, sill + frame, b, transom - half_bar))
    return frames, upper, lower


class Face:
    """A building's vertical face: `origin` its lower-left corner seen from outside [m, world], `normal` its
    outward unit normal (horizontal), `width_m` and `height_m` its size. `along` runs from the origin across it,
    so that along x up = normal."""

    def __init__(self, origin: np.ndarray, normal: np.ndarray, width_m: float, height_m: float) -> None:
        self.origin, self.normal, self.width_m, self.height_m = origin, normal, width_m, height_m
        self.along = np.cross(_UP, normal)

    def corners(self, rects: np.ndarray, proud_m: float) -> np.ndarray:
        """(N, 4, 3) world corners [m] of `rects` ((N, 4): u0, v0, u1, v1 on the face), `proud_m` in front of it,
        each counter-clockwise seen from outside."""
        rects = np.asarray(rects, float).reshape(-1, 4)
        u = rects[:, [0, 2, 2, 0]][..., None]  # (N, 4, 1): the corners' u, then v, in counter-clockwise order
        v = rects[:, [1, 1, 3, 3]][..., None]
        return self.origin + proud_m * self.normal + u * self.along + v * _UP


def faces_of(centre: np.ndarray, half_size: np.ndarray) -> list[Face]:
    """A world-aligned building box's faces that get windows: the one towards the road (y = 0, the approach's
    axis) and both ends. The back faces away from every camera on the road. centre, half_size: the box's [m]."""
    height_m = 2 * half_size[2]
    bottom = centre - np.array([0.0, 0.0, half_size[2]])
    towards_road = np.array([0.0, -math.copysign(1.0, centre[1]), 0.0])
    faces = []
    for normal, half_depth, width in ((towards_road, half_size[1], 2 * half_size[0]),
                                      (np.array([-1.0, 0.0, 0.0]), half_size[0], 2 * half_size[1]),
                                      (np.array([1.0, 0.0, 0.0]), half_size[0], 2 * half_size[1])):
        along = np.cross(_UP, normal)
        faces.append(Face(bottom + half_depth * normal - width / 2 * along, normal, width, height_m))
    return faces


def _add_quads(spec: mujoco.MjSpec, name: str, corners: np.ndarray, rgb: np.ndarray) -> None:
    """One visual mesh geom of the quads `corners` ((N, 4, 3), each counter-clockwise seen from its front)."""
    if len(corners) == 0:
        return
    first = 4 * np.arange(len(corners))[:, None]
    faces = (first + np.array([0, 1, 2, 0, 2, 3])).ravel()  # two triangles a quad, wound as the quad
    mesh = spec.add_mesh(name=name, uservert=corners.ravel().tolist(), userface=faces.tolist())
    mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL  # open quads enclose no volume
    mesh.maxhullvert = 4  # the convex hull serves collisions only, and these geoms collide with nothing
    spec.worldbody.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name, contype=0, conaffinity=0,
                            rgba=[*np.minimum(rgb, 1.0).tolist(), 1.0])


def add_window_geometry(spec: mujoco.MjSpec, facade_colours: dict[str, tuple[tuple[float, float, float], ...]]) -> None:
    """Give every box geom in a facade material (a key of `facade_colours`: (wall RGB, glass RGB)) its wall's
    material (`wall_material`, which the caller has added) and its windows as geometry (the module docstring).
    The boxes must be world-aligned, as `props.add_building` makes them."""
    upper_gain, lower_gain = pane_gains()
    for geom in [g for g in spec.geoms if g.material in facade_colours and g.type == mujoco.mjtGeom.mjGEOM_BOX]:
        if not np.allclose(geom.quat, (1.0, 0.0, 0.0, 0.0)):
            raise ValueError(f"facade box {geom.name} is turned; windows are built on world-aligned boxes only")
        wall, glass = facade_colours[geom.material]
        quads: dict[str, list[np.ndarray]] = {"frames": [], "panes_upper": [], "panes_lower": []}
        for face in faces_of(np.asarray(geom.pos, float), np.asarray(geom.size, float)):
            frames, upper, lower = window_rects(face.width_m, face.height_m)
            quads["frames"].append(face.corners(frames, FRAME_PROUD_M))
            quads["panes_upper"].append(face.corners(upper, PANE_PROUD_M))
            quads["panes_lower"].append(face.corners(lower, PANE_PROUD_M))
        colours = {"frames": st.window_frame_rgb(wall), "panes_upper": upper_gain * np.asarray(glass),
                   "panes_lower": lower_gain * np.asarray(glass)}
        for part, corners in quads.items():
            _add_quads(spec, f"{geom.name}/window_{part}", np.concatenate(corners), colours[part])
        geom.material = wall_material(geom.material)
