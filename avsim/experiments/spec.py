"""Experiment files (`experiments/*.toml`): small overrides of the defaults, as named cells.

    title = "Table III: stopping positions, Town07 standard"
    seeds = 5                       # each cell runs with scenario.seed = 0 .. seeds-1 (default 5)
    [defaults]                      # applied to every cell; the same keys as `avsim run --set`
    scenario = { town = "town07", placement = "standard", speed_kmh = 85 }
    [vary]                          # optional: drawn per seed, uniformly from [low, high]
    scenario = { sun_elevation_deg = [30, 70] }
    [[cells]]
    name = "clean sign, baseline"
    scenario = { sign = "clean" }
    policy = { name = "baseline" }

A cell's config is `SimConfig()` with the defaults, then the cell's own keys, on top.
Everything a run needs is checked when the file is loaded, so a typo fails before a
long batch starts: unknown keys, wrong types and out-of-range values (by the config
dataclasses) and registry names (town, placement, policy, perception). Sign textures
are the exception: the scene resolves them when it is built, so a file may name a
texture that an attack run has not written yet. A policy or perception key that a cell sets
must be read by the cell's policy or perception, and a key of `[defaults]` or `[vary]` by at
least one cell (`avsim.config_owners`).

What differs between the runs of one cell: `scenario.seed`, which seeds the start
jitter (up to `scenario.start_jitter_m` along the road) and the camera's sensor noise
(`perception.sensor_noise_std` sets its level), and the keys in `[vary]`, drawn from a
generator seeded by the run's seed alone, so seed k has the same lighting in every cell
and cells compare in pairs. Because `runs()` sets the seed, a file may not set
`scenario.seed` itself.

Every error is a one-line `ConfigError` that names the file, where in it (for example
`cells[2] "attacked sign, adjusted"`) and the key.
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from avsim.config import NO_SIGN, SimConfig, with_overrides
from avsim.config_owners import check_read, check_read_by_some, dotted_keys, set_keys
from avsim.errors import AvsimError, ConfigError
from avsim.experiments.plan_size import MAX_RUNS
from avsim.file_kinds import special_file_kind

TOP_LEVEL_KEYS = ("title", "seeds", "report", "compare_with", "defaults", "vary", "cells")
# The section `avsim reproduce` writes for an experiment, declared by the file (`report = "..."`),
# so a new experiment needs no code change in the report: "cells" (the default) is the table of
# every cell's results; "table3", "table1", "table2" and "fig3" set the cells beside the study's
# figures of that name; "adaptive" answers whether the side camera holds; "compare" sets each
# cell beside the same-named cell of the experiment named by `compare_with` (a file stem);
# "sensitivity" gives one table per policy or perception constant that varies across the cells.
# "stop_rates" gives each policy's stop rate per town and placement with its Wilson interval.
# "attack_success" gives each cell's closed-loop attack success rate, overrun and braking delay
# against the clean cell of the same town, placement, policy and perception (`avsim.experiments.attacks.success`).
REPORT_KINDS = ("cells", "table3", "table1", "table2", "fig3", "adaptive", "compare", "sensitivity", "stop_rates",
                "attack_success")
DEFAULT_SEEDS = 5
# Second word of the [vary] generator's seed, so its draws are independent of the start
# jitter, which ClosedLoop draws from default_rng(scenario.seed).
_VARY_STREAM = 1
# Drawn values are rounded so the saved configs read cleanly; far below any lighting effect.
_VARY_DECIMALS = 3


@dataclass(frozen=True)
class Cell:
    """One named cell of a table or figure: a fully resolved config.

    `config.scenario.seed` is the default (0); `Experiment.runs()` sets it per run.
    keys_set: the dotted keys the file sets for this cell, in [defaults] or the cell itself
    (`scenario.town`, ...): what a render setting applied over the file must leave alone.
    """

    name: str
    config: SimConfig
    keys_set: frozenset[str] = frozenset()


class Run(NamedTuple):
    """One simulation of an experiment: a cell at one seed, with its final config."""

    cell_name: str
    seed: int
    config: SimConfig


@dataclass(frozen=True)
class Experiment:
    """A loaded experiment file.

    vary: (dotted key, low, high) per key drawn uniformly per seed, sorted by key.
    """

    path: Path
    title: str
    seeds: int
    cells: tuple[Cell, ...]
    vary: tuple[tuple[str, float, float], ...] = ()
    report: str = "cells"  # one of REPORT_KINDS
    compare_with: str | None = None  # with report = "compare": the stem of the other experiment file

    @property
    def name(self) -> str:
        """The file's stem, which names the experiment in results and reports."""
        return self.path.stem

    def cell(self, name: str | None = None) -> Cell:
        """The cell called `name`; the first cell when `name` is None."""
        if name is None:
            return self.cells[0]
        for cell in self.cells:
            if cell.name == name:
                return cell
        names = ", ".join(f'"{c.name}"' for c in self.cells)
        raise ConfigError(f"{self.path}: no cell named \"{name}\"; cells: {names}")

    @property
    def size(self) -> int:
        """The number of runs: cells x seeds, counted without building any."""
        return len(self.cells) * self.seeds

    def runs(self) -> list[Run]:
        """Every cell at seeds 0 .. seeds-1, cell by cell."""
        return list(self.iter_runs())

    def iter_runs(self) -> Iterator[Run]:
        """`runs`, one at a time: each config is built when it is asked for."""
        return (Run(cell.name, seed, self.config_for(cell, seed)) for cell in self.cells for seed in range(self.seeds))

    def config_for(self, cell: Cell, seed: int) -> SimConfig:
        """`cell`'s config for one run: scenario.seed = `seed`, [vary] keys drawn from `seed`."""
        return config_at_seed(cell.config, self.vary, seed)


def config_at_seed(config: SimConfig, vary: tuple[tuple[str, float, float], ...], seed: int) -> SimConfig:
    """`config` for the run at `seed`: scenario.seed = `seed`, and each (dotted key, low, high) of
    `vary` drawn uniformly from a generator seeded by `seed` alone, so seed k draws the same
    values whatever the config."""
    rng = np.random.default_rng((seed, _VARY_STREAM))
    overrides: dict[str, Any] = {"scenario": {"seed": seed}}
    for key, low, high in vary:
        overrides = deep_merge(overrides, nested(key, round(float(rng.uniform(low, high)), _VARY_DECIMALS)))
    return with_overrides(config, overrides)


# A top-level key only one kind of file holds, and the command that runs that kind.
FILE_KINDS = {"grid": "avsim sweep", "cells": "avsim reproduce", "defences": "avsim leaderboard"}
KIND_COMMANDS = {"sweep": "avsim sweep", "experiment": "avsim reproduce", "leaderboard": "avsim leaderboard"}


def read_run_file(path: Path, kind: str, top_level_keys: tuple[str, ...], default_seeds: int) -> tuple[dict[str, Any], str, int]:
    """Read a TOML file of runs (an experiment or a sweep): (the raw table, its title, its seeds).

    kind names the file in errors ("experiment", "sweep"); unknown top-level keys, a title that
    is not a string and seeds that are not an integer >= 1 are one-line ConfigErrors.
    """
    if special := special_file_kind(path):  # /dev/zero would be read until memory runs out
        raise ConfigError(f"{path} is {special}, not a regular file; give the {kind} file itself")
    try:
        with path.open("rb") as handle:
            raw = tomllib.load(handle)
    except FileNotFoundError:
        raise ConfigError(f"{path}: {kind} file not found; check the path, or start from one of the files in "
                          f"{'experiments/sweeps/' if kind == 'sweep' else 'experiments/'}") from None
    except tomllib.TOMLDecodeError as exc:
        if path.read_bytes().startswith(b"\xef\xbb\xbf"):  # tomllib's message would point at line 1, column 1
            raise ConfigError(f"{path} starts with a UTF-8 byte-order mark, as some editors save text; save it as UTF-8 "
                              "without one") from None
        # tomllib's message names the line and column: "... (at line 3, column 7)".
        raise ConfigError(f"{path}: malformed TOML: {exc}; fix that line (TOML syntax: https://toml.io)") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not a text TOML file (byte {exc.start} is not UTF-8); give the {kind} file "
                          f"as TOML text, like those in experiments/") from None
    except IsADirectoryError:
        raise ConfigError(f"{path} is a folder; give the {kind} file itself (a .toml file, like those in "
                          f"{'experiments/sweeps/' if kind == 'sweep' else 'experiments/'})") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read {kind} file ({exc.strerror})") from None

    unknown = sorted(set(raw) - set(top_level_keys))
    for key, command in FILE_KINDS.items():
        if key in unknown and command != KIND_COMMANDS[kind]:
            article = "an" if kind[0] in "aeiou" else "a"
            raise ConfigError(f"{path} holds [{key}], so it is a file for `{command}`, not {article} {kind} file; run it "
                              f"with `{command}`")
    if unknown:
        raise ConfigError(f"{path}: unknown top-level key '{unknown[0]}'; valid keys: {', '.join(top_level_keys)}")
    title = raw.get("title", path.stem)
    if not isinstance(title, str):
        raise ConfigError(f"{path}: 'title' must be a string, got {title!r}")
    seeds = raw.get("seeds", default_seeds)
    if type(seeds) is not int or not 1 <= seeds <= MAX_RUNS:
        raise ConfigError(f"{path}: 'seeds' must be an integer >= 1 (and at most {MAX_RUNS:,}), got {seeds!r}")
    return raw, title, seeds


def load_experiment(path: str | os.PathLike) -> Experiment:
    """Read and check an experiment file; see the module docstring for its format."""
    path = Path(path)
    raw, title, seeds = read_run_file(path, "experiment", TOP_LEVEL_KEYS, DEFAULT_SEEDS)
    with located(path, "[defaults]"):
        defaults = as_table(raw.get("defaults", {}), "defaults")
        reject_seed(defaults)
        check_registry_names(with_overrides(SimConfig(), defaults))
    with located(path, "[vary]"):
        vary = parse_vary(raw.get("vary", {}))
    report, compare_with = _parse_report(path, raw)
    cells = _parse_cells(path, raw.get("cells"), defaults, vary)
    # [defaults] and [vary] apply to every cell: a key there needs one cell that reads it.
    for where, keys in (("[defaults]", set_keys(defaults)), ("[vary]", {key for key, _, _ in vary})):
        with located(path, where):
            check_read_by_some((cell.config for cell in cells), keys, runs="cell")
    return Experiment(path=path, title=title, seeds=seeds, cells=cells, vary=vary, report=report, compare_with=compare_with)


def _parse_report(path: Path, raw: Mapping[str, Any]) -> tuple[str, str | None]:
    """The declared report kind and, for "compare", the experiment it compares with."""
    report = raw.get("report", "cells")
    if report not in REPORT_KINDS:
        raise ConfigError(f"{path}: 'report' must be one of {', '.join(REPORT_KINDS)}, got {report!r}")
    compare_with = raw.get("compare_with")
    if (report == "compare") != (compare_with is not None):
        raise ConfigError(f"{path}: 'compare_with' (the stem of another experiment file) goes with report = \"compare\", and only with it")
    if compare_with is not None and (not isinstance(compare_with, str) or not compare_with.strip()):
        raise ConfigError(f"{path}: 'compare_with' must name another experiment file by its stem, got {compare_with!r}")
    return report, compare_with


# ---- parts of the file -------------------------------------------------------------------

def _parse_cells(path: Path, raw_cells: Any, defaults: dict[str, Any],
                 vary: tuple[tuple[str, float, float], ...]) -> tuple[Cell, ...]:
    if not isinstance(raw_cells, list) or not raw_cells:
        raise ConfigError(f"{path}: no cells; add at least one [[cells]] table with a name")
    cells: list[Cell] = []
    for index, raw_cell in enumerate(raw_cells):
        where = f"cells[{index}]"
        with located(path, where):
            overrides = dict(as_table(raw_cell, where))
            name = overrides.pop("name", None)
            if not isinstance(name, str) or not name.strip():
                raise ConfigError(f"'name' must be a non-empty string, got {name!r}")
        where = f'{where} "{name}"'
        with located(path, where):
            if any(c.name == name for c in cells):
                raise ConfigError("duplicate cell name; each cell needs its own")
            reject_seed(overrides)
            config = with_overrides(SimConfig(), deep_merge(defaults, overrides))
            check_registry_names(config)
            check_read(config, set_keys(overrides))  # a key the cell sets, its policy and perception read
        # Both ends of every [vary] range must be valid for this cell, so every draw is.
        with located(path, f"[vary], applied to {where}"):
            for key, low, high in vary:
                for value in (low, high):
                    with_overrides(config, nested(key, value))
        cells.append(Cell(name, config, dotted_keys(deep_merge(defaults, overrides))))
    return tuple(cells)


def parse_vary(raw: Any) -> tuple[tuple[str, float, float], ...]:
    """An experiment file's [vary] table as ("section.key", low, high) ranges, each checked to be a
    numeric config key with low <= high; scenario.seed cannot vary.
    """
    ranges = []
    for section, keys in as_table(raw, "vary").items():
        for key, bounds in as_table(keys, f"vary.{section}").items():
            dotted = f"{section}.{key}"
            if dotted == "scenario.seed":
                raise ConfigError("scenario.seed cannot vary: it is the run's seed, set by 'seeds'")
            numeric = isinstance(bounds, list) and len(bounds) == 2 and all(
                isinstance(b, (int, float)) and not isinstance(b, bool) for b in bounds)
            if not numeric or not bounds[0] <= bounds[1]:
                raise ConfigError(f"'{dotted}' must be a range [low, high] of two numbers with low <= high, got {bounds!r}")
            # Floats only: an int field rejects the float, naming the key.
            with_overrides(SimConfig(), nested(dotted, float(bounds[0])))
            ranges.append((dotted, float(bounds[0]), float(bounds[1])))
    return tuple(sorted(ranges))


def check_registry_names(config: SimConfig) -> None:
    """Fail on an unknown town, placement, policy or perception, as the run would later, and on a
    network arithmetic this CPU cannot run (bf16 without oneDNN's bf16 kernels)."""
    # Imported here: the registries pull in the world, control and perception packages.
    from avsim.control.policies import POLICIES
    from avsim.perception.factory import PERCEPTIONS, network_arithmetics
    from avsim.plausibility import check_meaningful
    from avsim.world.towns import PLACEMENTS, TOWNS

    for key, registry, name in (("scenario.town", TOWNS, config.scenario.town),
                                ("scenario.placement", PLACEMENTS, config.scenario.placement),
                                ("policy.name", POLICIES, config.policy.name),
                                ("perception.kind", PERCEPTIONS, config.perception.kind)):
        if name not in registry:
            try:
                registry.get(name)
            except ConfigError as exc:
                raise ConfigError(f"{key}: {exc}") from None
    network_arithmetics(config.perception)  # refuses bf16 where this CPU has no bf16 kernels
    check_meaningful(config)


def check_networks(config: SimConfig) -> None:
    """The run's perception networks build (`factory.check_networks_build`, once per distinct set of
    files): the batch commands check every config they will run so, and a missing or corrupt weights
    file stops the batch in one line before its results folder is made, not run by run. Not part of
    loading a file: `avsim run --config` builds its one cell's networks anyway."""
    from avsim.perception.factory import check_networks_build

    check_networks_build(config.perception)


def check_renderer(config: SimConfig) -> None:
    """This machine's GL can draw the run's frames as its config asks (`camera.texture_anisotropy`): the
    batch commands check every config they will run so, beside `check_networks`, and a GL that filters
    less is refused in one line before the results folder is made, not by each run's renderer."""
    # Imported here, as the networks are above: the GL bindings load only for a command that renders.
    from avsim.sensors.gl import check_texture_anisotropy

    check_texture_anisotropy(config.camera.texture_anisotropy)


def check_run_names(config: SimConfig) -> Path | None:
    """Registry names (town, placement, policy, perception) and the sign texture, decoded as the
    scene will decode it (a PNG of a stop sign's square shape); returns the texture's resolved
    path, or None when the scenario has no stop sign (scenario.sign = "none")."""
    from avsim.world.scene import resolve_sign_texture
    from avsim.world.textures import load_texture_png

    check_registry_names(config)
    sign = config.scenario.sign
    if sign == NO_SIGN:
        return None
    try:
        texture = resolve_sign_texture(sign)
        load_texture_png(texture, expected_aspect=1.0)
    except AvsimError as exc:  # an unknown name, or a file that is no usable PNG (TextureError)
        raise ConfigError(f"scenario.sign: {exc}") from None
    return texture.resolve()


def reject_seed(overrides: Mapping[str, Any]) -> None:
    """Refuse overrides that set scenario.seed: a batch sets it per run from its 'seeds'."""
    scenario = overrides.get("scenario")
    if isinstance(scenario, Mapping) and "seed" in scenario:
        raise ConfigError("scenario.seed is set per run (0 .. seeds-1); set the top-level 'seeds' instead")


# ---- helpers -------------------------------------------------------------------------------

@contextmanager
def located(path: Path, where: str) -> Iterator[None]:
    """Prefix a ConfigError raised inside with the file and the place in it."""
    try:
        yield
    except ConfigError as exc:
        raise ConfigError(f"{path}: {where}: {exc}") from None


def as_table(value: Any, name: str) -> dict[str, Any]:
    """`value` as a dict, or a one-line ConfigError naming `name` when it is not a TOML table."""
    if not isinstance(value, Mapping):
        raise ConfigError(f"'{name}' must be a table of keys, got {value!r}")
    return dict(value)


def nested(dotted: str, value: Any) -> dict[str, Any]:
    """A dotted key and its value as a nested override: ("a.b", 1) -> {"a": {"b": 1}}."""
    node: Any = value
    for part in reversed(dotted.split(".")):
        node = {part: node}
    return node


def deep_merge(base: Mapping[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    """`extra` laid over `base`, nested tables merged key by key (the later value wins); inputs unchanged."""
    merged = dict(base)
    for key, value in extra.items():
        both_tables = isinstance(value, Mapping) and isinstance(merged.get(key), Mapping)
        merged[key] = deep_merge(merged[key], value) if both_tables else value
    return merged
