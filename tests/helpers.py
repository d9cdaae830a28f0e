"""Test helpers importable from any test module (`from helpers import make_config`).

They live outside conftest.py because a second conftest (tests/perception/detector/)
would shadow a `from helpers import ...`.
"""

from __future__ import annotations

from avsim.config import SimConfig, with_overrides


def make_config(**sections) -> SimConfig:
    """SimConfig with per-section overrides, e.g. make_config(scenario={"town": "town03"}).

    Tests use the `oracle` perception unless they name another: physics and policy tests
    must not depend on how well the learned detector happens to be trained.
    """
    sections = {**sections, "perception": {"kind": "oracle", **sections.get("perception", {})}}
    return with_overrides(SimConfig(), sections)
