"""Tree crowns a camera can see through (`scenario.foliage = "clusters"`).

The towns place each tree as a trunk and one opaque ellipsoid crown (`avsim.world.props.add_tree`).
A real broadleaf crown in leaf is not opaque: sky and background show through the gaps between its
leaf clusters, and its outline is ragged. Under "clusters" each crown ellipsoid becomes an envelope,
filled with leaf clusters until the fraction of the envelope's silhouette through which the
background shows (the crown's optical porosity) has fallen to CROWN_POROSITY, seen from the side
from four horizontal directions (VIEW_AZIMUTHS_DEG: along the road, across it and both diagonals).

Physical figures:
- CROWN_POROSITY = 0.19: the median of the summer sky fractions seen through mature broadleaf crowns
  measured by Wilkinson (1992; oak 0.17, sycamore 0.18, birch 0.24, Lombardy poplar 0.13, lime 0.11,
  beech 0.19, hawthorn 0.22, alder 0.24, ash 0.22, horse chestnut 0.19), as tabulated in Tregenza and
  Sharples' daylight algorithms (1.44c). docs/realism_foliage.md.
- CLUSTER_RADIUS_M = 0.3-0.7 m: the foliage of one branch's leafy spray, 0.6-1.4 m across. This is an
  assumed scale, not a measured one.
- Leaves grow into light, so a crown's foliage spreads over its gaps rather than piling up behind
  itself. Each cluster is therefore the best of CANDIDATES places drawn at random: the one that covers
  the most of the silhouette still open. (With one candidate, a Boolean model, the towns' 5-12 m trees
  need 3-4 times as many clusters for the same porosity, most of them hidden behind others.)
None of these was searched for a detector's score.

A cluster is a small copy of its crown's envelope (the same proportions), k = r / a_min of its size,
where r is the cluster's horizontal radius and a_min the envelope's smallest semi-axis. Its centre lies
in the envelope shrunk by 1 - k, so the cluster lies wholly inside the envelope: for a convex E about
its centre, q + k E lies in E for every q in (1 - k) E. In the envelope's normalised coordinates
(each axis divided by its semi-axis) the envelope is the unit ball, a cluster a ball of radius k, and
their silhouettes along any direction discs of radius 1 and k. A parallel projection keeps ratios of
areas under this affine map, so the porosity seen along a world direction d is the one seen along
d / semi-axes in normalised coordinates.

Each crown's clusters come from its own generator, seeded by the layout seed and the tree's name,
so a scene is the same every time it is built, and a crown does not change when another tree does.
The clusters are visual only (contype = conaffinity = 0), like every prop.

Frames: world frame of `avsim.world.road`, metres.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import mujoco
import numpy as np

CROWN_POROSITY = 0.19
CLUSTER_RADIUS_M = (0.3, 0.7)
# A cluster's horizontal radius is at most this fraction of its envelope's smallest semi-axis.
MAX_CLUSTER_FRACTION = 0.4
CANDIDATES = 8
# The silhouettes judged, seen from afar horizontally from these azimuths about world z (0: along the
# road, world +x; 90: across it). A crown's porosity is measured from the side, from any direction.
VIEW_AZIMUTHS_DEG = (0.0, 45.0, 90.0, 135.0)
# The crowns' geoms as `add_tree` names them: "<tree>/crown".
CROWN_SUFFIX = "/crown"
# A silhouette is judged on this many grid points per axis across the unit disc: about 1,800 inside it.
SILHOUETTE_GRID = 48
# No crown gets more clusters than this (a 12 m tree needs about 70: a bound, not a target).
MAX_CLUSTERS = 400


@dataclass(frozen=True)
class Crown:
    """A crown's envelope: an axis-aligned ellipsoid at `centre_m` (3,) [m, world] with `semi_axes_m` (3,)."""

    centre_m: np.ndarray
    semi_axes_m: np.ndarray


@dataclass(frozen=True)
class LeafClusters:
    """A crown's clusters: `centres_m` (N, 3) [m, world] and `semi_axes_m` (N, 3), each a copy of the
    envelope scaled by its `scales` (N,) (k above)."""

    centres_m: np.ndarray
    semi_axes_m: np.ndarray
    scales: np.ndarray


def crown_rng(layout_seed: int, tree_name: str) -> np.random.Generator:
    """The generator of one crown's clusters: a stable function of the layout seed and the tree's name."""
    return np.random.default_rng([layout_seed, zlib.crc32(tree_name.encode())])


def _unit_disc_grid() -> np.ndarray:
    """(P, 2) cell centres of a SILHOUETTE_GRID square grid that lie inside the unit disc."""
    u = (np.arange(SILHOUETTE_GRID) + 0.5) / SILHOUETTE_GRID * 2 - 1
    grid = np.stack(np.meshgrid(u, u, indexing="ij"), axis=-1).reshape(-1, 2)
    return grid[(grid**2).sum(axis=1) <= 1.0]


def _image_plane(crown: Crown, view_dir: np.ndarray) -> np.ndarray:
    """(2, 3): an orthonormal basis of the plane across `view_dir` (3,) [world], in normalised coordinates."""
    d = view_dir / crown.semi_axes_m
    d /= np.linalg.norm(d)
    helper = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(helper, d)
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(d, e1)])


def horizontal_view(azimuth_deg: float) -> np.ndarray:
    """(3,) the world direction of a horizontal view at `azimuth_deg` about world z (0: +x)."""
    azimuth = np.radians(azimuth_deg)
    return np.array([np.cos(azimuth), np.sin(azimuth), 0.0])


def _covered(grid: np.ndarray, centres_unit: np.ndarray, scales: np.ndarray, plane: np.ndarray) -> np.ndarray:
    """(N, P): which grid points of the silhouette in `plane` (2, 3) each cluster covers (normalised coordinates)."""
    # Elementwise, not a matrix product, so that no BLAS kernel's rounding can move a point across a
    # cluster's edge: the crowns are the same on every machine.
    projected = (centres_unit[:, None, :] * plane[None, :, :]).sum(axis=2)  # (N, 2)
    across = grid[None, :, 0] - projected[:, 0:1]
    up = grid[None, :, 1] - projected[:, 1:2]
    return across * across + up * up <= scales[:, None] ** 2


def silhouette_porosity(crown: Crown, clusters: LeafClusters, view_dir: np.ndarray) -> float:
    """The fraction of the envelope's silhouette, seen from afar along `view_dir` (3,) [world], that no
    cluster covers: the crown's optical porosity from that direction."""
    grid = _unit_disc_grid()
    if not len(clusters.scales):
        return 1.0
    centres_unit = (clusters.centres_m - crown.centre_m) / crown.semi_axes_m
    plane = _image_plane(crown, np.asarray(view_dir, float))
    return float(1.0 - _covered(grid, centres_unit, clusters.scales, plane).any(axis=0).mean())


def leaf_clusters(crown: Crown, rng: np.random.Generator) -> LeafClusters:
    """Leaf clusters filling `crown` until its porosity from every VIEW_AZIMUTHS_DEG is CROWN_POROSITY or less.

    Clusters are added one at a time. Each draws a horizontal radius uniform in CLUSTER_RADIUS_M (at
    most MAX_CLUSTER_FRACTION of a_min) and CANDIDATES centres uniform in the volume where a cluster of
    that size fits, and keeps the centre that covers the most grid points still open in the silhouettes.
    """
    grid = _unit_disc_grid()
    planes = [_image_plane(crown, horizontal_view(azimuth)) for azimuth in VIEW_AZIMUTHS_DEG]
    a_min_m = float(crown.semi_axes_m.min())
    r_max_m = min(CLUSTER_RADIUS_M[1], MAX_CLUSTER_FRACTION * a_min_m)
    r_min_m = min(CLUSTER_RADIUS_M[0], r_max_m)
    # Per view, the grid points no cluster covers yet (the set shrinks as clusters are added).
    open_points = [grid for _ in planes]
    centres, scales = [], []
    while len(scales) < MAX_CLUSTERS and max(len(points) for points in open_points) > CROWN_POROSITY * len(grid):
        scale = float(rng.uniform(r_min_m, r_max_m)) / a_min_m
        directions = rng.normal(size=(CANDIDATES, 3))
        radii = rng.uniform(size=(CANDIDATES, 1)) ** (1 / 3)  # uniform in the unit ball's volume
        candidates = directions / np.linalg.norm(directions, axis=1, keepdims=True) * radii * (1.0 - scale)
        covers = [_covered(points, candidates, np.full(CANDIDATES, scale), plane) for points, plane in zip(open_points, planes)]
        best = int(np.argmax(sum(cover.sum(axis=1) for cover in covers)))
        open_points = [points[~cover[best]] for points, cover in zip(open_points, covers)]
        centres.append(candidates[best])
        scales.append(scale)
    scales_arr = np.array(scales)
    return LeafClusters(crown.centre_m + np.array(centres).reshape(-1, 3) * crown.semi_axes_m,
                        scales_arr[:, None] * crown.semi_axes_m, scales_arr)


def _icosphere() -> tuple[np.ndarray, np.ndarray]:
    """A unit sphere as an icosahedron subdivided once: vertices (42, 3) and faces (80, 3), outward."""
    t = (1 + 5**0.5) / 2
    vertices = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
                (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
             (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
             (8, 6, 7), (9, 8, 1)]
    midpoints: dict[tuple[int, int], int] = {}

    def midpoint(i: int, j: int) -> int:
        key = (min(i, j), max(i, j))
        if key not in midpoints:
            midpoints[key] = len(vertices)
            vertices.append(tuple((np.array(vertices[i]) + np.array(vertices[j])) / 2))
        return midpoints[key]

    split = []
    for a, b, c in faces:
        ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
        split += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
    unit = np.array(vertices, float)
    return unit / np.linalg.norm(unit, axis=1, keepdims=True), np.array(split, np.int32)


UNIT_SPHERE_VERTICES, UNIT_SPHERE_FACES = _icosphere()


def crown_mesh(crown: Crown, clusters: LeafClusters) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One mesh of a crown's clusters, each an ellipsoid of 80 faces, in the crown's frame (centred at
    `crown.centre_m`, world axes): vertices (V, 3) [m], faces (F, 3) and texture coordinates (V, 2) [m].

    The texture coordinates are lengths on each cluster's surface: round the vertical axis from -x
    (so the seam faces +x, away from cameras that look along the road) and down from its top. A
    material's texrepeat per metre then tiles the leaves at their physical scale.
    """
    n = len(clusters.scales)
    vertices = (UNIT_SPHERE_VERTICES[None] * clusters.semi_axes_m[:, None, :]
                + (clusters.centres_m - crown.centre_m)[:, None, :]).reshape(-1, 3)
    faces = (UNIT_SPHERE_FACES[None] + (np.arange(n) * len(UNIT_SPHERE_VERTICES))[:, None, None]).reshape(-1, 3)
    around = np.arctan2(UNIT_SPHERE_VERTICES[:, 1], -UNIT_SPHERE_VERTICES[:, 0])  # (-pi, pi]
    down = np.arccos(np.clip(UNIT_SPHERE_VERTICES[:, 2], -1.0, 1.0))  # [0, pi]
    texcoords = np.stack([around[None] * clusters.semi_axes_m[:, None, 0], down[None] * clusters.semi_axes_m[:, None, 2]],
                         axis=-1).reshape(-1, 2)
    return vertices, faces, texcoords


def crown_envelopes(spec: mujoco.MjSpec) -> list[tuple[mujoco.MjsGeom, Crown]]:
    """The solid crowns of `spec` (geoms named "<tree>/crown", ellipsoids in the world body)."""
    return [(geom, Crown(np.array(geom.pos, float), np.array(geom.size, float)))
            for geom in spec.worldbody.geoms
            if geom.name.endswith(CROWN_SUFFIX) and geom.type == mujoco.mjtGeom.mjGEOM_ELLIPSOID]


def replace_crowns_with_clusters(spec: mujoco.MjSpec, layout_seed: int) -> int:
    """Turn every solid crown of `spec` into its leaf clusters. Returns the number of clusters.

    Each crown stays one geom, "<tree>/crown", in its material, place and collision settings (visual
    only), now a mesh of its clusters ("<tree>/crown_mesh"): the physics pays for one geom per tree,
    as before, and segmentation names the crown as before.
    """
    added = 0
    for geom, crown in crown_envelopes(spec):
        tree_name = geom.name[: -len(CROWN_SUFFIX)]
        clusters = leaf_clusters(crown, crown_rng(layout_seed, tree_name))
        vertices, faces, texcoords = crown_mesh(crown, clusters)
        mesh_name = f"{tree_name}/crown_mesh"
        spec.add_mesh(name=mesh_name, uservert=vertices.ravel().tolist(), userface=faces.ravel().tolist(),
                      usertexcoord=texcoords.ravel().tolist())
        geom.type = mujoco.mjtGeom.mjGEOM_MESH
        geom.meshname = mesh_name
        added += len(clusters.scales)
    return added
