"""Dataset configuration (TOML): how many maps of which scene families, rendered by which model.

::

    name = "xnlos-default"
    seed = 2024                      # root of every random draw (scenes, families, splits, noise)
    n_maps = 2160                    # RA maps in the dataset (= scenes × frames_per_scene)
    frames_per_scene = 1             # frames of one scene at t = k·frame_interval [s]
    frame_interval = 0.1
    shard_size = 24                  # maps per shard file (a multiple of frames_per_scene)
    compression = "deflate"          # or "none"
    families = ["crossroads", "t_junction"]      # or a table of weights: [families] crossroads = 2.0
    generator = "sims.generators:generate_scene" # generate_scene(family, seed, **overrides) -> Scene
    [generator_params]               # keyword arguments passed to the generator for every family
    [family_overrides.crossroads]    # … and for one family (over generator_params)
    [radar]                          # RadarConfig fields, or preset = "../radar/xband_default.toml"
    [forward_model]
    name = "raytrace"
    params = {}
    [split]                          # fractions of scenes (hence of maps) per split, by scene seed
    train = 0.8
    val = 0.1
    test = 0.1

:func:`resolve` validates everything that can fail before any work is done (radar, forward
model and its parameters, generator import, families, overrides) and returns the config with
the radar written out in full, families as weights and the forward model's parameters with
their defaults: the canonical form whose :meth:`DatasetConfig.digest` identifies a dataset.
"""
from __future__ import annotations

import hashlib
import importlib
import json
import math
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

from xnlos_core.config import StageConfig, load_toml, validate_model
from xnlos_core.errors import ConfigError, PluginError

SPLITS = ("train", "val", "test")
DEFAULT_GENERATOR = "sims.generators:generate_scene"


class SplitConfig(BaseModel):
    """Fractions of scenes per split; they must sum to 1. Scenes (all their frames) never straddle splits."""

    model_config = ConfigDict(extra="forbid")
    train: float = Field(0.8, ge=0, le=1, description="fraction of scenes for training")
    val: float = Field(0.1, ge=0, le=1, description="fraction of scenes for validation")
    test: float = Field(0.1, ge=0, le=1, description="fraction of scenes for testing")

    @field_validator("test")
    @classmethod
    def _sum_to_one(cls, v, info: ValidationInfo):
        total = info.data.get("train", 0.0) + info.data.get("val", 0.0) + v
        if abs(total - 1.0) > 1e-6:
            raise ValueError(f"train + val + test must be 1, got {total:g}")
        return v


class DatasetConfig(BaseModel):
    """A validated dataset file (see the module docstring)."""

    model_config = ConfigDict(extra="forbid")
    name: str = "dataset"
    seed: int = Field(0, ge=0, lt=2**63, description="root seed of every random draw")
    frames_per_scene: int = Field(1, ge=1, le=10_000, description="frames rendered per scene")
    frame_interval: float = Field(0.1, gt=0, le=3600, description="time between a scene's frames [s]")
    n_maps: int = Field(2160, ge=1, le=10_000_000, description="RA maps in the dataset")
    shard_size: int = Field(24, ge=1, le=100_000, description="maps per shard file")
    compression: Literal["deflate", "none"] = Field("deflate", description="zip compression of shard members")
    compression_level: int = Field(1, ge=0, le=9, description="deflate level (1 fast … 9 small)")
    families: list[str] | dict[str, float] = Field(..., description="scene families, or family → weight")
    generator_params: dict[str, Any] = Field(default_factory=dict,
                                             description="generator keyword arguments for every family")
    family_overrides: dict[str, dict[str, Any]] = Field(default_factory=dict,
                                                        description="family → generator keyword arguments "
                                                                    "(over generator_params)")
    generator: str = Field(DEFAULT_GENERATOR, pattern=r"^[A-Za-z_][\w.]*:[A-Za-z_]\w*$",
                           description="'module:function' called as function(family, seed, **overrides)")
    radar: dict[str, Any] = Field(default_factory=dict, description="RadarConfig fields or preset = FILE")
    forward_model: StageConfig
    split: SplitConfig = Field(default_factory=SplitConfig)
    base_dir: str = Field(".", description="directory relative paths resolve against (set by load)")

    @field_validator("n_maps", "shard_size")
    @classmethod
    def _whole_scenes(cls, v, info: ValidationInfo):
        fps = info.data.get("frames_per_scene", 1)
        if v % fps:
            raise ValueError(f"must be a multiple of frames_per_scene = {fps} (whole scenes), got {v}")
        return v

    @field_validator("families")
    @classmethod
    def _families(cls, v):
        names = list(v)
        if not names:
            raise ValueError("give at least one scene family")
        if len(set(names)) != len(names):
            raise ValueError(f"families must be distinct, got {names}")
        if isinstance(v, dict):
            bad = {k: w for k, w in v.items() if not (math.isfinite(w) and w > 0)}
            if bad:
                raise ValueError(f"family weights must be finite and > 0, got {bad}")
        return v

    @field_validator("family_overrides")
    @classmethod
    def _overrides_known(cls, v, info: ValidationInfo):
        fams = list(info.data.get("families") or [])
        unknown = [k for k in v if k not in fams]
        if fams and unknown:
            raise ValueError(f"overrides for {unknown}, which are not in families {fams}")
        return v

    @property
    def n_scenes(self) -> int:
        return self.n_maps // self.frames_per_scene

    def weights(self) -> dict[str, float]:
        """family → weight (1 each for a plain list)."""
        return dict(self.families) if isinstance(self.families, dict) else {f: 1.0 for f in self.families}

    def generator_kwargs(self, family: str) -> dict[str, Any]:
        """Keyword arguments of the generator for ``family``: generator_params, then its overrides."""
        return {**self.generator_params, **self.family_overrides.get(family, {})}

    def digest(self) -> str:
        """sha256 of the canonical JSON (call on the :func:`resolve`-d config to identify a dataset)."""
        blob = json.dumps(self.model_dump(mode="json", exclude={"base_dir"}), sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()


def parse_dataset_config(table: dict[str, Any], source: str, base_dir: str | Path = ".",
                         n_maps: int | None = None) -> DatasetConfig:
    """Validate a dataset table (``n_maps`` overrides the file's); errors name ``source`` and the key."""
    if "base_dir" in table:  # relative paths and the config roots follow from where the file is
        raise ConfigError(f"{source}: [base_dir] is set by the loader (the config file's folder); remove it")
    table = {**table, "base_dir": str(base_dir)}
    if n_maps is not None:
        table["n_maps"] = n_maps
    return validate_model(DatasetConfig, table, source=source)


def load_dataset_config(path: str | Path, n_maps: int | None = None) -> DatasetConfig:
    """Load and validate a dataset TOML file (not yet resolved; see :func:`resolve`)."""
    path = Path(path)
    return parse_dataset_config(load_toml(path), str(path), path.resolve().parent, n_maps)


def import_generator(spec: str, source: str = "<config>"):
    """The scene generator function named by ``'module:function'``."""
    mod_name, _, attr = spec.partition(":")
    try:
        fn = getattr(importlib.import_module(mod_name), attr)
    except (ImportError, AttributeError) as exc:
        raise ConfigError(f"{source}: [generator] cannot import {spec!r} ({type(exc).__name__}: {exc}); "
                          f"expected 'module:function', e.g. {DEFAULT_GENERATOR!r}") from None
    if not callable(fn):
        raise ConfigError(f"{source}: [generator] {spec!r} is not callable")
    return fn


def resolve(config: DatasetConfig, source: str = "<config>", registry=None) -> DatasetConfig:
    """Validate against the installed plugins and generator; return the canonical config.

    Fails before any work with the file and key: unknown forward model or bad parameters, bad
    radar, a generator that does not import, unknown families (when the generator's module
    lists ``FAMILIES``), or keyword arguments the generator rejects: checked by the module's
    ``validate_params(family, kwargs)`` when it has one, else by drawing one scene per family.
    """
    from xnlos_core.pipeline import load_radar
    from xnlos_core.registry import get_registry
    from xnlos_core.scene import Scene

    radar = load_radar(config.radar, source, config.base_dir)
    fm_cfg = config.forward_model
    try:
        fm = (registry or get_registry()).create("forward_model", fm_cfg.name, fm_cfg.params, source=source)
    except PluginError as exc:
        raise ConfigError(f"{source}: [forward_model.name] {exc}") from None
    gen = import_generator(config.generator, source)
    module = importlib.import_module(config.generator.partition(":")[0])
    known = getattr(module, "FAMILIES", None)
    check = getattr(module, "validate_params", None)
    weights = config.weights()
    if known is not None:
        unknown = [f for f in weights if f not in known]
        if unknown:
            raise ConfigError(f"{source}: [families] unknown famil{'y' if len(unknown) == 1 else 'ies'} "
                              f"{', '.join(map(repr, unknown))}; {config.generator} knows: {', '.join(known)}")
    for fam in weights:
        kwargs = config.generator_kwargs(fam)
        try:
            scene = check(fam, kwargs) if check is not None else gen(fam, 0, **kwargs)
        except Exception as exc:  # the generator's own message says what is wrong
            key = f"family_overrides.{fam}" if fam in config.family_overrides else "generator_params"
            raise ConfigError(f"{source}: [{key}] the generator rejected family {fam!r} with {kwargs}: "
                              f"{type(exc).__name__}: {exc}") from None
        if check is None and not isinstance(scene, Scene):
            raise ConfigError(f"{source}: [generator] {config.generator} returned {type(scene).__name__} for "
                              f"family {fam!r}; expected an xnlos_core.scene.Scene")
    return config.model_copy(update={
        "radar": radar.model_dump(mode="json"),
        "families": weights,
        "forward_model": StageConfig(name=fm_cfg.name, params=fm.params.model_dump(mode="json")),
        "base_dir": ".",
    })
