"""A batch's runs, counted up front and built one at a time as the workers need them.

    plan = Plan(sweep.size, sweep.iter_specs)      # nothing is built yet
    plan.size                                      # the run count, known from the file's lists
    for spec in plan: ...                          # each RunSpec built when it is asked for
    plan = plan.then(lambda specs: with_recordings(specs, out, rrd="all"))   # still lazy

Why: a sweep of a million runs (the most one command takes, `plan_size.MAX_RUNS`) would spend
minutes and gigabytes building every config before its first run. A plan holds the recipe, not
the runs; `run_batch` draws from it only as many lock-step groups as it has workers to feed
(`in_flight`), so the first run starts as soon as its group is built, whatever the plan's size.
A plan is iterable again and again, each time the same runs in the same order.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Collection, Hashable, Iterable, Iterator, Sized
from dataclasses import dataclass
from typing import Any, TypeVar

from avsim.experiments.run_task import RunSpec
from avsim.frame_sharing import sibling_key

Item = TypeVar("Item")
Handle = TypeVar("Handle", bound=Hashable)
# A lock-step group: its specs, each with its index in the plan (records are put back in plan order).
Group = list[tuple[int, RunSpec]]
# How many specs `lockstep_groups` builds at a time to find each run's siblings among: a leaderboard's
# defences of one place and seed lie about 54 specs apart in its plan, so 8 of them within 432.
SIBLING_WINDOW = 1024


@dataclass(frozen=True)
class Plan:
    """A batch's runs, built lazily (module docstring).

    size: how many runs iterating yields; an upper bound where repeated configs are dropped as
    they come (a leaderboard's). make: a fresh iterator over the runs, in plan order.
    """

    size: int
    make: Callable[[], Iterator[RunSpec]]

    def __iter__(self) -> Iterator[RunSpec]:
        return self.make()

    def then(self, step: Callable[[Iterator[RunSpec]], Iterator[RunSpec]]) -> Plan:
        """This plan with `step` applied to its runs as they are built (e.g. adding recording paths)."""
        return Plan(self.size, lambda: step(self.make()))


def count_of(specs: Iterable[RunSpec]) -> int | None:
    """How many specs there are without building them: a plan's size, a list's length; None for
    another iterable."""
    if isinstance(specs, Plan):
        return specs.size
    return len(specs) if isinstance(specs, Sized) else None


def group_size(total: int | None, workers: int | None, batch: int) -> int:
    """Runs per lock-step group: at most `batch`, and few enough that each of `workers` gets a group
    (a 10-run plan at batch 8 on 2 workers is two groups of 5). total or workers None (unknown, or
    a Ray cluster's CPUs decide): `batch`."""
    if total is None or workers is None:
        return max(1, batch)
    return max(1, min(batch, -(-total // max(1, workers))))


def lockstep_groups(specs: Iterable[RunSpec], size: int, window: int = SIBLING_WINDOW) -> Iterator[Group]:
    """`specs` cut into groups of `size` (the last may be shorter), each spec with its index; built
    only as each window of `window` specs is asked for. Within a window, siblings (runs that differ
    only in their policy, `avsim.frame_sharing.sibling_key`) are put next to each other, in the
    order each family first appears, so that a group's cars share their frames for as long as they
    drive alike; a run's result is the same in any group."""
    numbered = enumerate(specs)
    while chunk := list(itertools.islice(numbered, max(size, window))):
        families: dict[bytes, Group] = {}
        for index, spec in chunk:
            families.setdefault(sibling_key(spec.config), []).append((index, spec))
        ordered = [item for family in families.values() for item in family]
        for start in range(0, len(ordered), size):
            yield ordered[start:start + size]


def specs_of(group: Group) -> list[RunSpec]:
    """A lock-step group's specs, without their indices."""
    return [spec for _, spec in group]


def in_flight(items: Iterator[Item], limit: int, submit: Callable[[Item], Handle],
              first_done: Callable[[Collection[Handle]], Handle], cancel: Callable[[Handle], Any]
              ) -> Iterator[tuple[Item, Handle]]:
    """Submit `items` so that at most `limit` are unfinished at a time; yield (item, its handle) as
    each finishes, the next item submitted in its place (so `items` is drawn from only as fast as
    the work goes). first_done: blocks until one of the pending handles is done and returns it.
    Stopped early (the caller closed the generator, an error), the pending handles are cancelled.
    """
    pending: dict[Handle, Item] = {}
    try:
        while True:
            for item in itertools.islice(items, max(0, limit - len(pending))):
                pending[submit(item)] = item
            if not pending:
                return
            handle = first_done(pending)
            yield pending.pop(handle), handle
    finally:
        for handle in pending:
            cancel(handle)


class Counted(Iterator[Item]):
    """An iterator that counts what it yields: `count` so far, and `exhausted` once it ran out
    (then `count` is the exact total a plan's `size` may only bound)."""

    def __init__(self, items: Iterable[Item]) -> None:
        self._items = iter(items)
        self.count = 0
        self.exhausted = False

    def __next__(self) -> Item:
        try:
            item = next(self._items)
        except StopIteration:
            self.exhausted = True
            raise
        self.count += 1
        return item
