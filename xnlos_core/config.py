"""TOML configuration: loading, validation with located errors, and `[sweep]` grid expansion.

A pipeline file names one plugin per kind::

    seed = 0
    [radar]                     # RadarConfig fields, or preset = "path/to/radar.toml"
    [scene]                     # builtin = "corner" | file = "scene.toml" | inline walls/objects
    [forward_model]             # exactly one of forward_model / backend
    name = "image"
    [detector]
    name = "nlos_cfar"
    params = { pfa = 1e-5 }
    [wall_estimator]            # optional: without it, a detection-only pipeline
    name = "lsq"
    [reconstructor]             # optional (needs [wall_estimator])
    name = "mirror"
    [tracker]                   # optional: hidden points, or LOS detections without [reconstructor]
    name = "nearest"
    [run]
    frames = 1
    [sweep]                     # optional grid: dotted key → list of values
    "detector.name" = ["cfar", "nlos_cfar"]
    [[sweep.cases]]             # optional list of cases: dotted key → one value each
    name = "rtn"
    "detector.name" = "rtn"

Sweep points are the listed cases (rows that are not a Cartesian product, e.g. Table 2) times
the grid of the remaining ``[sweep]`` keys; see :func:`expand_sweep`.
"""
from __future__ import annotations

import copy
import hashlib
import itertools
import json
import warnings
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from .errors import ConfigError, PipelineWarning
# load_toml, MAX_DEPTH and validate_model are re-exported: plugins and tests import them from here.
from .files import MAX_DEPTH, load_toml  # noqa: F401

SLOW_FRAMES = 10.0  # [s] a frame interval beyond which run.frame_interval warns (ms written as s)
from .interfaces import STAGE_KINDS
from .validation import format_errors, validate_model  # noqa: F401




class StageConfig(BaseModel):
    """One pipeline stage: the plugin ``name`` and its ``params`` table."""

    model_config = ConfigDict(extra="forbid")
    name: str
    params: dict[str, Any] = Field(default_factory=dict)


class RunConfig(BaseModel):
    """How many frames to process and how to score them."""

    model_config = ConfigDict(extra="forbid")
    frames: int = Field(1, ge=1, le=1_000_000, description="frames to simulate or read")
    frame_interval: float = Field(0.1, gt=0, le=3600, description="time between simulated frames [s]; above "
                                  f"{SLOW_FRAMES:g} s warns (milliseconds written as seconds)")
    match_radius: float = Field(1.0, gt=0, le=100, description="F1 match radius [m]")
    figure: bool = Field(True, description="write frame PNGs (which ones: ``figures``); false: none")
    figures: Literal["last", "all"] | Annotated[int, Field(ge=1, le=1_000_000)] = Field(
        "last", description="which frames get a frame_NNNN.png: 'last' (the last frame), 'all', or N (every "
                            "N-th frame, the first and the last included)")
    animation: bool | None = Field(None, description="write sequence.gif (RA map with Doppler-coloured detections "
                                                     "beside the bird's-eye view with tracks) when the run has more "
                                                     "than one frame; unset: only when a tracker is configured")
    blas_threads: int = Field(1, ge=0, le=1024, description="BLAS threads (numpy/scipy OpenBLAS, MKL) while a frame "
                              "is simulated and processed, restored afterwards (xnlos_core.threads): 1 keeps BLAS "
                              "from fighting torch for the cores; 0 leaves BLAS as it is (its default or "
                              "OPENBLAS_NUM_THREADS)")
    share_cores: bool = Field(True, description="before each frame, run torch with the cores that other processes "
                              "left free since the previous frame (xnlos_core.core_share): no collapse when the "
                              "cores are shared; false: torch keeps its thread count")

    @field_validator("frame_interval")
    @classmethod
    def _seconds(cls, v: float) -> float:
        if v > SLOW_FRAMES:
            warnings.warn(f"run.frame_interval = {v:g} s between frames: a radar frames every few milliseconds to "
                          f"a second; if milliseconds were meant, write {v / 1000:g} (the unit is seconds)",
                          PipelineWarning, stacklevel=2)
        return v

    def figure_frames(self, indices) -> list[int]:
        """Which of the recorded frame ``indices`` get a figure (sorted): none without ``figure``;
        per ``figures`` the last, all, or every N-th in frame order plus the last."""
        idx = sorted(indices)
        if not self.figure or not idx:
            return []
        if self.figures == "last":
            return idx[-1:]
        if self.figures == "all":
            return idx
        return sorted(set(idx[::self.figures]) | {idx[-1]})

    def wants_animation(self, tracker: bool) -> bool:
        """Whether ``xnlos run`` writes sequence.gif: more than one frame and ``animation``, which
        when unset follows whether a tracker is configured (``tracker``)."""
        return self.frames > 1 and (tracker if self.animation is None else self.animation)


class PluginsConfig(BaseModel):
    """Plugin loading (mirrors XNLOS_DISABLE_PLUGIN_AUTOLOAD / XNLOS_PLUGINS). Every name is an
    installed entry point of the ``xnlos.plugins`` group (entry-point or distribution name),
    never a module: a config imports no code of its own choosing (``xnlos -p MODULE`` does)."""

    model_config = ConfigDict(extra="forbid")
    autoload: bool = True
    allow: list[str] | None = None
    load: list[str] = Field(default_factory=list, description="installed xnlos.plugins entry points to load "
                                                              "(entry-point or distribution names), e.g. with "
                                                              "autoload = false")


class PipelineConfig(BaseModel):
    """A validated pipeline file (see module docstring)."""

    model_config = ConfigDict(extra="forbid")
    seed: int = Field(0, ge=0, lt=2**63)
    name: str = "pipeline"
    radar: dict[str, Any] = Field(default_factory=dict)
    scene: dict[str, Any] = Field(default_factory=dict)
    forward_model: StageConfig | None = None
    backend: StageConfig | None = None
    detector: StageConfig
    wall_estimator: StageConfig | None = Field(None, description="relay-wall stage; leave out for a "
                                                                 "detection-only pipeline")
    reconstructor: StageConfig | None = Field(None, description="mirror stage (needs wall_estimator)")
    tracker: StageConfig | None = Field(None, description="tracking stage: the reconstructor's hidden points, "
                                                          "or the line-of-sight detections without one")
    run: RunConfig = Field(default_factory=RunConfig)
    plugins: PluginsConfig = Field(default_factory=PluginsConfig)
    sweep: dict[str, list[Any]] | None = None
    base_dir: str = Field(".", description="directory relative paths resolve against (set by load)")

    @field_validator("sweep")
    @classmethod
    def _sweep_nonempty(cls, v):
        if v is not None:
            for k, vals in v.items():
                if not vals:
                    raise ValueError(f"sweep key {k!r} has an empty list of values")
        return v

    def model_post_init(self, _ctx) -> None:
        if (self.forward_model is None) == (self.backend is None):
            raise ValueError("exactly one of [forward_model] or [backend] must be given as the frame source")
        # Each stage feeds the next; one without its input could never run (a detection-only
        # pipeline, [detector] alone, is fine).
        # A tracker without a reconstructor tracks the line-of-sight detections (pipeline.py).
        for stage, needs in (("reconstructor", "wall_estimator"),):
            if getattr(self, stage) is not None and getattr(self, needs) is None:
                raise ValueError(f"[{stage}] needs [{needs}] (it works on that stage's output); add "
                                 f"[{needs}] or remove [{stage}]")

    def stages(self) -> dict[str, StageConfig]:
        """The configured stages by kind (absent optional stages omitted)."""
        return {k: getattr(self, k) for k in STAGE_KINDS if getattr(self, k) is not None}

    def digest(self) -> str:
        """sha256 of the canonical JSON of this config (provenance). ``run.animation`` and
        ``run.figures`` are left out: they change no result, only which pictures are drawn (so turning
        them on resumes a finished run, and runs made before they existed keep their hash); so are
        ``run.blas_threads`` and ``run.share_cores``, which change only speed (like OPENBLAS_NUM_THREADS,
        never hashed)."""
        return self._digest({"animation", "figures", "blas_threads", "share_cores"})

    def run_digest(self) -> str:
        """:meth:`digest` without ``run.frames``: frame k is the same whatever the count (its draws come
        from child k of the seed), so a run directory holding this digest (``run_sha256``) is extended by
        asking for more frames. Run directories written before it existed are recognised by
        ``config_sha256`` (:func:`xnlos_core.rundir.claim` takes the first key the old record holds)."""
        return self._digest({"frames", "animation", "figures", "blas_threads", "share_cores"})

    def _digest(self, run_exclude: set[str]) -> str:
        dump = self.model_dump(exclude={"base_dir": True, "run": run_exclude})
        blob = json.dumps(dump, sort_keys=True, default=str)
        return hashlib.sha256(blob.encode()).hexdigest()


def parse_pipeline(table: dict[str, Any], source: str, base_dir: str | Path = ".") -> PipelineConfig:
    """Validate a pipeline table; errors name ``source`` and the key."""
    if "base_dir" in table:  # relative paths and the config roots follow from where the file is
        raise ConfigError(f"{source}: [base_dir] is set by the loader (the config file's folder); remove it")
    table = {**table, "base_dir": str(base_dir)}
    try:
        return PipelineConfig.model_validate(table)
    except ValidationError as exc:
        raise ConfigError(format_errors(PipelineConfig, exc, source, "")) from None
    except ValueError as exc:  # from model_post_init
        raise ConfigError(f"{source}: {exc}") from None


# config kind → (the keys that mark it, the command that takes it, a shipped example)
CONFIG_KINDS = {
    "cross-modality study": (("modality",), "xnlos crossmodal", "configs/ablations/crossmodal.toml"),
    "training": (("data", "model"), "xnlos train", "configs/training/tiny.toml"),
    "dataset": (("families",), "xnlos simulate", "configs/datasets/smoke.toml"),
    "pipeline": (("detector",), "xnlos run / sweep / eval", "configs/pipelines/corner.toml"),
}


def config_kind(table: dict[str, Any]) -> str | None:
    """Which kind of config ``table`` is, by the keys that mark each (:data:`CONFIG_KINDS`); None when
    it holds none of them."""
    return next((kind for kind, (keys, _, _) in CONFIG_KINDS.items() if all(k in table for k in keys)), None)


def expect_kind(table: dict[str, Any], kind: str, source: str) -> None:
    """ConfigError naming the command that takes ``table`` when it is plainly another kind of config
    than ``kind`` (a pipeline config given to ``xnlos crossmodal``, …), instead of a list of the keys
    it lacks."""
    found = config_kind(table)
    if found is not None and found != kind:
        command, example = CONFIG_KINDS[found][1], CONFIG_KINDS[kind][2]
        raise ConfigError(f"{source}: this is a {found} config (for {command}), not a {kind} config "
                          f"(like {example})")


def load_pipeline(path: str | Path) -> PipelineConfig:
    """Load and validate a pipeline TOML file (ConfigError naming the right command for another kind)."""
    path = Path(path)
    table = load_toml(path)
    expect_kind(table, "pipeline", str(path))
    return parse_pipeline(table, str(path), base_dir=path.resolve().parent)


def _set_dotted(table: dict[str, Any], key: str, value: Any, source: str) -> None:
    parts = key.split(".")
    node = table
    for i, part in enumerate(parts[:-1]):
        nxt = node.get(part)
        if nxt is None:
            nxt = node[part] = {}
        if not isinstance(nxt, dict):
            raise ConfigError(f"{source}: [sweep] key {key!r}: {'.'.join(parts[:i + 1])} is not a table")
        node = nxt
    node[parts[-1]] = value


def _check_root(key: str, source: str, where: str) -> None:
    root = key.split(".")[0]
    if root not in PipelineConfig.model_fields or root in ("sweep", "base_dir"):
        raise ConfigError(f"{source}: {where} {key!r}: {root!r} is not a pipeline key; "
                          f"allowed roots: {', '.join(f for f in PipelineConfig.model_fields if f not in ('sweep', 'base_dir'))}")


def sweep_cases(sweep: dict[str, Any], source: str) -> list[dict[str, Any]]:
    """The validated ``[[sweep.cases]]`` list: each case a non-empty table {dotted key: value}."""
    cases = sweep.get("cases")
    if cases is None:
        return []
    if not isinstance(cases, list) or not cases or not all(isinstance(c, dict) for c in cases):
        raise ConfigError(f"{source}: [sweep] cases must be a non-empty list of tables ([[sweep.cases]] with "
                          f"dotted key = value lines), got {cases!r}")
    for i, case in enumerate(cases):
        if not case:
            raise ConfigError(f"{source}: [[sweep.cases]] #{i}: an empty case; give at least one dotted key = value")
        for k in case:
            _check_root(k, source, f"[[sweep.cases]] #{i} key")
    return [dict(c) for c in cases]


def expand_sweep(table: dict[str, Any], source: str = "<config>") -> list[tuple[dict[str, Any], dict[str, Any]]]:
    """Expand the ``[sweep]`` table: returns [(assignment {dotted key: value}, full table)].

    Keys are dotted paths into the pipeline table ("detector.name", "detector.params.pfa",
    "seed"). Grid keys map to lists of values and give their Cartesian product in the file's key
    order. ``cases`` (``[[sweep.cases]]``) lists assignments one by one, {dotted key: value}; the
    points are then every case combined with every grid point (cases vary slowest). A key may
    not be both a grid key and a case key. Without a sweep the single table is returned with an
    empty assignment. Setting ``<stage>.name`` to another plugin without ``<stage>.params``
    starts that stage's params from {} (another plugin takes other parameters).
    """
    sweep = table.get("sweep") or {}
    if not isinstance(sweep, dict):
        raise ConfigError(f"{source}: [sweep] must be a table of dotted keys → lists")
    cases = sweep_cases(sweep, source)
    keys = [k for k in sweep if k != "cases"]
    for k in keys:
        if not isinstance(sweep[k], list) or not sweep[k]:
            raise ConfigError(f"{source}: [sweep] {k!r} must be a non-empty list of values, got {sweep[k]!r}")
        _check_root(k, source, "[sweep]")
        clash = [i for i, c in enumerate(cases) if k in c]
        if clash:
            raise ConfigError(f"{source}: [sweep] {k!r} is both a grid key and a key of [[sweep.cases]] "
                              f"#{clash[0]}; give it in one place")
    out = []
    for case in cases or [{}]:
        for values in itertools.product(*(sweep[k] for k in keys)):
            t = copy.deepcopy({k: v for k, v in table.items() if k != "sweep"})
            assignment = {**case, **dict(zip(keys, values))}
            for k, v in assignment.items():
                stage = k.rsplit(".", 1)[0]
                if k.endswith(".name") and isinstance(table.get(stage), dict) and v != table[stage].get("name") \
                        and not any(a.startswith(stage + ".params") for a in assignment):
                    # Another plugin takes other parameters: the base file's params do not carry over.
                    _set_dotted(t, stage + ".params", {}, source)
                _set_dotted(t, k, copy.deepcopy(v), source)
            out.append((assignment, t))
    return out
