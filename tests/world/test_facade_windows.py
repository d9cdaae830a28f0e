"""Facade windows as geometry (`scenario.facade_windows = "geometry"`): a named choice, the texture's windows at
the texture's size and place, quads facing out of the face and standing proud of the wall, every facade box
given its wall material, and the default scene without any of it."""

import mujoco
import numpy as np
import pytest

from avsim.config import ScenarioConfig
from avsim.errors import ConfigError
from avsim.world import facade_windows as fw
from avsim.world import props
from avsim.world import surface_textures as st
from avsim.world.scene import compose_scene
from helpers import make_config

TOWN = "town03"  # rows of buildings on both sides of the road, and a scene that builds in a fraction of a second


@pytest.fixture(scope="module")
def texture_and_geometry():
    """The Town03 scene's spec with the windows painted (the default) and built."""
    return {name: compose_scene(make_config(scenario={"town": TOWN, "facade_windows": name}))[0]
            for name in ("texture", "geometry")}


def test_facade_windows_is_a_named_choice():
    with pytest.raises(ConfigError, match=r"scenario.facade_windows must be one of texture, geometry, got 'glass'"):
        ScenarioConfig(facade_windows="glass")


def test_a_face_gets_one_window_per_whole_bay_and_storey_at_the_textures_size_and_place():
    frames, upper, lower = fw.window_rects(width_m=11.0, height_m=7.2)  # 4 bays (1 m left over), 2 storeys
    assert len(frames) == 8 and len(upper) == len(lower) == 16
    widths = {round(u1 - u0, 6) for u0, _, u1, _ in frames}
    heights = {round(v1 - v0, 6) for _, v0, _, v1 in frames}
    assert widths == {round(st.WINDOW_RIGHT_M - st.WINDOW_LEFT_M, 6)} == {1.4}
    assert heights == {round(st.WINDOW_SILL_M - st.WINDOW_HEAD_M, 6)} == {1.6}
    # The bays are centred: the first window starts 0.5 m (half the left-over) plus its place in the bay.
    assert min(u0 for u0, *_ in frames) == pytest.approx(0.5 + st.WINDOW_LEFT_M)
    # Each storey's window head lies WINDOW_HEAD_M below its top (3.5 m, 7.0 m).
    assert sorted({round(v1, 6) for *_, v1 in frames}) == [pytest.approx(3.5 - 0.9), pytest.approx(7.0 - 0.9)]
    for pane in upper + lower:  # every pane inside a frame, the bars between them
        assert any(f[0] < pane[0] < pane[2] < f[2] and f[1] < pane[1] < pane[3] < f[3] for f in frames)
    assert fw.window_rects(2.4, 20.0) == ([], [], [])  # no whole bay, no window


def test_the_upper_panes_are_lighter_as_the_textures_sky_reflection_makes_them():
    upper, lower = fw.pane_gains()
    assert st.GLASS_GAIN_SILL < lower < upper < st.GLASS_GAIN_HEAD


@pytest.mark.parametrize("centre_y", [20.0, -20.0])
def test_the_quads_face_out_of_the_street_face_and_both_ends(centre_y):
    centre, half = np.array([5.0, centre_y, 15.0]), np.array([10.0, 8.0, 15.0])
    faces = fw.faces_of(centre, half)
    towards_road = -np.sign(centre_y)
    assert [tuple(f.normal) for f in faces] == [(0.0, towards_road, 0.0), (-1.0, 0.0, 0.0), (1.0, 0.0, 0.0)]
    for face in faces:
        corners = face.corners(np.array([[1.0, 2.0, 3.0, 5.0]]), proud_m=0.06)[0]
        winding = np.cross(corners[1] - corners[0], corners[2] - corners[0])
        assert np.dot(winding, face.normal) > 0  # counter-clockwise seen from outside: drawn from the road
        # 6 cm in front of the box's face, inside its outline
        distance_from_centre = np.dot(corners - centre, face.normal)
        assert np.allclose(distance_from_centre, np.dot(half, np.abs(face.normal)) + 0.06)
        assert np.all(np.abs(corners - centre)[:, 2] <= half[2])
        along = np.abs(np.dot(corners - centre, face.along))
        assert np.all(along <= np.dot(half, np.abs(face.along)) + 1e-9)


def test_every_facade_box_gets_its_wall_and_three_window_meshes(texture_and_geometry):
    painted, built = texture_and_geometry["texture"], texture_and_geometry["geometry"]
    buildings = [g.name for g in painted.geoms if g.material in props.FACADES]
    assert len(buildings) > 10
    materials = {g.name: g.material for g in built.geoms}
    assert all(materials[name] == fw.wall_material(painted.geom(name).material) for name in buildings)
    window_geoms = [g for g in built.geoms if "/window_" in g.name]
    assert len(window_geoms) == 3 * len(buildings)
    assert all(g.type == mujoco.mjtGeom.mjGEOM_MESH and g.contype == 0 and g.conaffinity == 0 for g in window_geoms)
    # The painted scene is untouched: no wall materials in use, no window geometry.
    assert not any("/window_" in g.name for g in painted.geoms)
    assert not any(g.material.endswith("_wall") for g in painted.geoms)
    built.compile()  # the open quads compile (shell inertia)


def test_the_textured_wall_is_the_facade_texture_without_its_window():
    windowed = st.facade_textures(props.FACADE_COLOURS)
    walls = st.facade_textures(props.FACADE_COLOURS, windows=False)
    for name in props.FACADES:
        # Above the window (the top 0.9 m less the frame's half), the two textures are the same wall and grain.
        rows = int(st.WINDOW_HEAD_M * 100) - 4
        assert np.array_equal(windowed[name][:rows], walls[name][:rows])
        window = walls[name][100:240, 60:190].astype(float)
        assert np.abs(window.mean(axis=(0, 1)) - np.array(props.FACADE_COLOURS[name][0]) * 255).max() < 3
