"""Parameters shared by every scene family (pydantic, strict) and the object class presets.

Intervals are [low, high] pairs drawn uniformly per scene (a single number means [v, v]); every
field carries its bounds, unit and a description, so a bad value is an error naming the key.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field, field_validator, model_validator

from xnlos_core.radar import RadarConfig
from sims.propagation import DETECTABLE_SNR_DB

Kind = Literal["car", "bicycle", "pedestrian"]


@dataclass(frozen=True)
class KindPreset:
    """Nominal object of one class: size (length, width) [m], height [m], RCS range [m²],
    speed range [m/s] when moving, and whether its heading is free (else along the street)."""

    size: tuple[float, float]
    height: float
    rcs: tuple[float, float]
    speed: tuple[float, float]
    free_heading: bool = False


KINDS: dict[str, KindPreset] = {
    "car": KindPreset((4.5, 1.8), 1.5, (7.0, 14.0), (3.0, 14.0)),
    "bicycle": KindPreset((1.8, 0.6), 1.1, (1.5, 3.0), (2.0, 7.0)),
    "pedestrian": KindPreset((0.5, 0.5), 1.8, (0.5, 1.0), (0.7, 2.0), free_heading=True),
}


# ---- parameter types ------------------------------------------------------------------------
def _pair(value):
    if isinstance(value, bool) or not isinstance(value, (int, float, list, tuple)):
        raise ValueError(f"expected a number or a [low, high] pair, got {value!r}")
    if isinstance(value, (int, float)):
        return (value, value)
    if len(value) != 2:
        raise ValueError(f"expected a [low, high] pair, got {len(value)} values")
    return tuple(value)


def Range(lo: float, hi: float, unit: str, integer: bool = False):
    """A [low, high] interval drawn uniformly, lo ≤ low ≤ high ≤ hi; a single number means [v, v]."""

    def check(v):
        a, b = v
        if not (lo <= a <= b <= hi):
            raise ValueError(f"need {lo} ≤ low ≤ high ≤ {hi} [{unit}], got [{a}, {b}]")
        return v

    t = int if integer else float
    return Annotated[tuple[t, t], BeforeValidator(_pair), AfterValidator(check)]


class BaseParams(BaseModel):
    """Parameters every family shares. Intervals [low, high] are drawn uniformly per scene."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)

    carrier_hz: float = Field(10e9, gt=1e8, le=3e11, description="radar carrier [Hz]; every material must "
                                                                 "be valid (ITU-R P.2040) at it or have a "
                                                                 "documented fallback (sims.material_fallback)")
    materials: list[str] = Field(default_factory=lambda: ["concrete", "brick"], min_length=1,
                                 description="facade materials (sims.materials names), one drawn per building")
    roughness: Range(0.0, 0.05, "m") = Field((0.0, 0.001), description="rms facade roughness σ_h [m]")
    thickness: Range(0.05, 2.0, "m") | None = Field(
        None, description="facade slab thickness [m]; None: solid buildings (half-space, opaque facades)")
    building_height: Range(2.0, 200.0, "m") = Field((6.0, 20.0), description="facade height [m]")
    object_kinds: list[Kind] = Field(default_factory=lambda: ["car", "bicycle", "pedestrian"], min_length=1,
                                     description="object classes drawn uniformly (car, bicycle, pedestrian)")
    n_hidden: int = Field(1, ge=1, le=4, description="objects that must be hidden yet mirror-visible")
    n_extra_objects: Range(0, 12, "objects", integer=True) = Field(
        (0, 2), description="further objects anywhere in the streets (line of sight or not)")
    hidden_distance: Range(1.0, 40.0, "m") = Field(
        (2.0, 20.0), description="distance of a hidden object's centre behind the occluding corner [m]")
    hidden_side: Literal["right", "left", "any"] = Field("any", description="side of the hidden street arm")
    hidden_heading: float | None = Field(None, ge=-2 * math.pi, le=2 * math.pi,
                                         description="fixed heading of hidden objects [rad]; None: along "
                                                     "the street ± heading_jitter")
    heading_jitter: float = Field(0.2, ge=0, le=math.pi, description="heading spread about the street [rad]")
    size_jitter: float = Field(0.1, ge=0, le=0.5, description="relative spread of object sizes")
    moving_probability: float = Field(0.0, ge=0, le=1, description="chance that an object moves along its "
                                                                   "heading at its class's speed")
    min_snr_db: float | None = Field(DETECTABLE_SNR_DB, ge=-50, le=100,
                                     description="a hidden object's best mirror path must reach this RA-map SNR "
                                                 "[dB] (default: detectable at pd 0.5, pfa 1e-5; None: any)")
    radar: dict[str, Any] = Field(default_factory=dict, description="RadarConfig fields of the radar whose field "
                                  "of view, range and SNR the mirror check uses ({}: the default radar; a "
                                  "carrier_frequency must equal carrier_hz)")
    facet_length: float = Field(1.0, ge=0.05, le=10, description="curved walls: facet length [m]")
    max_attempts: int = Field(300, ge=1, le=10000, description="re-draws before giving up")

    @field_validator("materials")
    @classmethod
    def _known(cls, names):
        from sims.materials import get_material

        return [get_material(n).name for n in names]

    @model_validator(mode="after")
    def _carrier(self):
        from sims.material_fallback import has_fallback
        from sims.materials import MATERIALS

        f_radar = self.radar.get("carrier_frequency", self.carrier_hz)
        if f_radar != self.carrier_hz:
            raise ValueError(f"radar.carrier_frequency = {f_radar!r} Hz differs from carrier_hz = {self.carrier_hz!r} "
                             "Hz; set carrier_hz to the radar's carrier")
        for name in self.materials + self.extra_materials():
            m = MATERIALS[name]
            if not m.covers(self.carrier_hz) and not has_fallback(m, self.carrier_hz):
                raise ValueError(f"material {name!r} is defined by ITU-R P.2040 only for {m.f_min_hz / 1e9:g}–"
                                 f"{m.f_max_hz / 1e9:g} GHz, not at carrier_hz = {self.carrier_hz / 1e9:g} GHz")
        return self

    def extra_materials(self) -> list[str]:
        """Materials a family uses besides ``materials`` (checked against the carrier)."""
        return []

    @field_validator("radar")
    @classmethod
    def _radar(cls, table):
        RadarConfig(**table)  # a bad field fails here, with its name
        return table

    def radar_config(self) -> RadarConfig:
        """The radar whose field of view, range and SNR decide if a mirror path counts."""
        return RadarConfig(**{**self.radar, "carrier_frequency": self.carrier_hz})


def uniform(rng: np.random.Generator, interval) -> float:
    a, b = interval
    return float(a) if a == b else float(rng.uniform(a, b))


def integer(rng: np.random.Generator, interval) -> int:
    a, b = interval
    return int(rng.integers(a, b + 1))
