"""Dataset configuration (TOML): how many maps of which scene families, rendered by which model.

::

    name = "xnlos-default"
    seed = 2024                      # root of every random draw (scenes, families, splits, noise)
    n_maps = 2160                    # RA maps in the dataset (= scenes × frames_per_scene)
    # full_n_maps = 21600            # set by --max-maps: this dataset is n_maps of that one's (see make_plan)
    frames_per_scene = 1             # frames of one scene at t = k·frame_interval [s]
    frame_interval = 0.1
    shard_size = 24                  # maps per shard file (a multiple of frames_per_scene)
    compression = "deflate"          # or "none"
    families = ["crossroads", "t_junction"]  # registered scene generators (xnlos plugins), or a table
                                             # of weights: [families] crossroads = 2.0
    [generator_params]               # parameters of every family's scene generator
    [family_overrides.crossroads]    # … and of one family (over generator_params)
    [radar]                          # RadarConfig fields, or preset = "xband_default" (a shipped preset) or "file.toml"
    [forward_model]
    name = "raytrace"
    params = {}
    [split]                          # fractions of scenes (hence of maps) per split, by scene seed
    train = 0.8
    val = 0.1
    test = 0.1

Scenes come only from registered components of kind ``scene_generator`` (the built-in
families are registered by ``sims.plugin``; a third party adds one through the same
``xnlos_register_components`` hook), so a config names code by registered name only and never
imports or calls anything it spells. The former ``generator = "module:function"`` key accepts
only its old default, ``"sims.generators:generate_scene"`` (deprecated: leave it out), which
stays in the canonical form so that the hashes of existing datasets do not change.

:func:`resolve` validates everything that can fail before any work is done (radar, forward
model and its parameters, families, their parameters) and returns the config with the radar
written out in full, families as weights and the forward model's parameters with their
defaults: the canonical form whose :meth:`DatasetConfig.digest` identifies a dataset.
"""
from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_serializer

from xnlos_core.config import StageConfig, load_toml, validate_model
from xnlos_core.errors import ConfigError, PluginError
from xnlos_core.interfaces import SceneGenerator

SPLITS = ("train", "val", "test")
# The only value of the legacy `generator` key: it meant "the scene generators of sims.generators"
# and now stands for the registry of scene_generator components.
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
    full_n_maps: int | None = Field(
        None, ge=1, le=10_000_000, description="set by --max-maps: n_maps of the full dataset of which this "
                                               "one holds the first scenes of each split (split sizes ∝ the "
                                               "fractions), with the full plan's scene indices, seeds, families "
                                               "and splits (a scene never changes split); None: the dataset is "
                                               "its own full plan")
    shard_size: int = Field(24, ge=1, le=100_000, description="maps per shard file")
    compression: Literal["deflate", "none"] = Field("deflate", description="zip compression of shard members")
    compression_level: int = Field(1, ge=0, le=9, description="deflate level (1 fast … 9 small)")
    families: list[str] | dict[str, float] = Field(..., description="registered scene generators, or name → weight")
    generator_params: dict[str, Any] = Field(default_factory=dict,
                                             description="parameters of every family's scene generator")
    family_overrides: dict[str, dict[str, Any]] = Field(default_factory=dict,
                                                        description="family → parameters of its scene generator "
                                                                    "(over generator_params)")
    generator: str = Field(DEFAULT_GENERATOR, description=f"deprecated; only {DEFAULT_GENERATOR!r}, which "
                                                          "stands for the registered scene generators")
    radar: dict[str, Any] = Field(default_factory=dict, description="RadarConfig fields or preset = FILE")
    forward_model: StageConfig
    split: SplitConfig = Field(default_factory=SplitConfig)
    base_dir: str = Field(".", description="directory relative paths resolve against (set by load)")

    @field_validator("generator")
    @classmethod
    def _no_code(cls, v):
        if v != DEFAULT_GENERATOR:  # never imported: a config names registered components only
            raise ValueError(f"a config cannot name code to import or call; scenes come from the registered "
                             f"scene generators named in `families` (`xnlos plugins` lists them). Leave "
                             f"`generator` out (its one accepted value, {DEFAULT_GENERATOR!r}, is deprecated)")
        return v

    @field_validator("n_maps", "shard_size")
    @classmethod
    def _whole_scenes(cls, v, info: ValidationInfo):
        fps = info.data.get("frames_per_scene", 1)
        if v % fps:
            raise ValueError(f"must be a multiple of frames_per_scene = {fps} (whole scenes), got {v}")
        return v

    @field_validator("full_n_maps")
    @classmethod
    def _full_covers(cls, v, info: ValidationInfo):
        if v is None:
            return v
        n, fps = info.data.get("n_maps"), info.data.get("frames_per_scene", 1)
        if v % fps:
            raise ValueError(f"must be a multiple of frames_per_scene = {fps} (whole scenes), got {v}")
        if n is not None and v < n:
            raise ValueError(f"the full dataset ({v} maps) cannot be smaller than this one (n_maps = {n})")
        return v

    @model_serializer(mode="wrap")
    def _omit_full_when_unset(self, handler):
        # full_n_maps arrived after datasets and their digests existed: left out while unset, so
        # the canonical JSON (hence config_sha256) of every other dataset stays as it was
        data = handler(self)
        if isinstance(data, dict) and data.get("full_n_maps", 0) is None:
            del data["full_n_maps"]
        return data

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

    @property
    def plan_scenes(self) -> int:
        """Scenes of the plan this dataset takes its ``n_scenes`` from (``full_n_maps``; see make_plan)."""
        return (self.full_n_maps or self.n_maps) // self.frames_per_scene

    def weights(self) -> dict[str, float]:
        """family → weight (1 each for a plain list)."""
        return dict(self.families) if isinstance(self.families, dict) else {f: 1.0 for f in self.families}

    def generator_kwargs(self, family: str) -> dict[str, Any]:
        """Parameters of ``family``'s scene generator: generator_params, then its overrides."""
        return {**self.generator_params, **self.family_overrides.get(family, {})}

    def params_key(self, family: str) -> str:
        """The config key that error messages about ``family``'s parameters name."""
        return f"family_overrides.{family}" if family in self.family_overrides else "generator_params"

    def digest(self) -> str:
        """sha256 of the canonical JSON (call on the :func:`resolve`-d config to identify a dataset)."""
        blob = json.dumps(self.model_dump(mode="json", exclude={"base_dir"}), sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()


def parse_dataset_config(table: dict[str, Any], source: str, base_dir: str | Path = ".",
                         n_maps: int | None = None) -> DatasetConfig:
    """Validate a dataset table; errors name ``source`` and the key.

    n_maps (``--max-maps``) overrides the file's: fewer maps than the file's give ``n_maps`` of
    the file's dataset, the first scenes of each of its splits in proportion to the split
    fractions (``full_n_maps`` = the file's ``n_maps``: the same scenes, families and splits, so
    no scene of the full dataset's training or validation split lands in this one's test split);
    more give a larger dataset with a plan of its own."""
    if "base_dir" in table:  # relative paths and the config roots follow from where the file is
        raise ConfigError(f"{source}: [base_dir] is set by the loader (the config file's folder); remove it")
    table = {**table, "base_dir": str(base_dir)}
    if n_maps is not None:
        full = table.get("full_n_maps") or table.get("n_maps", DatasetConfig.model_fields["n_maps"].default)
        table["n_maps"] = n_maps
        if isinstance(full, int) and n_maps < full:
            table["full_n_maps"] = full
        elif "full_n_maps" in table and isinstance(full, int) and n_maps >= full:
            del table["full_n_maps"]
    return validate_model(DatasetConfig, table, source=source)


def load_dataset_config(path: str | Path, n_maps: int | None = None) -> DatasetConfig:
    """Load and validate a dataset TOML file (not yet resolved; see :func:`resolve`)."""
    from xnlos_core.config import expect_kind

    path = Path(path)
    table = load_toml(path)
    expect_kind(table, "dataset", str(path))
    return parse_dataset_config(table, str(path), path.resolve().parent, n_maps)


def generator_classes(config: DatasetConfig, source: str = "<config>", registry=None) -> dict[str, type]:
    """family → the scene generator class registered under that name; ConfigError naming
    ``source`` and ``[families]`` (with the registered names) for a name no plugin registered."""
    from xnlos_core.registry import get_registry

    registry = registry or get_registry()
    known = registry.names("scene_generator")
    unknown = [f for f in config.weights() if f not in known]
    if unknown:
        raise ConfigError(f"{source}: [families] unknown scene generator{'s' if len(unknown) > 1 else ''} "
                          f"{', '.join(map(repr, unknown))}; registered scene generators: "
                          f"{', '.join(known) or '(none)'} (a plugin adds one with registry.add(\"scene_generator\", "
                          f"NAME, a SceneGenerator subclass))")
    return {fam: registry.get("scene_generator", fam).factory for fam in config.weights()}


def scene_generators(config: DatasetConfig, source: str = "<config>", registry=None,
                     classes: dict[str, type] | None = None) -> dict[str, SceneGenerator]:
    """family → its scene generator, built with its validated parameters.

    classes: family → class as :func:`generator_classes` resolved them (in a dataset worker,
    from the parent's registry); else they are looked up in ``registry``. Raises ConfigError
    naming ``source`` and the key: ``[families]`` for an unknown name, ``[generator_params.…]``
    or ``[family_overrides.<family>.…]`` for parameters the family's ``Params`` model rejects.
    """
    classes = generator_classes(config, source, registry) if classes is None else classes
    out = {}
    for fam in config.weights():
        cls = classes.get(fam)
        if not (isinstance(cls, type) and issubclass(cls, SceneGenerator)):
            raise ConfigError(f"{source}: [families] {fam!r} is not a scene generator ({cls!r})")
        params = validate_model(cls.Params, config.generator_kwargs(fam), source=source, prefix=config.params_key(fam))
        out[fam] = cls(params)
    return out


def resolve(config: DatasetConfig, source: str = "<config>", registry=None) -> DatasetConfig:
    """Validate against the installed plugins; return the canonical config.

    Fails before any work with the file and key: unknown forward model or bad parameters, bad
    radar, families that are not registered scene generators, or parameters a family's model
    rejects. Nothing is drawn or imported here.
    """
    from xnlos_core.radar import load_radar
    from xnlos_core.registry import get_registry

    registry = registry or get_registry()
    radar = load_radar(config.radar, source, config.base_dir)
    fm_cfg = config.forward_model
    try:
        fm = registry.create("forward_model", fm_cfg.name, fm_cfg.params, source=source)
    except PluginError as exc:
        raise ConfigError(f"{source}: [forward_model.name] {exc}") from None
    scene_generators(config, source, registry)
    return config.model_copy(update={
        "radar": radar.model_dump(mode="json"),
        "families": config.weights(),
        "forward_model": StageConfig(name=fm_cfg.name, params=fm.params.model_dump(mode="json")),
        "base_dir": ".",
    })
