"""Scene description for forward models: walls and objects in the bird's-eye plane (TOML).

Example (see ``xnlos_core/defaults/corner.toml``)::

    [[walls]]
    name = "facade"
    start = [15.0, 10.0]
    end = [35.0, -10.0]
    reflectivity = 0.6        # α: specular amplitude reflection coefficient (Eq. 2)
    backscatter_db = -12.0    # σ⁰ at normal incidence [dB m²/m²], diffuse LOS return
    [[objects]]
    name = "car"
    shape = "box"
    center = [22.0, -14.0]
    size = [4.5, 1.8]         # length along heading, width [m]
    heading = 1.5708          # [rad], 0 = along +x
    rcs = 10.0                # total radar cross-section [m²]
    velocity = [0.0, 2.0]     # [m/s]; position at time t is center + t·velocity
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from .types import WallSegment

Vec2 = tuple[float, float]


class WallSpec(BaseModel):
    """A vertical planar wall (segment start→end seen from above).

    Two ways to give its electromagnetics, not both:
    * constants: ``reflectivity`` α (specular amplitude coefficient, angle-independent) and
      ``backscatter_db`` σ⁰ at normal incidence (diffuse LOS return ∝ cos²ψ);
    * physics: ``material`` (ITU-R P.2040 name, :mod:`sims.materials`), optional ``thickness``
      (a slab; None is a half-space), rms ``roughness`` σ_h and a diffuse ``lobe``: α follows
      from Fresnel/slab reflection and the specular factor, σ⁰ from the lobe model.
    Without either, the constants default to α = 0.6 and σ⁰ = −12 dB.
    """

    model_config = ConfigDict(extra="forbid")
    name: str = "wall"
    start: Vec2
    end: Vec2
    height: float = Field(3.0, gt=0, le=500, description="visible height [m] (diffuse RCS)")
    reflectivity: float | None = Field(None, ge=0, le=1, description="α, specular amplitude coefficient "
                                                                     "(default 0.6 without a material)")
    backscatter_db: float | None = Field(None, ge=-80, le=20, description="σ⁰ at normal incidence [dB] "
                                                                          "(default −12 without a material)")
    material: str | None = Field(None, description="ITU-R P.2040 material (concrete, brick, glass, …)")
    thickness: float | None = Field(None, gt=0, le=10, description="slab thickness [m]; None: half-space")
    roughness: float = Field(0.0, ge=0, le=0.5, description="rms surface height σ_h [m]")
    lobe: Literal["lambertian", "directive"] = Field("lambertian", description="diffuse scattering lobe")
    lobe_exponent: int = Field(4, ge=1, le=100, description="α_R of the directive lobe")
    relay: bool = Field(True, description="acts as a mirror for hidden objects")
    spacing: float = Field(0.25, gt=0.005, le=10, description="scatterer spacing along the wall [m]")

    @model_validator(mode="after")
    def _length(self):
        if math.dist(self.start, self.end) <= 0:
            raise ValueError(f"wall {self.name!r}: start and end coincide; a wall needs length > 0")
        if self.material is not None and (self.reflectivity is not None or self.backscatter_db is not None):
            raise ValueError(f"wall {self.name!r}: give either material (with thickness/roughness) or the "
                             "constants reflectivity/backscatter_db, not both")
        if self.material is None and (self.thickness is not None or self.roughness > 0):
            raise ValueError(f"wall {self.name!r}: thickness and roughness need a material")
        if self.material is not None:
            from sims.materials import get_material  # validates the name with a did-you-mean

            get_material(self.material)
        return self

    @property
    def alpha(self) -> float:
        """The constant specular reflectivity α (walls without a material)."""
        return 0.6 if self.reflectivity is None else self.reflectivity

    @property
    def sigma0_db(self) -> float:
        """The constant normal-incidence σ⁰ [dB] (walls without a material)."""
        return -12.0 if self.backscatter_db is None else self.backscatter_db

    def segment(self) -> WallSegment:
        return WallSegment(np.array(self.start, float), np.array(self.end, float), self.name)


class ObjectSpec(BaseModel):
    """A point or box-shaped (vehicle-like) scatterer, optionally moving at constant velocity."""

    model_config = ConfigDict(extra="forbid")
    name: str = "object"
    shape: Literal["point", "box"] = "box"
    center: Vec2
    size: Vec2 = Field((4.5, 1.8), description="(length, width) [m] for a box")
    heading: float = Field(0.0, ge=-2 * math.pi, le=2 * math.pi, description="[rad] from +x")
    rcs: float = Field(10.0, gt=0, le=1e6, description="total radar cross-section [m²]")
    velocity: Vec2 = (0.0, 0.0)
    spacing: float = Field(0.3, gt=0.005, le=10, description="scatterer spacing on a box outline [m]")

    @field_validator("size")
    @classmethod
    def _positive(cls, v):
        if min(v) <= 0:
            raise ValueError(f"size must be positive (length, width) in metres, got {v}")
        return v

    def center_at(self, t: float) -> np.ndarray:
        """Centre position [m] at time t [s]."""
        return np.asarray(self.center, float) + t * np.asarray(self.velocity, float)

    def scatterers(self, t: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Scatterer positions (K, 2) [m], outward normals (K, 2) (zero for a point), RCS (K,) [m²].

        A box is sampled along its outline at ``spacing``; the total RCS is shared equally.
        """
        c = self.center_at(t)
        if self.shape == "point":
            return c[None, :], np.zeros((1, 2)), np.array([self.rcs])
        length, width = self.size
        u = np.array([math.cos(self.heading), math.sin(self.heading)])
        v = np.array([-u[1], u[0]])
        pts, nrm = [], []
        for half, along, normal, extent in ((length / 2, v, u, width), (-length / 2, v, -u, width),
                                             (width / 2, u, v, length), (-width / 2, u, -v, length)):
            k = max(2, int(math.ceil(extent / self.spacing)) + 1)
            s = np.linspace(-extent / 2, extent / 2, k)
            pts.append(c + abs(half) * normal + s[:, None] * along)
            nrm.append(np.broadcast_to(normal, (k, 2)))
        p = np.concatenate(pts)
        n = np.concatenate(nrm)
        return p, n, np.full(len(p), self.rcs / len(p))


class AtmosphereSpec(BaseModel):
    """Air along the paths (ITU-R P.676 gaseous absorption, :mod:`sims.atmosphere`)."""

    model_config = ConfigDict(extra="forbid")
    pressure_hpa: float = Field(1013.25, ge=1, le=1200, description="total pressure [hPa]")
    temperature_k: float = Field(288.15, ge=150, le=350, description="temperature [K]")
    water_density: float = Field(7.5, ge=0, le=50, description="water-vapour density [g/m³]")


class Scene(BaseModel):
    """Walls and objects of one scene; frames at t = k·frame_interval move the objects.

    ``atmosphere``: None means vacuum-like air (no gaseous loss is modelled).
    """

    model_config = ConfigDict(extra="forbid")
    name: str = "scene"
    walls: list[WallSpec] = Field(default_factory=list)
    objects: list[ObjectSpec] = Field(default_factory=list)
    atmosphere: AtmosphereSpec | None = None

    def wall_segments(self) -> tuple[WallSegment, ...]:
        return tuple(w.segment() for w in self.walls)


BUILTIN_DIR = Path(__file__).with_name("defaults")


def load_scene(table: dict, source: str, base_dir: str | Path = ".") -> Scene:
    """Scene from a pipeline's ``[scene]`` table: ``builtin = NAME``, ``file = PATH`` or inline."""
    from .config import load_toml, validate_model
    from .errors import ConfigError

    table = dict(table or {})
    if "builtin" in table and "file" in table:
        raise ConfigError(f"{source}: [scene] give either 'builtin' or 'file', not both")
    if "builtin" in table:
        name = table.pop("builtin")
        path = BUILTIN_DIR / f"{name}.toml"
        if not path.is_file():
            known = sorted(p.stem for p in BUILTIN_DIR.glob("*.toml") if p.stem != "demo")
            raise ConfigError(f"{source}: [scene.builtin] unknown scene {name!r}; built-in scenes: {', '.join(known)}")
        return validate_model(Scene, {**load_toml(path), **table}, source=str(path), prefix="scene")
    if "file" in table:
        path = Path(base_dir) / table.pop("file")
        return validate_model(Scene, {**load_toml(path), **table}, source=str(path), prefix="scene")
    return validate_model(Scene, table, source=source, prefix="scene")
