"""The validation layer (`avsim.validation`): declared ranges, and random values at every numeric key.

Property-style: a seeded numpy generator throws values at every numeric config key, NaN,
infinities, huge, negative and in-range ones alike, each written as `--set KEY=VALUE` text. Each
must be accepted or refused with one ConfigError line naming the key, never anything else; the
slow variant runs the accepted ones, which must end as a clean run or a one-line refusal.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import typing

import numpy as np
import pytest

from avsim import cli
from avsim.cli.overrides import parse_set
from avsim.config import SimConfig, with_overrides
from avsim.errors import ConfigError
from avsim.experiments.spec import check_run_names
from avsim.plausibility import check_meaningful
from avsim.validation import Range, check_span, declared_ranges, name_list_flag, number_flag, number_list_flag, ranged


def _numeric_keys() -> list[tuple[str, Range | None, type]]:
    """(dotted key, declared range, int or float) of every scalar numeric field of SimConfig."""
    keys = []
    for section in dataclasses.fields(SimConfig):
        cls = section.default_factory  # type: ignore[misc]
        hints = typing.get_type_hints(cls)
        ranges = declared_ranges(cls)
        for f in dataclasses.fields(cls):
            if typing.get_origin(hints[f.name]) is tuple:  # regions of interest: lists of ints, checked as a whole
                continue
            options = typing.get_args(hints[f.name]) or (hints[f.name],)
            kind = next((k for k in options if k in (int, float)), None)
            if kind is not None:
                keys.append((f"{section.name}.{f.name}", ranges.get(f.name), kind))
    return keys


NUMERIC_KEYS = _numeric_keys()
# Choices, not ranges: these take one of a few listed values (checked by their dataclass).
LISTED_VALUES = {"camera.offsamples", "camera.seg_supersample", "camera.supersample", "camera.texture_anisotropy",
                 "perception.purify_median_kernel_px", "scenario.sun_shadow_map_px"}


def test_every_numeric_config_key_declares_its_range():
    undeclared = [key for key, spec, _ in NUMERIC_KEYS if spec is None and key not in LISTED_VALUES]
    assert undeclared == []
    assert len(NUMERIC_KEYS) >= 60


def test_a_range_refuses_nan_infinity_and_out_of_range_values_in_one_line():
    speed = Range(0, 200, lo_open=True, unit="km/h")
    assert speed.describe() == "in (0, 200] km/h"
    for bad in (math.nan, math.inf, -math.inf, 0, -1, 200.5, True, "85", None):
        with pytest.raises(ConfigError) as refused:
            speed.check(bad, "scenario.speed_kmh")
        assert str(refused.value).startswith("scenario.speed_kmh must be in (0, 200] km/h, got ")
    assert speed.check(200, "x") == 200
    count = Range(1, None, integer=True)
    assert count.describe() == "an integer >= 1" and not count.contains(2.0) and count.contains(2)


def test_a_default_outside_its_own_range_is_a_programming_error():
    with pytest.raises(ValueError):
        ranged(5.0, 0, 1)


def test_argparse_types_refuse_in_one_line():
    parser = argparse.ArgumentParser()
    parser.add_argument("--x", type=number_flag(0, 1, lo_open=True))
    parser.add_argument("--n", type=number_flag(1, None, integer=True))
    parser.add_argument("--budgets", type=number_list_flag(0, 1, lo_open=True))
    parser.add_argument("--towns", type=name_list_flag())
    assert parser.parse_args(["--x", "0.5", "--n", "3", "--budgets", "0.1, 0.2", "--towns", "a,b"]) == argparse.Namespace(
        x=0.5, n=3, budgets=[0.1, 0.2], towns=["a", "b"])
    for argv in (["--x", "nan"], ["--x", "0"], ["--n", "1.5"], ["--n", "0"], ["--budgets", "0.1,0.1"],
                 ["--budgets", ""], ["--towns", ","], ["--towns", "a,a"]):
        with pytest.raises(SystemExit):
            parser.parse_args(argv)


def _random_texts(rng: np.random.Generator, spec: Range | None, kind: type, n: int) -> list[str]:
    """`n` values as --set text: the specials first, then draws around (and past) the declared range."""
    specials = ["nan", "inf", "-inf", "0", "-1", "1e300", "-1e300", "1e-300", "2.5", '"7"', "true"]
    lo = spec.lo if spec is not None and spec.lo is not None else -1e3
    hi = spec.hi if spec is not None and spec.hi is not None else 1e3
    span = max(hi - lo, 1.0)
    draws = rng.uniform(lo - span, hi + span, size=n)
    texts = [str(int(round(v))) if kind is int else repr(float(v)) for v in draws]
    return specials + texts


@pytest.mark.parametrize("key, spec, kind", NUMERIC_KEYS, ids=[k for k, _, _ in NUMERIC_KEYS])
def test_random_values_at_a_numeric_key_are_accepted_or_refused_in_one_line(key, spec, kind):
    rng = np.random.default_rng(sum(key.encode()))  # the same draws in every session
    for text in _random_texts(rng, spec, kind, 24):
        try:
            config = with_overrides(SimConfig(), parse_set([f"{key}={text}"]))
            check_run_names(config)
            check_meaningful(config)
        except ConfigError as exc:
            message = str(exc)
            assert "\n" not in message and key.split(".")[-1] in message, (text, message)
            continue
        value = config
        for part in key.split("."):
            value = getattr(value, part)
        if value is not None:
            assert isinstance(value, (int, float)) and math.isfinite(value), (text, value)
            if spec is not None:
                assert spec.contains(value), (text, value)


@pytest.mark.slow  # a few minutes: one short closed-loop run per numeric key
@pytest.mark.parametrize("key, spec, kind", NUMERIC_KEYS, ids=[k for k, _, _ in NUMERIC_KEYS])
def test_a_random_accepted_value_runs_cleanly_or_is_refused_in_one_line(key, spec, kind, tmp_path, capsys):
    rng = np.random.default_rng(sum(key.encode()) + 1)
    lo = spec.lo if spec is not None and spec.lo is not None else 0
    hi = spec.hi if spec is not None and spec.hi is not None else 10
    for text in ["nan", *(str(int(v)) if kind is int else repr(float(v)) for v in rng.uniform(lo, hi, size=2))]:
        out = tmp_path / "r.json"
        argv = ["run", "--perception", "oracle", "--set", "loop.max_time_s=0.3", "--set", f"{key}={text}", "--json", str(out)]
        if key == "loop.max_time_s":
            argv = argv[:3] + argv[5:]
        status = cli.main(argv)
        err = capsys.readouterr().err
        assert "internal error" not in err and "Traceback" not in err, err
        if status == 0:
            assert out.exists()
            out.unlink()
        else:
            assert status in (2, 3) and len(err.splitlines()) <= 2, err
            assert not out.exists()


@pytest.mark.parametrize("value, named", [
    ([0.5], "a pair"), ("ab", "a pair"), ([1, 0.5], "lo <= hi"), ([0.5, 5], "in [0, 1]"), ([0.1, float("nan")], "in [0, 1]"),
])
def test_a_span_is_a_pair_in_order_inside_its_bounds(value, named):
    assert check_span([0.2, 0.2], "gain", Range(0, 1)) == (0.2, 0.2)
    with pytest.raises(ConfigError) as refused:
        check_span(value, "gain", Range(0, 1))
    assert str(refused.value).startswith("gain must be") and named in str(refused.value)


@pytest.mark.parametrize("text", ["1_00", "\u0664\u0660", "1\u00a0"])
def test_a_number_flag_reads_only_what_its_config_key_would(text):
    with pytest.raises(argparse.ArgumentTypeError, match="ASCII digits"):
        number_flag(0, 200)(text)
    assert number_flag(0, 200)("100") == 100.0 and number_flag(0, 200, integer=True)("-0") == 0
