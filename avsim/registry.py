"""A named registry: towns, placements and braking policies are looked up by name.

Tests loop over `names()`, so a new entry is smoke-tested as soon as it is registered.
"""

from collections.abc import Callable, Iterator
from typing import Generic, TypeVar

from avsim.errors import ConfigError

T = TypeVar("T")


class Registry(Generic[T]):
    """Maps names to entries of one kind (e.g. "town" -> town builder)."""

    def __init__(self, kind: str) -> None:
        self._kind = kind
        self._entries: dict[str, T] = {}

    def add(self, name: str, entry: T) -> T:
        """Register `entry` under `name` and return it; a name registered twice is a bug (ValueError)."""
        if name in self._entries:
            raise ValueError(f"{self._kind} '{name}' is registered twice")
        self._entries[name] = entry
        return entry

    def register(self, name: str) -> Callable[[T], T]:
        """Decorator form of `add`."""
        return lambda entry: self.add(name, entry)

    def get(self, name: str) -> T:
        """The entry registered under `name`, or a one-line ConfigError listing the names there are."""
        try:
            return self._entries[name]
        except KeyError:
            raise ConfigError(
                f"unknown {self._kind} '{name}'; choose one of: {', '.join(self.names())}"
            ) from None

    def names(self) -> list[str]:
        """Every registered name, sorted."""
        return sorted(self._entries)

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())
