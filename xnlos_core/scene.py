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
    # or, instead of velocity, a trajectory from center and heading (xnlos_core.motion):
    # trajectory = { model = "constant_turn", speed = 5.0, yaw_rate = 0.2 }
"""
from __future__ import annotations

import functools
import math
import re
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_serializer, model_validator

from .motion import MAX_SPEED, ConstantVelocity, MotionState, Trajectory

from .types import WallSegment

MAX_COORD = 10_000.0  # m: a scene is metres to kilometres around the radar
MAX_UNDECLARED_EXTENT = 1_000.0  # m: a mesh without a declared unit larger than this is refused as probably mm or cm
MAX_SCATTERERS = 1_000_000  # per wall or object outline (length / spacing): bounds the forward models' arrays
# Finite and bounded: 1e308 overflows the image model's squares, 2**31 m walls allocate 64 GiB of scatterers.
Coord = Annotated[float, Field(ge=-MAX_COORD, le=MAX_COORD, allow_inf_nan=False)]
Vec2 = tuple[Coord, Coord]
Velocity = tuple[Annotated[float, Field(ge=-MAX_SPEED, le=MAX_SPEED, allow_inf_nan=False)],
                 Annotated[float, Field(ge=-MAX_SPEED, le=MAX_SPEED, allow_inf_nan=False)]]
Size = Annotated[float, Field(gt=0, le=1_000, allow_inf_nan=False)]


@functools.lru_cache(maxsize=4096)
def _segment(start: tuple, end: tuple, name: str) -> WallSegment:
    """:meth:`WallSpec.segment`, cached: a WallSegment is immutable (frozen, read-only arrays), and the
    ray tracer asks each wall for it several times per map (world boxes, inside checks, ground truth)."""
    return WallSegment(np.array(start, float), np.array(end, float), name)


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
    radius: float | None = Field(None, ge=-1e6, le=1e6, allow_inf_nan=False, description="curved wall: circular arc start→end of this radius [m]; "
                                                   "> 0 bulges to the left of start→end, < 0 to the right")
    facet_length: float = Field(0.5, gt=0.01, le=50, description="a curved wall is cut into planar facets "
                                                                 "of about this length [m]")

    @model_validator(mode="after")
    def _length(self):
        if math.dist(self.start, self.end) <= 0:
            raise ValueError(f"wall {self.name!r}: start and end coincide; a wall needs length > 0")
        if math.dist(self.start, self.end) / self.spacing > MAX_SCATTERERS:
            raise ValueError(f"wall {self.name!r}: {math.dist(self.start, self.end):.6g} m at spacing {self.spacing} m "
                             f"is more than {MAX_SCATTERERS} scatterers; raise spacing")
        if self.radius is not None and abs(self.radius) < 0.5 * math.dist(self.start, self.end) * (1 + 1e-9):
            raise ValueError(f"wall {self.name!r}: |radius| = {abs(self.radius)} m is below half the chord "
                             f"({0.5 * math.dist(self.start, self.end):.3f} m); no arc joins start and end")
        if self.material is not None and (self.reflectivity is not None or self.backscatter_db is not None):
            raise ValueError(f"wall {self.name!r}: give either material (with thickness/roughness) or the "
                             "constants reflectivity/backscatter_db, not both")
        if self.material is None and (self.thickness is not None or self.roughness > 0):
            raise ValueError(f"wall {self.name!r}: thickness and roughness need a material")
        # The material name is checked by the forward model that knows the materials
        # (ForwardModel.check, e.g. sims.walls.check_materials): the core knows no material table.
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
        """The planar segment start→end (read-only; one object per distinct start, end and name)."""
        return _segment(tuple(self.start), tuple(self.end), self.name)

    def vertices(self) -> np.ndarray:
        """(K+1, 2) polyline [m]: start, end for a planar wall; the arc's facet corners for a curved one
        (the shorter arc through start and end, bulging to the side the sign of ``radius`` gives)."""
        a, b = np.asarray(self.start, float), np.asarray(self.end, float)
        if self.radius is None:
            return np.stack([a, b])
        r = abs(self.radius)
        chord = b - a
        c_len = float(np.linalg.norm(chord))
        left = np.array([-chord[1], chord[0]]) / c_len
        h = math.sqrt(max(r * r - (c_len / 2) ** 2, 0.0))
        side = 1.0 if self.radius > 0 else -1.0
        centre = (a + b) / 2 - side * h * left  # the bulge points away from the centre
        t0 = math.atan2(*(a - centre)[::-1])
        t1 = math.atan2(*(b - centre)[::-1])
        sweep = (t1 - t0 + math.pi) % (2 * math.pi) - math.pi  # shorter arc
        k = max(2, int(math.ceil(abs(sweep) * r / self.facet_length)))
        t = t0 + sweep * np.linspace(0.0, 1.0, k + 1)
        return centre + r * np.stack([np.cos(t), np.sin(t)], axis=1)

    def facets(self) -> list["WallSpec"]:
        """Planar pieces of this wall (itself when planar), each a WallSpec with the same properties."""
        if self.radius is None:
            return [self]
        v = self.vertices()
        return [self.model_copy(update={"start": tuple(v[i]), "end": tuple(v[i + 1]), "radius": None,
                                        "name": f"{self.name}[{i}]"}) for i in range(len(v) - 1)]


class ObjectSpec(BaseModel):
    """A point or box-shaped (vehicle-like) scatterer, optionally moving.

    Motion: ``velocity`` (vx, vy) [m/s] is constant velocity, centre c₀ + t·velocity; or a
    ``trajectory`` table (:mod:`xnlos_core.motion`) started from ``center`` and ``heading`` at
    t = 0, whose heading also turns the box. Not both.
    """

    model_config = ConfigDict(extra="forbid")
    name: str = "object"
    shape: Literal["point", "box"] = "box"
    kind: Literal["generic", "car", "bicycle", "pedestrian"] = Field(
        "generic", description="object class (ground truth label; sizes and RCS come from the fields)")
    height: float = Field(1.5, gt=0, le=50, description="height above ground [m] (3-D occlusion)")
    centre_height: float | None = Field(
        None, ge=0, le=50, description="height of the scattering centres above the ground [m] (3-D propagation); "
                                       "None: the radar's mounting height, capped at the object's height")
    center: Vec2
    size: tuple[Size, Size] = Field((4.5, 1.8), description="(length, width) [m] for a box")
    heading: float = Field(0.0, ge=-2 * math.pi, le=2 * math.pi, description="[rad] from +x")
    rcs: float = Field(10.0, gt=0, le=1e6, description="total radar cross-section [m²]")
    velocity: Velocity = (0.0, 0.0)
    spacing: float = Field(0.3, gt=0.005, le=10, description="scatterer spacing on a box outline [m]")
    trajectory: Trajectory | None = Field(None, description="motion model table (xnlos_core.motion); "
                                                            "replaces velocity")

    @model_serializer(mode="wrap")
    def _dump(self, handler):
        # Without a trajectory the dump (scene digests, dataset shards) stays what it was before the
        # key existed; with one, the unused velocity is left out so the dump validates again.
        out = handler(self)
        if isinstance(out, dict):
            out.pop("trajectory" if self.trajectory is None else "velocity", None)
            if self.centre_height is None:
                out.pop("centre_height", None)
        return out

    @model_validator(mode="after")
    def _outline(self):
        if self.trajectory is not None and "velocity" in self.model_fields_set:
            raise ValueError(f"object {self.name!r}: give velocity (constant velocity) or trajectory, not both")
        if self.shape == "box" and 2 * sum(self.size) / self.spacing > MAX_SCATTERERS:
            raise ValueError(f"object {self.name!r}: a {self.size} m box at spacing {self.spacing} m is more than "
                             f"{MAX_SCATTERERS} scatterers; raise spacing")
        return self

    @field_validator("size")
    @classmethod
    def _positive(cls, v):
        if min(v) <= 0:
            raise ValueError(f"size must be positive (length, width) in metres, got {v}")
        return v

    def center_at(self, t: float) -> np.ndarray:
        """Centre position (2,) [m] at time t [s] (a number; :meth:`motion` takes arrays of times)."""
        if self.trajectory is None:
            return np.asarray(self.center, float) + t * np.asarray(self.velocity, float)
        return self.trajectory.state(t, self.center, self.heading).position[0]

    def heading_at(self, t: float) -> float:
        """Box heading [rad] at time t [s]: ``heading`` unless a trajectory turns it."""
        if self.trajectory is None:
            return self.heading
        return float(self.trajectory.state(t, self.center, self.heading).heading[0])

    def motion(self, t) -> MotionState:
        """Centre position (T, 2) [m], velocity (T, 2) [m/s] and heading (T,) [rad] at times t (T,) [s]."""
        model = self.trajectory or ConstantVelocity(velocity=self.velocity)
        return model.state(t, self.center, self.heading)

    def footprint(self, t: float = 0.0) -> np.ndarray:
        """Bird's-eye outline at time t [s]: the box's 4 corners (4, 2) [m] in order around it, or
        the centre (1, 2) [m] of a point object (figures draw it, e.g. for an unobservable object)."""
        c = self.center_at(t)
        if self.shape == "point":
            return c[None, :]
        heading = self.heading_at(t)
        u = np.array([math.cos(heading), math.sin(heading)]) * self.size[0] / 2
        v = np.array([-math.sin(heading), math.cos(heading)]) * self.size[1] / 2
        return np.stack([c + u + v, c - u + v, c - u - v, c + u - v])

    def scatterers(self, t: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Scatterer positions (K, 2) [m], outward normals (K, 2) (zero for a point), RCS (K,) [m²].

        A box is sampled along its outline at ``spacing``; the total RCS is shared equally.
        """
        c = self.center_at(t)
        if self.shape == "point":
            return c[None, :], np.zeros((1, 2)), np.array([self.rcs])
        length, width = self.size
        heading = self.heading_at(t)
        u = np.array([math.cos(heading), math.sin(heading)])
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


class GroundSpec(BaseModel):
    """A flat ground plane z = 0 under the radar (3-D propagation: the ground-reflected twin of every path).

    Its reflection is the Fresnel coefficient of an ITU-R P.2040 ``material`` at the grazing angle
    (the radar's V polarisation is TM on the ground, H is TE), or the constant amplitude
    coefficient ``reflection`` (−1: a perfect reflector, the grazing limit of every real ground).
    """

    model_config = ConfigDict(extra="forbid")
    material: str | None = Field(None, description="ITU-R P.2040 material of the ground (e.g. 'concrete', "
                                                   "'medium_dry_ground')")
    reflection: float | None = Field(None, ge=-1, le=1, description="constant amplitude reflection coefficient "
                                                                    "Γ [-] instead of a material")

    @model_validator(mode="after")
    def _one(self):
        if (self.material is None) == (self.reflection is None):
            raise ValueError("ground: give a material (e.g. 'concrete') or a constant reflection coefficient "
                             "(e.g. -1.0), exactly one")
        return self


class MeshSpec(BaseModel):
    """A static user mesh (OBJ, STL, PLY, GLB, …) placed in the scene, for mesh-based forward models.

    Electromagnetics as for walls: ``material`` for every face, or per-part ``materials``
    (mesh part / material tag name → ITU-R P.2040 material) with ``material`` as the default for
    untagged parts, or the constants ``reflectivity`` / ``backscatter_db``.

    Units: the file's coordinates are in ``unit`` (``"m"``, ``"cm"``, ``"mm"``), then multiplied by
    ``scale``. Without ``unit`` they are metres, and a mesh whose extent (× scale) exceeds
    :data:`MAX_UNDECLARED_EXTENT` (a car 4500 units long, a building 20 000) is refused as probably
    millimetres or centimetres; declare ``unit = "m"`` for a mesh that truly is that large.
    """

    model_config = ConfigDict(extra="forbid")
    name: str = "mesh"
    file: str = Field(..., min_length=1, description="mesh file, relative to the scene file")
    material: str | None = None
    materials: dict[str, str] = Field(default_factory=dict)
    reflectivity: float | None = Field(None, ge=0, le=1)
    backscatter_db: float | None = Field(None, ge=-80, le=20)
    roughness: float = Field(0.0, ge=0, le=0.5, description="rms surface height σ_h [m]")
    relay: bool = True
    translation: tuple[Coord, Coord, Coord] = (0.0, 0.0, 0.0)
    yaw: float = Field(0.0, ge=-2 * math.pi, le=2 * math.pi, description="rotation about z [rad]")
    scale: float = Field(1.0, gt=0, le=1e4)
    unit: Literal["m", "cm", "mm"] | None = Field(
        None, description="length unit of the file's coordinates (STL, OBJ, PLY carry none); None: metres, and a "
                          "mesh larger than MAX_UNDECLARED_EXTENT is refused as probably millimetres")

    @model_serializer(mode="wrap")
    def _dump(self, handler):
        # without a declared unit the dump (scene digests, dataset shards) stays what it was before the key existed
        out = handler(self)
        if isinstance(out, dict) and self.unit is None:
            out.pop("unit", None)
        return out

    @model_validator(mode="after")
    def _em(self):
        if (self.material or self.materials) and (self.reflectivity is not None or self.backscatter_db is not None):
            raise ValueError(f"mesh {self.name!r}: give materials or the constants reflectivity/backscatter_db, "
                             "not both")
        return self


class Scene(BaseModel):
    """Walls, static meshes and objects of one scene; frames at t = k·frame_interval move the objects.

    ``atmosphere``: None means vacuum-like air (no gaseous loss is modelled). ``base_dir``: where
    relative mesh files are looked up (set by :func:`load_scene`). ``meta``: free-form scene
    parameters (e.g. a generator's family and draws), kept with datasets.
    """

    model_config = ConfigDict(extra="forbid")
    name: str = "scene"
    walls: list[WallSpec] = Field(default_factory=list)
    meshes: list[MeshSpec] = Field(default_factory=list)
    objects: list[ObjectSpec] = Field(default_factory=list)
    atmosphere: AtmosphereSpec | None = None
    ground: GroundSpec | None = Field(None, description="ground plane (3-D propagation); None: no ground")
    base_dir: str = "."
    meta: dict = Field(default_factory=dict)

    @model_serializer(mode="wrap")
    def _dump(self, handler):
        # without a ground the dump (scene digests, dataset shards) stays what it was before the key existed
        out = handler(self)
        if isinstance(out, dict) and self.ground is None:
            out.pop("ground", None)
        return out

    def planar_walls(self) -> list[WallSpec]:
        """Every wall as planar pieces (curved walls cut into facets), in order."""
        return [f for w in self.walls for f in w.facets()]

    def wall_segments(self) -> tuple[WallSegment, ...]:
        """BEV segments of the planar pieces (ground-truth wall geometry)."""
        return tuple(w.segment() for w in self.planar_walls())


BUILTIN_DIR = Path(__file__).with_name("defaults")


BUILTIN_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_-]{0,63}")
MESH_SUFFIXES = (".obj", ".stl", ".ply", ".glb", ".gltf")  # sims.meshes.SUPPORTED


def builtin_scenes() -> list[str]:
    """Names of the built-in scenes (``xnlos_core/defaults/*.toml`` but the demo pipeline)."""
    return sorted(p.stem for p in BUILTIN_DIR.glob("*.toml") if p.stem != "demo")


FAMILY_KEYS = ("family", "seed", "overrides")


def generated_scene(table: dict, source: str, base_dir: str | Path, registry=None,
                    root_dir: str | Path | None = None) -> Scene:
    """The scene of ``[scene] family = NAME``: the registered scene generator ``NAME`` (kind
    ``scene_generator``, e.g. ``t_junction``) with ``overrides`` (its ``Params``, validated and named
    ``scene.overrides.KEY`` in errors) draws one scene from ``seed`` (default 0).
    ``registry``: where the generator is looked up (:class:`xnlos_core.registry.Registry`, e.g.
    the pipeline's); required. Path parameters of the generator (:data:`xnlos_core.param_paths.ConfigPath`,
    e.g. the ``osm`` generator's ``map``) are relative to ``base_dir`` and bounded by the config roots
    of ``root_dir`` (default ``base_dir``)."""
    from .errors import ConfigError, PluginError
    from .param_paths import PathContext
    from .validation import validate_model

    extra = sorted(set(table) - set(FAMILY_KEYS))
    if extra:
        raise ConfigError(f"{source}: [scene] a generated scene (family = …) takes only {', '.join(FAMILY_KEYS)}; "
                          f"remove {', '.join(extra)} (builtin, file and inline walls/objects are other scene kinds)")
    family, seed, overrides = table["family"], table.get("seed", 0), table.get("overrides", {})
    if not isinstance(seed, int) or isinstance(seed, bool) or not 0 <= seed < 2**63:
        raise ConfigError(f"{source}: [scene.seed] expected an integer in [0, 2^63), got {seed!r}")
    if not isinstance(overrides, dict):
        raise ConfigError(f"{source}: [scene.overrides] expected a table of the family's parameters, got {overrides!r}")
    if registry is None:  # the caller's registry (the pipeline's): the core's scene module imports no registry
        raise ConfigError(f"{source}: [scene.family] a generated scene is built by a pipeline (or a caller that "
                          "passes its plugin registry); here only builtin, file or inline scenes are read")
    if not isinstance(family, str):
        raise ConfigError(f"{source}: [scene.family] expected a scene generator name, got {family!r}")
    try:
        comp = registry.get("scene_generator", family)
    except PluginError as exc:
        raise ConfigError(f"{source}: [scene.family] {exc}") from None
    model = comp.params_model
    # path parameters (ConfigPath, e.g. a map file) are relative to the config that names them
    context = PathContext(base_dir, root_dir).validation_context()
    params = validate_model(model, overrides, source=source, prefix="scene.overrides", context=context) if model else None
    generator = comp.factory(params) if model else comp.factory()
    scene = generator.generate(seed)
    return scene.model_copy(update={"base_dir": str(base_dir),
                                    "meta": {**scene.meta, "family": family, "seed": seed}})


def load_scene(table: dict, source: str, base_dir: str | Path = ".", root_dir: str | Path | None = None,
               registry=None) -> Scene:
    """Scene from a pipeline's ``[scene]`` table: ``builtin = NAME``, ``file = PATH``,
    ``family = NAME`` (with ``seed`` and ``overrides``: :func:`generated_scene`, looked up in
    ``registry``) or inline.

    ``file`` and every mesh ``file`` are regular files inside the config roots of ``root_dir``
    (default ``base_dir``, the top-level config's folder; :mod:`xnlos_core.files`): a scene file
    relative to ``base_dir``, its meshes relative to the scene file. ``builtin`` is a name of
    :func:`builtin_scenes`, never a path.
    """
    from .errors import ConfigError
    from .files import load_toml, resolve_config_path
    from .validation import validate_model

    if not isinstance(table, dict):
        raise ConfigError(f"{source}: [scene] expected a table (builtin = NAME, file = PATH or inline walls/"
                          f"objects), got {table!r}")
    root_dir = base_dir if root_dir is None else root_dir
    table = dict(table)
    given = [k for k in ("builtin", "file", "family") if k in table]
    if len(given) > 1:
        raise ConfigError(f"{source}: [scene] give one of 'builtin', 'file' or 'family', not {' and '.join(given)}")
    if "base_dir" in table:  # where meshes are looked up follows from where the scene is written
        raise ConfigError(f"{source}: [scene.base_dir] is set by the loader (the scene file's folder); remove it")
    if "family" in table:
        scene, src = generated_scene(table, source, base_dir, registry, root_dir), source
    elif "builtin" in table:
        name = table.pop("builtin")
        if not (isinstance(name, str) and BUILTIN_NAME.fullmatch(name) and name in builtin_scenes()):
            raise ConfigError(f"{source}: [scene.builtin] unknown scene {name!r}; built-in scenes: "
                              f"{', '.join(builtin_scenes())}")
        path = BUILTIN_DIR / f"{name}.toml"
        # meshes added in the [scene] table are relative to the config that adds them
        scene = validate_model(Scene, {**load_toml(path), **table, "base_dir": str(base_dir)}, source=str(path),
                               prefix="scene")
        src = source
    elif "file" in table:
        path = resolve_config_path(table.pop("file"), source=source, key="scene.file", base_dir=base_dir,
                                   root_dir=root_dir, suffixes=(".toml",))
        content = load_toml(path)
        if "base_dir" in content:
            raise ConfigError(f"{path}: [base_dir] is set by the loader (this file's folder); remove it")
        scene = validate_model(Scene, {**content, **table, "base_dir": str(path.parent)}, source=str(path),
                               prefix="scene")
        src = str(path)
    else:
        scene = validate_model(Scene, {**table, "base_dir": str(base_dir)}, source=source, prefix="scene")
        src = source
    for i, mesh in enumerate(scene.meshes):
        resolve_config_path(mesh.file, source=src, key=f"scene.meshes.{i}.file", base_dir=scene.base_dir,
                            root_dir=root_dir, suffixes=MESH_SUFFIXES)
    return scene
