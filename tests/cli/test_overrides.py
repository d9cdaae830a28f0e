"""`--set KEY=VALUE` parsing (avsim/cli/overrides.py)."""

import pytest

from avsim.cli.overrides import merge_overrides, parse_set
from avsim.errors import ConfigError


def test_nests_dotted_keys():
    assert parse_set(["policy.baseline_brake=0.9", "policy.name=adjusted", "scenario.seed=3"]) == {
        "policy": {"baseline_brake": 0.9, "name": "adjusted"},
        "scenario": {"seed": 3},
    }


def test_deeper_nesting_and_top_level_key():
    assert parse_set(["a.b.c=1", "top=2"]) == {"a": {"b": {"c": 1}}, "top": 2}


@pytest.mark.parametrize(
    "raw, expected, kind",
    [
        ("0.9", 0.9, float),
        ("85.0", 85.0, float),
        ("1e3", 1000.0, float),
        ("3", 3, int),
        ("-2", -2, int),
        ("true", True, bool),
        ("false", False, bool),
        ("town03", "town03", str),
        ('"quoted"', "quoted", str),
        ("textures/faded.png", "textures/faded.png", str),
    ],
)
def test_types_values(raw, expected, kind):
    value = parse_set([f"k={raw}"])["k"]
    assert value == expected
    assert type(value) is kind


def test_later_value_wins():
    assert parse_set(["policy.name=baseline", "policy.name=adjusted"]) == {"policy": {"name": "adjusted"}}


@pytest.mark.parametrize("item", ["nonsense", "=5", ""])
def test_rejects_malformed_items(item):
    with pytest.raises(ConfigError) as excinfo:
        parse_set([item])
    assert "\n" not in str(excinfo.value)
    assert "KEY=VALUE" in str(excinfo.value)




def test_merge_overrides_merges_nested_keys_and_the_later_value_wins():
    base = {"policy": {"name": "baseline", "trigger_dist_m": 40.0}, "seed": 1}
    assert merge_overrides(base, {"policy": {"name": "adjusted"}, "seed": 2}) == {
        "policy": {"name": "adjusted", "trigger_dist_m": 40.0}, "seed": 2}
    assert base["policy"]["name"] == "baseline"  # not changed in place
