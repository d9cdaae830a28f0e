"""Town registry. Each town module registers one `Town`; import order fills `TOWNS`."""

from avsim.world.towns.base import PLACEMENTS, TOWNS, Town
from avsim.world.towns import town03, town07, town10  # noqa: F401  (registration)

__all__ = ["PLACEMENTS", "TOWNS", "Town"]
