"""The scene families as registered ``scene_generator`` components (registered by :mod:`sims.plugin`).

A dataset config names them in ``families``; ``registry.create("scene_generator", "crossroads",
{"hidden_distance": [20, 40]})`` validates the parameters with the family's model and
``.generate(seed)`` draws the same scene as ``generate_scene("crossroads", seed, ...)``. Each
family is a module-level class so that it pickles by reference into dataset workers.
"""
from __future__ import annotations

from typing import ClassVar

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.interfaces import SceneGenerator
from xnlos_core.scene import Scene

from . import (corner_split, crossroads, curved_wall, hidden_car_approach, hidden_cyclist, hidden_pedestrian,
               parking_lot, residential_street, t_junction)
from .common import Generator, generate


class FamilyGenerator(SceneGenerator):
    """A family of :mod:`sims.generators` (its ``GENERATOR``) as a scene generator component.

    A subclass names its family once, ``class Crossroads(FamilyGenerator, family=crossroads.GENERATOR)``;
    its ``Params`` and docstring (``xnlos plugins``' description) are the family's.
    """

    GENERATOR: ClassVar[Generator]

    def __init_subclass__(cls, family: Generator, **kwargs):
        super().__init_subclass__(**kwargs)
        cls.GENERATOR, cls.Params, cls.__doc__ = family, family.Params, family.description

    def generate(self, seed: int) -> Scene:
        """The family's scene for ``seed`` (≥ 0) with these parameters (see ``generate_scene``)."""
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise InputError(f"scene family {self.GENERATOR.name!r}: seed must be an integer ≥ 0, got {seed!r}")
        return generate(self.GENERATOR, int(seed), self.params)


class Crossroads(FamilyGenerator, family=crossroads.GENERATOR): pass
class TJunction(FamilyGenerator, family=t_junction.GENERATOR): pass
class ParkingLot(FamilyGenerator, family=parking_lot.GENERATOR): pass
class ResidentialStreet(FamilyGenerator, family=residential_street.GENERATOR): pass
class CurvedWall(FamilyGenerator, family=curved_wall.GENERATOR): pass
class CornerSplit(FamilyGenerator, family=corner_split.GENERATOR): pass
class HiddenCarApproach(FamilyGenerator, family=hidden_car_approach.GENERATOR): pass
class HiddenCyclist(FamilyGenerator, family=hidden_cyclist.GENERATOR): pass
class HiddenPedestrian(FamilyGenerator, family=hidden_pedestrian.GENERATOR): pass


COMPONENTS: dict[str, type[FamilyGenerator]] = {c.GENERATOR.name: c for c in (
    Crossroads, TJunction, ParkingLot, ResidentialStreet, CurvedWall, CornerSplit, HiddenCarApproach, HiddenCyclist,
    HiddenPedestrian)}
