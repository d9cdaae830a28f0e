"""The attack families by name (`avsim attack generate --method NAME`)."""

from __future__ import annotations

from avsim.attacks.base import Attack
from avsim.attacks.chen import Chen
from avsim.attacks.driveby import DriveBy
from avsim.attacks.eykholt import Eykholt
from avsim.attacks.lu_v2 import LuV2
from avsim.attacks.lu_v3 import LuV3
from avsim.attacks.range_inflation import RangeInflation
from avsim.attacks.yang import Yang
from avsim.registry import Registry

ATTACKS: Registry[type[Attack]] = Registry("attack")
for _attack in (Chen, Eykholt, LuV2, LuV3, Yang, DriveBy, RangeInflation):
    ATTACKS.add(_attack.name, _attack)
