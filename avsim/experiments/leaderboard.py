"""`avsim leaderboard`: every defence against the attacks, and against roads that need no stop.

A leaderboard file (`experiments/leaderboards/defences.toml`) declares the whole matrix as data, so a new
defence or a new texture is an edit of the file, never of code:

    title = "..."
    [defaults]                      # every run, as in experiment files (no scenario.seed)
    [vary]                          # optional: drawn per seed, as in experiment files
    [conditions.clean]              # the attacks every defence faces where a stop is required:
    scenario = { sign = "clean" }   #   "clean" and "strongest" (the strongest non-adaptive attack)
    [conditions.strongest]
    note = "..."                    #   shown in the report (e.g. that a texture is a placeholder)
    scenario = { sign = "yang" }
    [[defences]]                    # one row each
    name = "purify_jpeg"
    about = "..."                   # one line for the report
    policy = { name = "baseline" }  # the defence: any config sections
    perception = { purify = "jpeg" }
    adaptive = { scenario = { sign = "yang" } }    # its own adaptive attack (the third condition)
    adaptive_note = "..."
    [[places]]                      # towns and placements of the runs that require a stop
    town = "town07"
    placement = "standard"
    seeds = 10                      # scenario.seed = 0 .. seeds-1
    quick_seeds = 1                 # with --quick (0: left out)
    [[availability]]                # scenarios where no stop is required (phantom braking)
    name = "no stop sign"
    scenario = { sign = "none" }
    seeds = 5
    quick_seeds = 1
    defences = ["map_prior"]        # optional: only these defences run it

A run's config is `SimConfig()`, then [defaults], the place (town, placement), the defence's
keys, then the condition's (or the availability scenario's), then the seed and its [vary]
draw. Every run is checked when the file is loaded, before anything runs: config keys and
ranges, registry names, sign textures, and that every safety run requires a stop and no
availability run does. Runs with the same config (a placeholder adaptive texture that equals
the strongest attack) run once and count once per defence.

`avsim.experiments.leaderboard_run.run_leaderboard` runs the unique configs through the sweep
machinery (`resumable`: a pool or Ray, one fsynced line per run, `--resume`), then writes into its folder:
    leaderboard.toml   the file as it was run
    results.jsonl      one record per unique config (`avsim.experiments.run_task`)
    manifest.json      command, workers, wall time, runs, failures, versions
    leaderboard.md     the tables (`avsim.experiments.leaderboard_report`)
    leaderboard.png    safety against availability, one point per defence, the Pareto front marked
    set.json           the --set values every run was given, when there were any (`avsim.experiments.set_overrides`)
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from avsim.config import SimConfig, with_overrides
from avsim.config_owners import check_read, check_read_by_some, dotted_keys, set_keys
from avsim.errors import ConfigError
from avsim.experiments.plan import Plan
from avsim.experiments.plan_size import MAX_RUNS, check_plan_size
from avsim.experiments.run_task import RunSpec
from avsim.experiments.set_overrides import checked_set, flat_items, refuse_layered, set_title
from avsim.experiments.spec import (as_table, check_networks, check_renderer, check_run_names, config_at_seed, deep_merge, located, parse_vary,
                                   read_run_file, reject_seed)
from avsim.realism.settings import BASELINE

TOP_LEVEL_KEYS = ("title", "defaults", "vary", "conditions", "defences", "places", "availability")
CONDITIONS = ("clean", "strongest", "adaptive")  # "adaptive" is each defence's own
SAFETY, AVAILABILITY = "safety", "availability"
DEFAULT_FILE = Path(__file__).resolve().parents[2] / "experiments" / "leaderboards" / "defences.toml"


@dataclass(frozen=True)
class Condition:
    """Config overrides for one attack condition, and a note for the report."""

    overrides: dict[str, Any]
    note: str = ""


@dataclass(frozen=True)
class Defence:
    """One row of the board: its name, a line `about` it for the report, the config `overrides`
    (nested sections) that make the defence, and its own `adaptive` attack condition."""

    name: str
    about: str
    overrides: dict[str, Any]
    adaptive: Condition


@dataclass(frozen=True)
class Place:
    """A town and sign placement where a stop is required, run at scenario.seed 0 .. seeds - 1
    (quick_seeds of them with --quick; 0 leaves the place out)."""

    town: str
    placement: str
    seeds: int
    quick_seeds: int

    @property
    def label(self) -> str:
        """"town placement", as the report's rows name the place."""
        return f"{self.town} {self.placement}"


@dataclass(frozen=True)
class Availability:
    """A scenario where no stop is required (phantom braking): its name, the `overrides` that make
    it, its seed counts as `Place`'s, and the `defences` that run it (None: every defence)."""

    name: str
    overrides: dict[str, Any]
    seeds: int
    quick_seeds: int
    defences: tuple[str, ...] | None  # None: every defence


@dataclass(frozen=True)
class LeaderboardRun:
    """One run of the matrix: which defence, which side of the board and where, with its config.

    kind: SAFETY (condition is one of CONDITIONS, place a Place label) or AVAILABILITY
    (condition is the scenario's name, place its town and placement).
    """

    defence: str
    kind: str
    condition: str
    place: str
    seed: int
    config: SimConfig

    @property
    def label(self) -> str:
        """"defence | condition | place", the run's name in progress lines and errors."""
        return f"{self.defence} | {self.condition} | {self.place}"


@dataclass(frozen=True)
class Leaderboard:
    """A loaded leaderboard file (module docstring)."""

    path: Path
    title: str
    base: SimConfig
    vary: tuple[tuple[str, float, float], ...]
    conditions: dict[str, Condition]  # "clean", "strongest"
    defences: tuple[Defence, ...]
    places: tuple[Place, ...]
    availability: tuple[Availability, ...]
    defaults_keys: frozenset[str] = frozenset()  # the dotted keys the file's [defaults] sets
    setting: str = BASELINE  # the render setting it runs under (`avsim leaderboard --setting`)
    set_items: tuple[tuple[str, Any], ...] = ()  # the --set values in its base config: (dotted key, value), sorted

    def layers(self) -> list[tuple[str, frozenset[str]]]:
        """Where the file and its --set values set keys over the base config (where, dotted keys): none of
        them may a --setting set too."""
        return ([("[defaults]", self.defaults_keys)] + self.layers_over_base()
                + [("--set", frozenset(key for key, _ in self.set_items))])

    def layers_over_base(self) -> list[tuple[str, frozenset[str]]]:
        """The layers that runs compose over the base config ([vary], conditions, defences, places,
        availability scenarios; (where, dotted keys)): a --set, which goes into the base config, may set
        none of their keys, since those runs would keep the file's value."""
        layers = [("[vary]", frozenset(key for key, _, _ in self.vary))]
        layers += [(f'condition "{name}"', dotted_keys(c.overrides)) for name, c in self.conditions.items()]
        for defence in self.defences:
            layers += [(f'defence "{defence.name}"', dotted_keys(defence.overrides)),
                       (f'defence "{defence.name}"\'s adaptive condition', dotted_keys(defence.adaptive.overrides))]
        layers += [(f'availability scenario "{a.name}"', dotted_keys(a.overrides)) for a in self.availability]
        if self.places:
            layers.append(("[[places]]", dotted_keys(place_overrides(self.places[0]))))
        return layers

    @property
    def name(self) -> str:
        """The leaderboard file's stem (e.g. "defences")."""
        return self.path.stem

    def condition(self, defence: Defence, name: str) -> Condition:
        """The condition called `name` for `defence`: its own adaptive attack for "adaptive", else the file's."""
        return defence.adaptive if name == "adaptive" else self.conditions[name]

    def size(self, quick: bool = False) -> int:
        """How many runs `runs(quick)` holds, counted without building them."""
        safety = sum(_seed_count(place, quick) for place in self.places) * len(CONDITIONS)
        total = 0
        for defence in self.defences:
            total += safety + sum(_seed_count(scenario, quick) for scenario in self.availability
                                  if scenario.defences is None or defence.name in scenario.defences)
        return total

    def runs(self, quick: bool = False, first_seed_only: bool = False) -> list[LeaderboardRun]:
        """Every run of the matrix (with `quick`, each place's and scenario's quick_seeds), defence by defence;
        first_seed_only: only each one's seed 0 (the configs to check, not to run)."""
        return list(self.iter_runs(quick, first_seed_only))

    def iter_runs(self, quick: bool = False, first_seed_only: bool = False) -> Iterator[LeaderboardRun]:
        """`runs`, one at a time: each config is built when it is asked for."""
        for defence in self.defences:
            for place in self.places:
                for name in CONDITIONS:
                    config = self.compose(place_overrides(place), defence.overrides, self.condition(defence, name).overrides)
                    for seed in range(_seed_count(place, quick, first_seed_only)):
                        yield LeaderboardRun(defence.name, SAFETY, name, place.label, seed,
                                             config_at_seed(config, self.vary, seed))
            for scenario in self.availability:
                if scenario.defences is not None and defence.name not in scenario.defences:
                    continue
                config = self.compose({}, defence.overrides, scenario.overrides)
                where = f"{config.scenario.town} {config.scenario.placement}"
                for seed in range(_seed_count(scenario, quick, first_seed_only)):
                    yield LeaderboardRun(defence.name, AVAILABILITY, scenario.name, where, seed,
                                         config_at_seed(config, self.vary, seed))

    def plan(self, quick: bool = False) -> Plan:
        """The specs of the board's distinct configs (`unique_specs`), built only as a batch draws on
        them (`avsim.experiments.plan`); its size counts every run, repeated configs included."""
        return Plan(self.size(quick), lambda: unique_specs(self, self.iter_runs(quick)))

    def compose(self, *layers: Mapping[str, Any]) -> SimConfig:
        """The file's base config with the override `layers` merged over it in order (later wins)."""
        merged: dict[str, Any] = {}
        for layer in layers:
            merged = deep_merge(merged, layer)
        return with_overrides(self.base, merged)


def _seed_count(entry: Place | Availability, quick: bool, first_seed_only: bool = False) -> int:
    """How many seeds of a place or availability scenario a plan runs: its quick_seeds or seeds, or
    only seed 0 (first_seed_only, for checking the configs)."""
    if first_seed_only:
        return min(1, entry.seeds)
    return entry.quick_seeds if quick else entry.seeds


def unique_specs(leaderboard: Leaderboard, runs: Iterable[LeaderboardRun]) -> Iterator[RunSpec]:
    """One batch spec per distinct config, labelled by the first run that has it, as the runs come."""
    seen: set[str] = set()
    for run in runs:
        spec = RunSpec(leaderboard.name, run.label, run.seed, run.config)
        if spec.spec_hash not in seen:
            seen.add(spec.spec_hash)
            yield spec


def place_overrides(place: Place) -> dict[str, Any]:
    """The overrides that put a run at `place`: scenario.town and scenario.placement."""
    return {"scenario": {"town": place.town, "placement": place.placement}}


# ---- loading ---------------------------------------------------------------------------------

def load_leaderboard(path: str | Path = DEFAULT_FILE, *, quick: bool = False, yes: bool = False,
                     overrides: Mapping[str, Any] | None = None) -> Leaderboard:
    """Read and check a leaderboard file, every run of it (module docstring).

    quick, yes: the plan to be run (its quick seeds or all) may exceed `plan_size.RUNS_WITHOUT_YES`
    runs only with `yes`; its size is checked before any run is built. overrides: `--set` values (nested),
    over [defaults] under every run; one that a defence, condition, place, availability scenario or [vary]
    sets is refused (`avsim.experiments.set_overrides`)."""
    path = Path(path)
    overrides = overrides or {}
    keys_given = checked_set(overrides)
    raw, title, _ = read_run_file(path, "leaderboard", TOP_LEVEL_KEYS, 1)
    with located(path, "[defaults]"):
        defaults = as_table(raw.get("defaults", {}), "defaults")
        reject_seed(defaults)
        base = with_overrides(SimConfig(), defaults)
    with located(path, "--set"):
        base = with_overrides(base, overrides)
    with located(path, "[vary]"):
        vary = parse_vary(raw.get("vary", {}))
    with located(path, "[conditions]"):
        conditions = _parse_conditions(raw.get("conditions"))
    defences = tuple(_parse_defence(path, index, item) for index, item in enumerate(_array(path, raw, "defences")))
    _unique(path, "defences", [d.name for d in defences])
    places = tuple(_parse_place(path, index, item) for index, item in enumerate(_array(path, raw, "places")))
    _unique(path, "places", [p.label for p in places])
    availability = tuple(_parse_availability(path, index, item, {d.name for d in defences})
                         for index, item in enumerate(raw.get("availability", [])))
    _unique(path, "availability", [a.name for a in availability])
    board = Leaderboard(path, set_title(title, overrides) if overrides else title, base, vary, conditions, defences,
                        places, availability, dotted_keys(defaults), set_items=tuple(flat_items(overrides).items()))
    refuse_layered(path, keys_given, board.layers_over_base())
    check_plan_size(board.size(quick), f"{path}: {len(defences)} defences", yes=yes)
    check_runs_any(board, quick)
    _check_runs(board)
    _check_keys_read(board, defaults, keys_given)
    return board


def check_runs_any(board: Leaderboard, quick: bool) -> None:
    """A one-line ConfigError when the plan has no run: with --quick, every place's and availability scenario's
    quick_seeds may be 0, and a board of no runs would still write a whole report of empty rows."""
    if board.size(quick) == 0:
        raise ConfigError(f"{board.path}: with --quick it has no run to make (every place's and availability "
                          "scenario's quick_seeds is 0); give one of them quick_seeds = 1, or leave out --quick")


def _parse_conditions(raw: Any) -> dict[str, Condition]:
    table = as_table(raw if raw is not None else {}, "conditions")
    missing = [name for name in CONDITIONS[:2] if name not in table]
    if missing:
        raise ConfigError(f"no [conditions.{missing[0]}]; give [conditions.clean] and [conditions.strongest] (the "
                          f"strongest non-adaptive attack), each a table of config keys")
    unknown = sorted(set(table) - set(CONDITIONS[:2]))
    if unknown:
        raise ConfigError(f"unknown condition '{unknown[0]}'; the conditions are clean and strongest (each defence "
                          f"declares its own adaptive one)")
    return {name: _condition(table[name], f"conditions.{name}") for name in CONDITIONS[:2]}


def _condition(raw: Any, where: str) -> Condition:
    overrides = as_table(raw, where)
    note = overrides.pop("note", "")
    if not isinstance(note, str):
        raise ConfigError(f"'{where}.note' must be a string, got {note!r}")
    _check_layer(overrides)
    return Condition(overrides, note)


def _check_layer(overrides: Mapping[str, Any]) -> None:
    """A defence's, condition's or availability scenario's config keys, checked where they are parsed so that an
    unknown key or a bad value is named with its place in the file (the runs compose the layers later); the
    seed is set per run."""
    reject_seed(overrides)
    with_overrides(SimConfig(), overrides)


def _parse_defence(path: Path, index: int, raw: Any) -> Defence:
    with located(path, f"defences[{index}]"):
        overrides = as_table(raw, f"defences[{index}]")
        name = _name(overrides.pop("name", None))
    with located(path, f'defences[{index}] "{name}"'):
        about = overrides.pop("about", "")
        adaptive_note = overrides.pop("adaptive_note", "")
        if not isinstance(about, str) or not isinstance(adaptive_note, str):
            raise ConfigError("'about' and 'adaptive_note' must be strings")
        if "adaptive" not in overrides:
            raise ConfigError("no 'adaptive' table: give the defence's own adaptive attack as config keys, e.g. "
                              "adaptive = { scenario = { sign = \"adaptive\" } }")
        adaptive = _condition(overrides.pop("adaptive"), "adaptive")
        _check_layer(overrides)
        return Defence(name, about, overrides, Condition(adaptive.overrides, adaptive_note))


def _parse_place(path: Path, index: int, raw: Any) -> Place:
    with located(path, f"places[{index}]"):
        table = as_table(raw, f"places[{index}]")
        unknown = sorted(set(table) - {"town", "placement", "seeds", "quick_seeds"})
        if unknown:
            raise ConfigError(f"unknown key '{unknown[0]}'; a place has town, placement, seeds and quick_seeds")
        town, placement = table.get("town"), table.get("placement")
        if not isinstance(town, str) or not isinstance(placement, str):
            raise ConfigError("'town' and 'placement' must be names, e.g. town = \"town07\", placement = \"standard\"")
        return Place(town, placement, *_seeds(table))


def _parse_availability(path: Path, index: int, raw: Any, defence_names: set[str]) -> Availability:
    with located(path, f"availability[{index}]"):
        overrides = as_table(raw, f"availability[{index}]")
        name = _name(overrides.pop("name", None))
    with located(path, f'availability[{index}] "{name}"'):
        seeds = _seeds(overrides)
        for key in ("seeds", "quick_seeds"):
            overrides.pop(key, None)
        only = overrides.pop("defences", None)
        if only is not None:
            if not isinstance(only, list) or not all(isinstance(n, str) for n in only) or not only:
                raise ConfigError(f"'defences' must be a non-empty list of defence names, got {only!r}")
            unknown = sorted(set(only) - defence_names)
            if unknown:
                raise ConfigError(f"'defences' names '{unknown[0]}', which is no defence of this file")
        _check_layer(overrides)
        return Availability(name, overrides, *seeds, tuple(only) if only is not None else None)


def _seeds(table: Mapping[str, Any]) -> tuple[int, int]:
    seeds, quick = table.get("seeds", 1), table.get("quick_seeds", 0)
    if type(seeds) is not int or not 1 <= seeds <= MAX_RUNS or type(quick) is not int or not 0 <= quick <= seeds:
        raise ConfigError(f"'seeds' must be an integer >= 1 (at most {MAX_RUNS:,}) and 'quick_seeds' one in 0 .. seeds, "
                          f"got {seeds!r} and {quick!r}")
    return seeds, quick


def _name(value: Any) -> str:
    if not isinstance(value, str) or not value.strip() or "|" in value:
        raise ConfigError(f"'name' must be a non-empty string without '|', got {value!r}")
    return value


def _array(path: Path, raw: Mapping[str, Any], key: str) -> list[Any]:
    items = raw.get(key)
    if not isinstance(items, list) or not items:
        raise ConfigError(f"{path}: no [[{key}]]; add at least one")
    return items


def _unique(path: Path, key: str, names: list[str]) -> None:
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ConfigError(f"{path}: [[{key}]] names '{repeated[0]}' twice; each needs its own")


def _check_keys_read(board: Leaderboard, defaults: Mapping[str, Any], keys_given: frozenset[str]) -> None:
    """A defence's policy and perception keys are read by its runs; those of [defaults] and [vary], and the
    --set keys (`keys_given`), by some run of the board (`avsim.config_owners`)."""
    runs = board.runs(first_seed_only=True)
    with located(board.path, "[defaults] and [vary]"):
        check_read_by_some((run.config for run in runs), set_keys(defaults) | {key for key, _, _ in board.vary})
    with located(board.path, "--set"):
        check_read_by_some((run.config for run in runs), keys_given)
    for defence in board.defences:
        with located(board.path, f'defence "{defence.name}"'):
            for run in runs:
                if run.defence == defence.name:
                    check_read(run.config, set_keys(defence.overrides))


def _check_runs(board: Leaderboard) -> None:
    """Every run's config (both seed counts give the same configs up to the seed), its registry
    names and sign texture, and whether it requires a stop."""
    # Seed k's config is seed 0's but for the seed and its [vary] draw, both checked by config_at_seed.
    for run in board.runs(first_seed_only=True):
        with located(board.path, f'run "{run.label}"'):
            check_run_names(run.config)
            check_networks(run.config)
            check_renderer(run.config)
            required = run.config.scenario.stop_required
            if run.kind == SAFETY and not required:
                raise ConfigError("this safety run has no stop to make (no stop sign facing the car); an attack "
                                  "condition must keep the junction's stop sign")
            if run.kind == AVAILABILITY and required:
                raise ConfigError("this availability scenario requires a stop (a stop sign facing the car); give it "
                                  "scenario.sign = \"none\" or a stop sign turned to the cross street")
