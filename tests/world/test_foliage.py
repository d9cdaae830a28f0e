"""See-through tree crowns (`scenario.foliage = "clusters"`): a named choice, the same crowns for the same
seed, clusters inside each crown's envelope at the stated porosity, visual only, the default crowns
unchanged, and a render in which the background shows through a crown."""

import mujoco
import numpy as np
import pytest

from avsim.config import ScenarioConfig
from avsim.errors import ConfigError
from avsim.sensors.gl import OffscreenRenderer
from avsim.world import foliage, props, sky
from avsim.world.scene import compose_scene
from helpers import make_config

# Town03 has 8 street trees (Town07 44): its scene builds in a fraction of a second.
TOWN = "town03"


def _crown_geoms(spec: mujoco.MjSpec) -> dict[str, mujoco.MjsGeom]:
    return {geom.name: geom for geom in spec.geoms if geom.name.endswith(foliage.CROWN_SUFFIX)}


@pytest.fixture(scope="module")
def solid_and_clusters():
    """The Town03 scene's spec under each foliage setting."""
    return {name: compose_scene(make_config(scenario={"town": TOWN, "foliage": name}))[0] for name in ("solid", "clusters")}


def test_foliage_is_a_named_choice():
    with pytest.raises(ConfigError, match=r"scenario.foliage must be one of solid, clusters, got 'leafy'"):
        ScenarioConfig(foliage="leafy")


def test_the_default_crowns_stay_solid_ellipsoids(solid_and_clusters):
    crowns = _crown_geoms(solid_and_clusters["solid"])
    assert len(crowns) == 8
    assert all(geom.type == mujoco.mjtGeom.mjGEOM_ELLIPSOID and geom.meshname == "" for geom in crowns.values())
    assert not any(mesh.name.endswith("/crown_mesh") for mesh in solid_and_clusters["solid"].meshes)


def test_clusters_keep_one_visual_geom_per_crown_in_its_place_and_material(solid_and_clusters):
    solid, clusters = _crown_geoms(solid_and_clusters["solid"]), _crown_geoms(solid_and_clusters["clusters"])
    assert clusters.keys() == solid.keys()
    for name, geom in clusters.items():
        assert geom.type == mujoco.mjtGeom.mjGEOM_MESH and geom.meshname == name + "_mesh"
        assert geom.material == solid[name].material == "leaves"
        assert geom.contype == 0 and geom.conaffinity == 0  # never touches the car
        assert list(geom.pos) == list(solid[name].pos)
    # The physics sees as many geoms as before: the clusters are one mesh per crown.
    assert len(solid_and_clusters["clusters"].geoms) == len(solid_and_clusters["solid"].geoms)


def test_the_same_seed_gives_the_same_crowns_and_another_seed_other_crowns(solid_and_clusters):
    again = compose_scene(make_config(scenario={"town": TOWN, "foliage": "clusters"}))[0]
    for mesh in solid_and_clusters["clusters"].meshes:
        assert np.array_equal(np.array(mesh.uservert), np.array(again.mesh(mesh.name).uservert))
    geom, crown = foliage.crown_envelopes(compose_scene(make_config(scenario={"town": TOWN}))[0])[0]
    tree = geom.name.removesuffix(foliage.CROWN_SUFFIX)
    first = foliage.leaf_clusters(crown, foliage.crown_rng(0, tree))
    assert not np.array_equal(first.centres_m, foliage.leaf_clusters(crown, foliage.crown_rng(1, tree)).centres_m)
    assert not np.array_equal(first.centres_m, foliage.leaf_clusters(crown, foliage.crown_rng(0, tree + "x")).centres_m)


# Crowns of the towns' smallest and largest trees (add_tree: semi-axes 0.25 h, 0.25 h, 0.33 h), and a flattened one.
CROWNS = [foliage.Crown(np.array([10.0, -4.0, 0.7 * h]), np.array([0.25 * h, 0.25 * h, 0.33 * h])) for h in (5.0, 12.0)]
CROWNS.append(foliage.Crown(np.array([0.0, 0.0, 6.0]), np.array([3.0, 2.0, 1.5])))


@pytest.mark.parametrize("crown", CROWNS, ids=["h5", "h12", "flattened"])
def test_clusters_lie_inside_the_envelope_with_gaps_at_the_stated_porosity(crown):
    clusters = foliage.leaf_clusters(crown, np.random.default_rng(7))
    vertices, faces, texcoords = foliage.crown_mesh(crown, clusters)
    assert faces.max() < len(vertices) and texcoords.shape == (len(vertices), 2)
    # Every vertex (and so every face: the envelope is convex) lies inside the envelope.
    assert ((vertices / crown.semi_axes_m) ** 2).sum(axis=1).max() <= 1.0 + 1e-9
    # Every cluster, the ellipsoid the faces approximate, lies inside it too: its normalised centre + its scale.
    normalised = np.linalg.norm((clusters.centres_m - crown.centre_m) / crown.semi_axes_m, axis=1)
    assert (normalised + clusters.scales).max() <= 1.0 + 1e-9
    horizontal_radius_m = clusters.scales * crown.semi_axes_m.min()
    assert horizontal_radius_m.min() >= min(foliage.CLUSTER_RADIUS_M[0], 0.4 * crown.semi_axes_m.min()) - 1e-9
    assert horizontal_radius_m.max() <= foliage.CLUSTER_RADIUS_M[1] + 1e-9
    for azimuth in foliage.VIEW_AZIMUTHS_DEG:
        # Drawing stops at the first cluster that closes the gaps to the target in the last open view, so the
        # crown is at the target or below it, but not closed (the towns' crowns: 0.118-0.19).
        assert 0.08 < foliage.silhouette_porosity(crown, clusters, foliage.horizontal_view(azimuth)) <= foliage.CROWN_POROSITY
    # Between the judged views, and from above, the background still shows through (but not through most of it).
    for view in (foliage.horizontal_view(20.0), foliage.horizontal_view(70.0), np.array([0.0, 0.0, 1.0])):
        assert 0.08 < foliage.silhouette_porosity(crown, clusters, view) < 0.35


def test_porosity_counts_the_uncovered_part_of_the_silhouette():
    crown = foliage.Crown(np.zeros(3), np.array([2.0, 2.0, 2.0]))
    one = foliage.LeafClusters(np.zeros((1, 3)), np.full((1, 3), 1.0), np.array([0.5]))
    # A centred cluster half the envelope's size covers a quarter of its silhouette, from any side.
    for view in (foliage.horizontal_view(0.0), foliage.horizontal_view(33.0), np.array([0.0, 0.0, 1.0])):
        assert foliage.silhouette_porosity(crown, one, view) == pytest.approx(0.75, abs=0.01)
    empty = foliage.LeafClusters(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    assert foliage.silhouette_porosity(crown, empty, foliage.horizontal_view(0.0)) == 1.0


# Two views of the tree, from 30 m: along the road (the car's view) and diagonally across it.
CAMERA_AZIMUTHS_DEG = (180.0, 225.0)


def _tree_on_its_own(foliage_name: str) -> mujoco.MjModel:
    """A 9 m tree alone at the origin, seen by a camera 30 m away at each of CAMERA_AZIMUTHS_DEG, aimed at its crown."""
    spec = mujoco.MjSpec()
    sky.add_sky(spec, ScenarioConfig())
    props.add_materials(spec)
    props.add_tree(spec, "tree", 0.0, 0.0, 9.0)
    if foliage_name == "clusters":
        foliage.replace_crowns_with_clusters(spec, layout_seed=0)
    for k, azimuth_deg in enumerate(CAMERA_AZIMUTHS_DEG):
        azimuth = np.radians(azimuth_deg)
        position = 30.0 * np.array([np.cos(azimuth), np.sin(azimuth), 0.0]) + [0.0, 0.0, 6.3]
        right = [-np.sin(azimuth), np.cos(azimuth), 0.0]  # the camera looks along -z = -(right x up): at the tree
        spec.worldbody.add_camera(name=f"view_{k}", pos=position.tolist(), xyaxes=[*right, 0.0, 0.0, 1.0], fovy=15.0)
    spec.visual.global_.offwidth, spec.visual.global_.offheight = 320, 320
    return spec.compile()


def _renders(foliage_name: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per camera: (320, 320) bool, where the crown is the nearest surface, and the (320, 320, 3) colour render."""
    model = _tree_on_its_own(foliage_name)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    segment = OffscreenRenderer(model, 320, 320, segmentation=True)
    colour = OffscreenRenderer(model, 320, 320, segmentation=False)
    views = []
    for camera_id in range(model.ncam):
        ids = segment.render(data, camera_id, mujoco.MjvOption()).astype(np.int32)
        geom_ids = segment.geom_id_lookup()[ids[..., 0] | (ids[..., 1] << 8) | (ids[..., 2] << 16)]
        views.append((geom_ids == model.geom("tree/crown").id, colour.render(data, camera_id, mujoco.MjvOption()).copy()))
    segment.close()
    colour.close()
    return views


def test_a_render_shows_the_background_through_the_crown():
    for (solid_crown, solid_rgb), (cluster_crown, cluster_rgb) in zip(_renders("solid"), _renders("clusters")):
        assert solid_crown.sum() > 10_000  # the crown fills much of the view
        # Inside the solid crown's outline, the clusters leave gaps: sky or trunk, not crown.
        see_through = 1.0 - cluster_crown[solid_crown].mean()
        assert 0.08 < see_through < 0.35
        # ...and the colour pixels there differ from the solid crown's: the background shows.
        changed = np.abs(cluster_rgb.astype(int) - solid_rgb.astype(int)).max(axis=2) > 40
        assert changed[solid_crown].mean() > 0.05
        # Nothing of the crown lies outside the solid crown's outline (one pixel of rasterisation aside).
        grown = solid_crown.copy()
        for axis in (0, 1):
            grown |= np.roll(solid_crown, 1, axis) | np.roll(solid_crown, -1, axis)
        assert cluster_crown[~grown].mean() < 0.002
