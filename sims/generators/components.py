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

from . import corner_split, crossroads, curved_wall, parking_lot, residential_street, t_junction
from .common import Generator, generate


class FamilyGenerator(SceneGenerator):
    """A family of :mod:`sims.generators` (its ``GENERATOR``) as a scene generator component."""

    GENERATOR: ClassVar[Generator]

    def generate(self, seed: int) -> Scene:
        """The family's scene for ``seed`` (≥ 0) with these parameters (see ``generate_scene``)."""
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise InputError(f"scene family {self.GENERATOR.name!r}: seed must be an integer ≥ 0, got {seed!r}")
        return generate(self.GENERATOR, int(seed), self.params)


class Crossroads(FamilyGenerator):
    __doc__ = crossroads.GENERATOR.description
    GENERATOR = crossroads.GENERATOR
    Params = crossroads.GENERATOR.Params


class TJunction(FamilyGenerator):
    __doc__ = t_junction.GENERATOR.description
    GENERATOR = t_junction.GENERATOR
    Params = t_junction.GENERATOR.Params


class ParkingLot(FamilyGenerator):
    __doc__ = parking_lot.GENERATOR.description
    GENERATOR = parking_lot.GENERATOR
    Params = parking_lot.GENERATOR.Params


class ResidentialStreet(FamilyGenerator):
    __doc__ = residential_street.GENERATOR.description
    GENERATOR = residential_street.GENERATOR
    Params = residential_street.GENERATOR.Params


class CurvedWall(FamilyGenerator):
    __doc__ = curved_wall.GENERATOR.description
    GENERATOR = curved_wall.GENERATOR
    Params = curved_wall.GENERATOR.Params


class CornerSplit(FamilyGenerator):
    __doc__ = corner_split.GENERATOR.description
    GENERATOR = corner_split.GENERATOR
    Params = corner_split.GENERATOR.Params


COMPONENTS: dict[str, type[FamilyGenerator]] = {c.GENERATOR.name: c for c in (
    Crossroads, TJunction, ParkingLot, ResidentialStreet, CurvedWall, CornerSplit)}
