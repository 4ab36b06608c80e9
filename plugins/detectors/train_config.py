"""Training configuration (TOML) for ``xnlos train``; strict, with errors naming file and key.

::

    name = "swin_unet-default"
    seed = 0                          # data order, crops, weight init: every draw derives from it
    out = "../../out/train/swin_unet" # checkpoints and logs (relative paths: to this file's folder)
    device = "auto"                   # auto: cuda when available, else cpu
    export = "../../plugins/detectors/models/swin_unet.pt"   # optional: also write the final model here

    [data]
    dataset = "../../out/data/default"  # a dataset from `xnlos simulate` (splits train / val)
    # or, for small runs, maps generated on the fly:
    # [data.generate]
    # forward_model = { name = "image" }
    # radar = { n_samples = 128, max_range = 30.0, n_azimuth_bins = 31 }
    # scene = { builtin = "corner" }  # or families = ["crossroads", ...] (sims.generators)
    # n_train = 8
    # n_val = 2
    crop = [160, 96]                  # random training crops (range, azimuth) [cells]; omit: whole maps

    [model]
    name = "swin_unet"                # swin_unet | unet | further_than_cfar | rtn
    params = { embed_dim = 32 }       # the architecture's hyper-parameters
    sigma = [0.7, 1.0]                # Gaussian target width (range, azimuth) [cells]

    [optim]
    epochs = 30
    batch_size = 8
    lr = 2e-3
    patience = 6                      # early stopping: epochs without a better validation Macro-F1
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from plugins.training.optim import OptimConfig as BaseOptim
from xnlos_core.config import StageConfig, load_toml, validate_model
from xnlos_core.errors import ConfigError

ARCHITECTURES = ("swin_unet", "unet", "further_than_cfar", "rtn")


class GenerateConfig(BaseModel):
    """Maps simulated on the fly (small runs and tests): scene(s) × forward model × radar."""

    model_config = ConfigDict(extra="forbid")
    forward_model: StageConfig = Field(default_factory=lambda: StageConfig(name="image"))
    radar: dict[str, Any] = Field(default_factory=dict, description="RadarConfig fields or preset = FILE")
    scene: dict[str, Any] | None = Field(None, description="one scene table (builtin / file / inline); maps "
                                                          "differ by receiver noise")
    families: list[str] | None = Field(None, description="scene families of sims.generators, cycled")
    n_train: int = Field(8, ge=1, le=100_000)
    n_val: int = Field(2, ge=1, le=100_000)
    n_test: int = Field(0, ge=0, le=100_000)

    @model_validator(mode="after")
    def _one_source(self):
        if (self.scene is None) == (self.families is None):
            raise ValueError("give exactly one of scene = {...} or families = [...]")
        return self


LATE_OPTIONS = (("data", "flip_azimuth", False), ("data", "doppler", False), ("data", "previous_frames", 0))  # (section, key, default): see TrainConfig.digest


class DataConfig(BaseModel):
    """Where the maps come from and how training samples are cut."""

    model_config = ConfigDict(extra="forbid")
    dataset: str | None = Field(None, description="dataset directory written by `xnlos simulate`")
    generate: GenerateConfig | None = None
    train_split: str = "train"
    val_split: str = "val"
    max_train_maps: int | None = Field(None, ge=1, description="use only the first N training maps")
    max_val_maps: int | None = Field(None, ge=1, description="use only the first N validation maps")
    crop: tuple[int, int] | None = Field(None, description="training crop (range, azimuth) [cells]")
    flip_azimuth: bool = Field(False, description="mirror each training sample in azimuth with probability "
                                                  "1/2 (seeded); needs an azimuth axis symmetric about boresight")
    match_radius: float = Field(1.0, gt=0, le=100, description="F1 match radius [m] (Table 2 metrics)")
    doppler: bool = Field(False, description="add the Doppler channels (radial velocity, its σ, Doppler spread; "
                                             "plugins.detectors.features) to the network's inputs; needs maps "
                                             "from Doppler processing (forward model params doppler = true)")
    previous_frames: int = Field(0, ge=0, le=4, description="also feed the normalised log power of this many "
                                 "earlier frames of the same sequence (plugins.detectors.features); a sequence's "
                                 "first frames repeat the oldest one there is")

    @model_validator(mode="after")
    def _one_source(self):
        if (self.dataset is None) == (self.generate is None):
            raise ValueError("give exactly one of data.dataset = DIR or a [data.generate] table")
        if self.crop is not None and min(self.crop) < 4:
            raise ValueError(f"crop {self.crop}: each side must be ≥ 4 cells")
        return self


class ModelConfig(BaseModel):
    """Which detector network to train, its hyper-parameters and target width."""

    model_config = ConfigDict(extra="forbid")
    name: str = "swin_unet"
    params: dict[str, Any] = Field(default_factory=dict, description="the architecture's hyper-parameters")
    sigma: tuple[float, float] = Field((0.7, 1.0), description="Gaussian target σ (range, azimuth) [cells]")

    @field_validator("name")
    @classmethod
    def _known(cls, v):
        if v not in ARCHITECTURES:
            raise ValueError(f"unknown model {v!r}; expected one of {', '.join(ARCHITECTURES)}")
        return v

    @field_validator("sigma")
    @classmethod
    def _positive(cls, v):
        if not all(0 < s <= 20 for s in v):  # so that NaN fails too (min/max skip a NaN)
            raise ValueError(f"sigma {v}: widths must lie in (0, 20] cells")
        return v


class OptimConfig(BaseOptim):
    """AdamW with a warm-up and cosine learning-rate schedule and early stopping
    (:mod:`plugins.training.optim`, whose defaults are the detectors')."""

    steps_per_epoch: int | None = Field(None, ge=1, description="cap on optimizer steps per epoch")
    warmup_steps: int = Field(50, ge=0, le=1_000_000, description="linear learning-rate warm-up")


class EvalConfig(BaseModel):
    """Validation: decoding settings searched for the best Macro-F1."""

    model_config = ConfigDict(extra="forbid")
    thresholds: list[float] = Field([0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6], min_length=1,
                                    description="candidate confidence thresholds (each class picks its best)")
    windows: list[tuple[int, int]] = Field([(1, 3), (3, 3)], min_length=1)
    every: int = Field(1, ge=1, description="validate every N epochs (and after the last)")

    @field_validator("thresholds")
    @classmethod
    def _in_unit(cls, v):
        if any(not 0 < t < 1 for t in v):
            raise ValueError(f"thresholds {v}: each must lie in (0, 1)")
        return sorted(v)


class TrainConfig(BaseModel):
    """A validated training file (module doc)."""

    model_config = ConfigDict(extra="forbid")
    name: str = "train"
    seed: int = Field(0, ge=0, lt=2**63)
    out: str = Field("out/train", description="output directory")
    export: str | None = Field(None, description="also write the final model to this path (into the installed "
                               "package only when the command names it: --export)")
    device: str = Field("auto", pattern=r"^(auto|cpu|cuda(:\d+)?|mps)$")
    threads: int | None = Field(None, ge=1, le=1024, description="torch CPU threads (None: torch's setting, "
                                "which the process thread policy makes one per available core; "
                                "xnlos_core.threads)")
    init: str | None = Field(None, description="start from the weights of this checkpoint (same architecture "
                             "and hyper-parameters): fine-tuning, e.g. on whole maps after training on crops")
    data: DataConfig
    model: ModelConfig = Field(default_factory=ModelConfig)
    optim: OptimConfig = Field(default_factory=OptimConfig)
    eval: EvalConfig = Field(default_factory=EvalConfig)

    def channels(self) -> tuple[str, ...]:
        """The network's input channels (:func:`plugins.detectors.features.channel_layout`): the
        power-map ones, the Doppler ones with ``data.doppler``, the previous frames' log power with
        ``data.previous_frames``."""
        from .features import channel_layout

        return channel_layout(self.data.doppler, self.data.previous_frames)

    def hparams(self):
        """The architecture's validated hyper-parameter model; ``in_channels`` follows the input
        channels (:meth:`channels`), and a different value in model.params is a ConfigError."""
        from .nets import architectures

        arch = architectures()[self.model.name]
        n = len(self.channels())
        given = self.model.params.get("in_channels")
        if given is not None and given != n:
            raise ConfigError(f"model.params.in_channels = {given!r}: the inputs are {n} channels "
                              f"({', '.join(self.channels())}); leave in_channels out, it follows data.doppler and "
                              "data.previous_frames")
        return validate_model(arch.HParams, {**self.model.params, "in_channels": n},
                              source=f"model {self.model.name!r}", prefix="model.params")

    def digest(self) -> str:
        """sha256 of the canonical config, excluding where outputs go (identifies a run for resuming).

        Options added after models were shipped (LATE_OPTIONS) count only when set, so that the runs
        and checkpoints made before them keep their identity."""
        dump = self.model_dump(exclude={"out", "export", "threads"})
        for section, key, default in LATE_OPTIONS:
            if dump[section].get(key) == default:
                del dump[section][key]
        blob = json.dumps(dump, sort_keys=True, default=str)
        return hashlib.sha256(blob.encode()).hexdigest()


def parse_train_config(table: dict[str, Any], source: str = "<config>") -> TrainConfig:
    """Validate a training table; the architecture's hyper-parameters are checked too."""
    cfg = validate_model(TrainConfig, table, source=source)
    try:
        cfg.hparams()
    except ConfigError as exc:
        raise ConfigError(f"{source}: {exc}") from None
    return cfg


def load_train_config(path: str | Path) -> TrainConfig:
    """Load and validate a training TOML file."""
    return parse_train_config(load_toml(path), str(path))


def check_train_config(cfg: TrainConfig, source: str, base_dir: str | Path = ".") -> None:
    """``xnlos check`` beyond parsing: what ``xnlos train`` builds from ``[data.generate]`` before
    simulating (relative paths from ``base_dir``, the config file's folder, as the trainer takes them)."""
    gen = cfg.data.generate
    if gen is None:
        return
    from xnlos_core.radar import load_radar
    from xnlos_core.registry import get_registry
    from xnlos_core.scene import load_scene

    source = f"{source}: [data.generate]"
    radar = load_radar(gen.radar, source, base_dir)
    fm = get_registry().create("forward_model", gen.forward_model.name, gen.forward_model.params, source=source)
    if gen.scene is not None:
        fm.check(load_scene(gen.scene, source, base_dir), radar)
    scene_generators(gen, source)


def scene_generators(gen: GenerateConfig, source: str = "data.generate") -> list:
    """The registered ``scene_generator`` components named in ``gen.families`` (default parameters),
    in order; ConfigError naming ``source``, the key and the registered names for an unknown one."""
    from xnlos_core.errors import PluginError
    from xnlos_core.registry import get_registry

    reg = get_registry()
    try:
        return [reg.create("scene_generator", f) for f in gen.families or ()]  # default parameters
    except PluginError as exc:
        raise ConfigError(f"{source}: [families] {exc}") from None
