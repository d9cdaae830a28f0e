"""Traffic signs as MJCF (built with MjSpec): a textured face mesh on a post.

Sign frame: origin at the foot of the post on the ground; the face looks along
local -x (towards traffic approaching along world +x when yaw = 0), local y is the
viewer's left, z is up. The face is a thin prism whose front cap carries the
texture; the texture is passed in as an RGB array, so any PNG can be put on any
sign at run time (see `avsim.world.textures`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from avsim.world.sign_materials import ALUMINIUM, BLANK_THICKNESS_M, GALVANISED

FACE_THICKNESS_M = 0.004
POST_HALF_WIDTH_M = 0.035
# Texture coordinate of a grey texel outside every sign shape: the back and rim of the
# face prism use it, so the back of a sign reads as a plain plate.
_BACK_UV = (0.01, 0.01)


@dataclass(frozen=True)
class SignShape:
    """Outline of a sign face, in metres, in the face plane (y = viewer's left, z = up).

    `outline_yz` is centred on the face centre; `width_m` x `height_m` is the texture's
    footprint, i.e. the texture's edges map to the outline's bounding box.
    """

    kind: str
    outline_yz: tuple[tuple[float, float], ...]
    width_m: float
    height_m: float


def _octagon(flat_to_flat_m: float) -> SignShape:
    # Vertices at 22.5 deg + k * 45 deg put flats at the top and bottom, as on a real stop sign.
    r = flat_to_flat_m / 2 / math.cos(math.pi / 8)
    pts = tuple((r * math.cos(math.pi / 8 + k * math.pi / 4), r * math.sin(math.pi / 8 + k * math.pi / 4)) for k in range(8))
    return SignShape("stop_sign", pts, flat_to_flat_m, flat_to_flat_m)


def _yield_triangle(side_m: float) -> SignShape:
    # Point down; the texture is square with the triangle's top edge along its top,
    # so the square's footprint is side x side with the apex at sqrt(3)/2 of the way down.
    h = side_m * math.sqrt(3) / 2
    top = side_m / 2
    pts = ((side_m / 2, top), (0.0, top - h), (-side_m / 2, top))
    return SignShape("yield", pts, side_m, side_m)


def _rectangle(width_m: float, height_m: float) -> SignShape:
    w, h = width_m / 2, height_m / 2
    return SignShape("speed_limit", ((w, h), (w, -h), (-w, -h), (-w, h)), width_m, height_m)


# MUTCD sizes: R1-1 stop 30 in, R1-2 yield 36 in, R2-1 speed limit 24 x 30 in.
SIGN_SHAPES: dict[str, SignShape] = {
    "stop_sign": _octagon(0.762),
    "yield": _yield_triangle(0.914),
    "speed_limit": _rectangle(0.610, 0.762),
}


@dataclass(frozen=True)
class PlacedSign:
    """A sign in the world. Positions are world frame [m]; yaw about +z [rad]."""

    name: str
    kind: str
    base_pos_m: tuple[float, float, float]
    yaw_rad: float
    bottom_height_m: float

    @property
    def shape(self) -> SignShape:
        """The face outline of this kind of sign (`SIGN_SHAPES`, MUTCD sizes)."""
        return SIGN_SHAPES[self.kind]

    @property
    def face_geom(self) -> str:
        """Name of the MuJoCo geom that carries the sign's face texture."""
        return f"{self.name}/face"

    @property
    def texture_name(self) -> str:
        """Name of the MuJoCo texture drawn on the face (swapped for an attacked one)."""
        return f"{self.name}/texture"

    @property
    def face_center_m(self) -> np.ndarray:
        """Centre of the textured face, world frame [m], shape (3,)."""
        return self.face_points_m(np.zeros((1, 2)))[0]

    def face_points_m(self, points_yz: np.ndarray) -> np.ndarray:
        """Map face-plane points (N, 2) [m] from the face centre to world points (N, 3)."""
        c, s = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        local = np.column_stack([
            np.full(len(points_yz), -POST_HALF_WIDTH_M - FACE_THICKNESS_M),
            points_yz[:, 0],
            points_yz[:, 1] + self.bottom_height_m + self.shape.height_m / 2,
        ])
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return local @ rot.T + np.asarray(self.base_pos_m)

    def corners_m(self) -> np.ndarray:
        """World positions (N, 3) of the outline's vertices, for projecting into a camera."""
        return self.face_points_m(np.asarray(self.shape.outline_yz))


def _outline_prism(shape: SignShape, thickness_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) and outward faces (F, 3) of a prism of the face outline, in face-local metres: its
    front cap at x = -thickness_m facing -x, its back cap at x = 0, the outline centred on the origin.
    Vertex 0 is the front cap's centre, 1..n its rim; n + 1 the back cap's centre, then its rim."""
    rim = np.asarray(shape.outline_yz)
    n = len(rim)
    front = np.vstack([[0.0, 0.0], rim])
    verts = np.vstack([
        np.column_stack([np.full(n + 1, -thickness_m), front[:, 0], front[:, 1]]),
        np.column_stack([np.zeros(n + 1), front[:, 0], front[:, 1]]),
    ])
    faces = []
    for i in range(1, n + 1):
        j = i % n + 1
        faces.append((0, i, j))  # front cap
        faces.append((n + 1, n + 1 + j, n + 1 + i))  # back cap
        faces.append((i, n + 1 + i, n + 1 + j))  # rim
        faces.append((i, n + 1 + j, j))
    return verts, _orient_outwards(verts, np.asarray(faces))


def _face_mesh(shape: SignShape) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices (V, 3), faces (F, 3) and texcoords (V, 2) of the face prism, in face-local metres.

    The face centre sits at the origin; the front cap is at x = -thickness, facing -x.
    """
    verts, faces = _outline_prism(shape, FACE_THICKNESS_M)
    front = np.vstack([[0.0, 0.0], np.asarray(shape.outline_yz)])
    # The viewer looks along +x, so their right is -y: u grows towards -y, v downwards.
    uv_front = np.column_stack([0.5 - front[:, 0] / shape.width_m, 0.5 - front[:, 1] / shape.height_m])
    uv = np.vstack([uv_front, np.tile(_BACK_UV, (len(front), 1))])
    return verts, faces, uv


def _orient_outwards(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Flip triangles whose normal points into the (convex) prism; MuJoCo wants CCW outward."""
    centroid = verts.mean(axis=0)
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    normal = np.cross(b - a, c - a)
    inward = np.einsum("ij,ij->i", normal, (a + b + c) / 3 - centroid) < 0
    faces = faces.copy()
    faces[inward] = faces[inward][:, [0, 2, 1]]
    return faces


def add_sign(spec: mujoco.MjSpec, sign: PlacedSign, texture_rgb: np.ndarray, metal: bool = False) -> None:
    """Add `sign` (post, textured face) as a static body of `spec`.

    texture_rgb: (H, W, 3) uint8, RGB, covering the face's `width_m` x `height_m`
    footprint with row 0 at the top edge.
    metal: the face on an aluminium blank and the post galvanised (`avsim.world.sign_materials`, whose
    materials `spec` must hold); else a plain grey post and the face prism's own grey back.
    """
    add_plate(spec, sign.name, sign.shape, sign.base_pos_m, sign.yaw_rad, sign.bottom_height_m, texture_rgb, metal)


def add_plate(spec: mujoco.MjSpec, name: str, shape: SignShape, base_pos_m: tuple[float, float, float], yaw_rad: float,
              bottom_height_m: float, texture_rgb: np.ndarray, metal: bool = False) -> None:
    """A textured plate of any outline on a post (a sign, or a sign-like board that is none), as a
    static body named `name`; the frame, yaw, texture and `metal` as for `add_sign`."""
    tex = spec.add_texture(name=f"{name}/texture", type=mujoco.mjtTexture.mjTEXTURE_2D)
    set_texture_data(tex, texture_rgb)
    mat = spec.add_material(name=f"{name}/material")
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = f"{name}/texture"
    verts, faces, uv = _face_mesh(shape)
    spec.add_mesh(
        name=f"{name}/face_mesh",
        uservert=verts.ravel().tolist(),
        userface=faces.ravel().tolist(),
        usertexcoord=uv.ravel().tolist(),
    )
    c, s = math.cos(yaw_rad / 2), math.sin(yaw_rad / 2)
    body = spec.worldbody.add_body(name=name, pos=list(base_pos_m), quat=[c, 0, 0, s])
    centre_z = bottom_height_m + shape.height_m / 2
    post_top_m = centre_z
    post = body.add_geom(
        name=f"{name}/post", type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[POST_HALF_WIDTH_M, POST_HALF_WIDTH_M, post_top_m / 2], pos=[0, 0, post_top_m / 2],
        rgba=[0.55, 0.56, 0.58, 1], contype=0, conaffinity=0,
    )
    if metal:
        post.material = GALVANISED
        _add_blank(spec, body, name, shape, centre_z)
    body.add_geom(
        name=f"{name}/face", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"{name}/face_mesh",
        material=f"{name}/material", pos=[-POST_HALF_WIDTH_M, 0, centre_z],
        contype=0, conaffinity=0,
    )


def _add_blank(spec: mujoco.MjSpec, body: mujoco.MjsBody, name: str, shape: SignShape, centre_z_m: float) -> None:
    """The aluminium blank the face is mounted on: a BLANK_THICKNESS_M prism of the face's outline right
    behind it, seen from behind and at the rim."""
    verts, faces = _outline_prism(shape, BLANK_THICKNESS_M)
    spec.add_mesh(name=f"{name}/blank_mesh", uservert=verts.ravel().tolist(), userface=faces.ravel().tolist())
    body.add_geom(name=f"{name}/blank", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"{name}/blank_mesh", material=ALUMINIUM,
                  pos=[-POST_HALF_WIDTH_M + BLANK_THICKNESS_M, 0, centre_z_m], contype=0, conaffinity=0)


def set_texture_data(tex: mujoco.MjsTexture, rgb: np.ndarray) -> None:
    """Fill an MjSpec texture from an (H, W, 3) uint8 RGB array (row 0 = top)."""
    rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
    tex.width, tex.height, tex.nchannel = rgb.shape[1], rgb.shape[0], 3
    tex.data = rgb.tobytes()
