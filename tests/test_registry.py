"""Named registries: the generic class and the real town / placement / policy entries."""

import pytest

from avsim.errors import ConfigError
from avsim.registry import Registry


def test_add_get_names_contains():
    reg: Registry[int] = Registry("widget")
    assert reg.add("b", 2) == 2
    reg.add("a", 1)
    assert reg.get("a") == 1
    assert reg.get("b") == 2
    assert reg.names() == ["a", "b"]
    assert list(reg) == ["a", "b"]
    assert "a" in reg
    assert "c" not in reg


def test_register_decorator_adds_and_returns_entry():
    reg: Registry[object] = Registry("thing")

    @reg.register("x")
    def make_x():
        return "x"

    assert reg.get("x") is make_x
    assert make_x() == "x"


def test_duplicate_add_raises():
    reg: Registry[int] = Registry("widget")
    reg.add("a", 1)
    with pytest.raises(ValueError, match="'a'"):
        reg.add("a", 2)
    assert reg.get("a") == 1


def test_unknown_name_raises_config_error_listing_valid_names():
    reg: Registry[int] = Registry("widget")
    reg.add("alpha", 1)
    reg.add("beta", 2)
    with pytest.raises(ConfigError) as excinfo:
        reg.get("gamma")
    msg = str(excinfo.value)
    assert "\n" not in msg
    assert "widget" in msg and "gamma" in msg
    assert "alpha" in msg and "beta" in msg


def test_town_and_placement_registries_are_populated():
    from avsim.world.towns import PLACEMENTS, TOWNS

    for town in ("town03", "town07", "town10"):
        assert town in TOWNS
    assert set(PLACEMENTS.names()) >= {"standard", "near", "far"}


def test_placements_are_ordered_near_standard_far():
    from avsim.world.towns import PLACEMENTS

    near, standard, far = PLACEMENTS.get("near"), PLACEMENTS.get("standard"), PLACEMENTS.get("far")
    assert near < standard < far
    assert near == pytest.approx(0.5)
    assert standard == pytest.approx(2.0)
    assert 5.0 <= far <= 6.0


def test_policy_registry_is_populated():
    from avsim.control.policies import POLICIES

    for name in ("baseline", "adjusted", "side_camera", "autopilot", "combined"):
        assert name in POLICIES
        assert callable(POLICIES.get(name))
