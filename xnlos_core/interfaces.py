"""The plugin kinds. A plugin is a class with a pydantic ``Params`` model; ``__init__`` only
stores the validated parameters (scikit-learn style) and the stage method does the work.

Six kinds are pipeline stages; ``scene_generator`` draws the random scenes a dataset is
rendered from (a dataset config names them in ``families``), and ``nlos_solver`` reconstructs
optical transient volumes for the cross-modality comparison (neither is a stage). Any registered plugin of
a kind can replace any other of that kind by a one-line config change, and a config can name
nothing else: no module, no function. :data:`BASES` (kind → interface) is the one list of kinds.

Each interface declares everything its callers use. Optional capabilities have a default that
says "not available": :attr:`Backend.n_frames` (None), :meth:`Detector.heatmap` (None),
:meth:`ForwardModel.simulate_adc` (PluginError; :attr:`ForwardModel.supports_adc` asks first),
:meth:`FrameState.state` / :meth:`FrameState.load_state` of a tracker or a wall estimator (PluginError;
:attr:`FrameState.supports_state`),
:meth:`WallEstimator.warm_up` and :meth:`Detector.warm_up` (build nothing). Input checks every implementation needs live
here once (:meth:`Backend.check_max_frames`, :meth:`Detector.check_frame`).
"""
from __future__ import annotations

import abc
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict

from .errors import InputError, PluginError
from .radar import RadarConfig
from .validation import validate_model
from .types import Detections, Frame, HiddenPoints, Tracks, WallPosterior

if TYPE_CHECKING:
    from .nlos_volume import NLOSVolume
    from .scene import Scene
    from .transient import TransientVolume


class NoParams(BaseModel):
    """Parameter model of a plugin without parameters (unknown keys are rejected)."""

    model_config = ConfigDict(extra="forbid")


class Plugin:
    """Common base: stores a validated ``Params`` instance as ``self.params``."""

    Params: ClassVar[type[BaseModel]] = NoParams
    kind: ClassVar[str]  # the registry kind; each interface below sets it, and :data:`BASES` is keyed by it
    stage: ClassVar[bool] = True  # a pipeline stage (a config table of that name); False: a dataset's helper

    def __init__(self, params: BaseModel | dict[str, Any] | None = None):
        if params is None:
            params = self.Params()
        elif isinstance(params, dict):
            params = validate_model(self.Params, params, source=type(self).__name__, prefix="params")
        self.params = params

    def get_params(self) -> dict[str, Any]:
        """Parameters as a plain dict (for provenance and cloning)."""
        return self.params.model_dump()

    def check_radar(self, radar: RadarConfig) -> None:
        """Check the parameters against the radar they will run with — bounds that depend on the RA
        map's size (``radar.n_range_bins`` × ``radar.n_azimuth_bins``), e.g. a detector's window —
        and raise :class:`xnlos_core.errors.ConfigError` naming the parameter, its value, the map
        size and the allowed maximum. :class:`xnlos_core.pipeline.Pipeline` calls it for every stage
        on construction, so ``xnlos check`` refuses what ``xnlos run`` would. Default: nothing to check.
        """

    def state_sha256(self) -> str | None:
        """Hash of what, besides the parameters, decides this stage's output — learned weights read
        from a file — or None when the parameters decide it all (the default).

        Resumable runs (``xnlos run``, ``eval``, sweeps) compare it, so that results made with other
        weights under an unchanged config (a retrained model exported over the shipped one) are
        never resumed or reported as current.
        """
        return None


class FrameState:
    """What a stage carries from frame to frame (a tracker's tracks, a wall estimator's history of
    LOS detections), and its checkpoint. :class:`xnlos_core.pipeline.Pipeline` resets every stage
    whose :attr:`carries_state` is True at the start of a run and of each sequence
    (:meth:`~xnlos_core.pipeline.Pipeline.reset`), replays a resumed run from frame 0 unless all of
    them have a checkpoint (:attr:`supports_state`), and ``xnlos run`` writes those checkpoints with
    each frame (:mod:`xnlos_core.checkpoint`)."""

    @property
    def carries_state(self) -> bool:
        """True when an output depends on earlier frames (a tracker always; the default: True)."""
        return True

    def reset(self) -> None:
        """Forget everything earlier frames left (the default: nothing to forget)."""

    def state(self) -> dict[str, Any]:
        """Optional: everything the stage carries from frame to frame, as a JSON-able dict
        (numbers, strings, lists; arrays as nested lists, floats exact through ``json``), so that
        ``xnlos run`` can checkpoint it with each frame and resume without replaying the frames
        before (:mod:`xnlos_core.checkpoint`). ``load_state(state())`` on a fresh instance with
        the same parameters must give bit-identical outputs afterwards. The default raises
        :class:`xnlos_core.errors.PluginError`: the stage has no checkpoint, and a resumed run
        replays every frame from 0 (:attr:`supports_state` asks first)."""
        raise PluginError(f"{type(self).__name__}.state: this {self.kind} has no checkpoint; a resumed run "
                          "replays its frames from 0")

    def load_state(self, state: dict[str, Any]) -> None:
        """Optional: restore what :meth:`state` returned (it replaces everything held). Raises
        :class:`xnlos_core.errors.InputError` naming the key for a state that is not one this stage
        wrote; the default raises :class:`xnlos_core.errors.PluginError` (no checkpoint)."""
        raise PluginError(f"{type(self).__name__}.load_state: this {self.kind} has no checkpoint")

    @property
    def supports_state(self) -> bool:
        """True when the stage overrides :meth:`state` and :meth:`load_state` (checkpointable)."""
        return type(self).state is not FrameState.state and type(self).load_state is not FrameState.load_state


class ForwardModel(Plugin, abc.ABC):
    """Scene → Frame. ``simulate`` must be deterministic given ``rng`` and return ground truth."""

    kind: ClassVar[str] = "forward_model"

    @abc.abstractmethod
    def simulate(self, scene, radar: RadarConfig, rng: np.random.Generator, timestamp: float = 0.0,
                 index: int = 0) -> Frame:
        """Render ``scene`` (an :class:`xnlos_core.scene.Scene`) at ``timestamp`` [s] into a Frame."""

    def check(self, scene, radar: RadarConfig) -> None:
        """Raise the typed error (InputError, ConfigError) that :meth:`simulate` would raise for this
        scene and radar at t = 0, without simulating; cheap. ``xnlos check`` and every run call it
        through :meth:`xnlos_core.pipeline.Pipeline.validate`. The default accepts everything."""

    def simulate_adc(self, scene, radar: RadarConfig, rng: np.random.Generator, timestamp: float = 0.0,
                     index: int = 0) -> tuple[np.ndarray, Frame]:
        """Optional: (ADC cube, Frame) of ``scene`` at ``timestamp`` [s]: the noisy ADC cube
        (n_samples, n_channels) [√W] the RA map is formed from, and the Frame :meth:`simulate`
        returns. The radar emulator's ADC payloads need it (:attr:`supports_adc`). The default
        raises :class:`xnlos_core.errors.PluginError`: the model renders RA maps only."""
        raise PluginError(f"{type(self).__name__}.simulate_adc: this forward model renders RA maps only, no "
                          "ADC cube; ADC payloads need a model that overrides simulate_adc (image, raytrace)")

    @property
    def supports_adc(self) -> bool:
        """True when the model overrides :meth:`simulate_adc` (renders ADC cubes)."""
        return type(self).simulate_adc is not ForwardModel.simulate_adc


class Backend(Plugin, abc.ABC):
    """A source of measured frames (hardware, a recording). Used as a context manager."""

    kind: ClassVar[str] = "backend"

    def open(self, radar: RadarConfig) -> None:
        """Connect and configure the sensor; the default does nothing."""

    def close(self) -> None:
        """Release the sensor; must be safe to call twice."""

    @abc.abstractmethod
    def frames(self, max_frames: int | None = None) -> Iterator[Frame]:
        """Yield complete frames in order; never yields a partial or corrupted frame. Call
        :meth:`check_max_frames` first."""

    @property
    def n_frames(self) -> int | None:
        """How many frames :meth:`frames` yields without a limit, or None when unknown (a live
        sensor, the default); progress bars use it."""
        return None

    #: True when the frames carry the source's own radar (a recording's description, a dataset, saved
    #: frames), not the pipeline's ``[radar]`` that :meth:`open` is given (a live sensor: False).
    own_radar: ClassVar[bool] = False

    def source_radar(self) -> RadarConfig | None:
        """The radar of the maps :meth:`frames` will yield when the source fixes it (:attr:`own_radar`)
        and it can be read without yielding a frame; None (the default): the pipeline's radar, or, for
        a source with its own radar, not known before the first frame. :class:`xnlos_core.pipeline.Pipeline`
        checks a learned detector against it before the first frame (:meth:`Detector.check_model`)."""
        return None

    def check_source(self) -> None:
        """Open what :meth:`frames` reads and check it as far as it can be without yielding a frame
        (a recording's file: its format, header, shape and frame count), raising the typed error
        (InputError, ConfigError) that :meth:`frames` would raise, naming the file. ``xnlos check``
        calls it (:meth:`xnlos_core.pipeline.Pipeline.check_inputs`), so that it refuses the sources a
        run would refuse. The default checks nothing (a live sensor is only reached by ``open``)."""

    def check_max_frames(self, max_frames: int | None) -> None:
        """InputError unless ``max_frames`` is None or an integer ≥ 0 (every :meth:`frames` checks it)."""
        if max_frames is not None and (not isinstance(max_frames, int) or max_frames < 0):
            raise InputError(f"{type(self).__name__}.frames: max_frames must be None or an integer ≥ 0, "
                             f"got {max_frames!r}")

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class Detector(Plugin, abc.ABC):
    """Frame → Detections (range, azimuth, LOS/mNLOS class, confidence)."""

    kind: ClassVar[str] = "detector"
    #: Whether :meth:`detect` labels detections LOS / mNLOS. False for a detector whose every
    #: detection is UNCLASSIFIED (plain CFAR): it can be scored class-agnostically, but a wall
    #: estimator (needs LOS) and a reconstructor (needs mNLOS) behind it never get any input, so
    #: :class:`xnlos_core.pipeline.Pipeline` warns (:class:`~xnlos_core.errors.PipelineWarning`).
    classifies: ClassVar[bool] = True

    @abc.abstractmethod
    def detect(self, frame: Frame) -> Detections:
        """Find peaks in ``frame.ra_map``; an empty map region gives empty Detections, not an error.
        Call :meth:`check_frame` first."""

    def heatmap(self, frame: Frame) -> np.ndarray | None:
        """Optional: LOS and mNLOS confidence maps in [0, 1], float32 of shape (2, H, W) (learned
        detectors; H × W the RA map's grid or the network head's), drawn in the per-frame figure.
        The default, None, means the detector has none."""
        return None

    def warm_up(self, radar: RadarConfig | None = None) -> int:
        """Optional: load and prepare what :meth:`detect` would otherwise prepare on the first frame
        (a learned detector: the network, one forward on an empty map of ``radar``'s grid, compilation),
        so that the first frame runs at the steady-state speed. :class:`xnlos_core.pipeline.Pipeline`
        calls it before its first frame. Returns how many warm-up passes were made; the default
        prepares nothing: 0."""
        return 0

    def check_model(self, radar: RadarConfig) -> list[str]:
        """Optional: compare what a learned model was trained on (carrier, bandwidth, virtual array,
        grid) with ``radar``, the radar of the maps it will see, before any frame; raise
        :class:`xnlos_core.errors.ConfigError` naming each difference it refuses. Returns the
        differences it accepts (a setting to run anyway), which the run's provenance records.
        :meth:`xnlos_core.pipeline.Pipeline.check_inputs` (``xnlos check``) and ``warm_up`` call it.
        The default has no model to compare: []."""
        return []

    def check_frame(self, frame: Frame) -> None:
        """InputError unless ``frame`` is a :class:`xnlos_core.types.Frame` (every :meth:`detect` checks it)."""
        if not isinstance(frame, Frame):
            raise InputError(f"{type(self).__name__}.detect: expected a Frame, got {type(frame).__name__}")


class WallEstimator(FrameState, Plugin, abc.ABC):
    """LOS detections → relay walls with uncertainty.

    A wall estimator may pool the LOS detections of earlier frames (a static radar sees the same
    facades frame after frame): it then says so through :attr:`carries_state` and forgets them on
    :meth:`reset`. The default is one frame at a time (no state)."""

    kind: ClassVar[str] = "wall_estimator"

    @abc.abstractmethod
    def estimate(self, detections: Detections) -> list[WallPosterior]:
        """Fit walls to the LOS detections. Raises InsufficientDataError with < 2 LOS points."""

    def warm_up(self, max_points: int = 64) -> int:
        """Optional: build once what :meth:`estimate` would otherwise build on first use, for up to
        ``max_points`` LOS detections (casadi Functions per problem size), so that timings measure
        the solve alone; returns how many were built. The default builds nothing: 0."""
        return 0

    @property
    def carries_state(self) -> bool:
        """Whether :meth:`estimate` uses earlier frames' detections; the default: False."""
        return False


class Reconstructor(Plugin, abc.ABC):
    """mNLOS detections + walls → hidden points (Eq. 7)."""

    kind: ClassVar[str] = "reconstructor"

    @abc.abstractmethod
    def reconstruct(self, detections: Detections, walls: list[WallPosterior]) -> HiddenPoints:
        """Mirror each mNLOS detection across its wall; rows reference ``detections`` by index."""


class Tracker(FrameState, Plugin, abc.ABC):
    """Hidden points over frames → tracks with predictions."""

    kind: ClassVar[str] = "tracker"

    @abc.abstractmethod
    def update(self, points: HiddenPoints, timestamp: float) -> Tracks:
        """Ingest one frame's hidden points at ``timestamp`` [s]; return the current tracks."""

    def reset(self) -> None:
        """Forget all tracks (called at the start of a run and of each sequence)."""


class SceneGenerator(Plugin, abc.ABC):
    """seed → Scene: one scene family (Sec. 5.1), its ``Params`` the family's parameters.

    A dataset config lists registered scene generators by name in ``families``; its
    ``generator_params`` and ``family_overrides.<name>`` tables are validated by ``Params``.
    """

    kind: ClassVar[str] = "scene_generator"
    stage: ClassVar[bool] = False

    @abc.abstractmethod
    def generate(self, seed: int) -> "Scene":
        """A random :class:`xnlos_core.scene.Scene` drawn from ``numpy.random.default_rng(seed)``
        only (``seed`` an integer ≥ 0): the same parameters and seed give the same scene, in any
        process. Raises :class:`xnlos_core.errors.InputError` when no valid scene can be drawn."""


class NLOSSolver(Plugin, abc.ABC):
    """TransientVolume → NLOSVolume: a reconstruction solver of the optical (SPAD) modality for the
    cross-modality comparison (Sec. 5.1.2, Fig. 5) — f-k migration, LCT, or a third
    party's (phasor fields). Not a pipeline stage: the comparison calls it on transient volumes.
    """

    kind: ClassVar[str] = "nlos_solver"
    stage: ClassVar[bool] = False

    @abc.abstractmethod
    def reconstruct(self, volume: "TransientVolume") -> "NLOSVolume":
        """Hidden albedo (Z, H, W) ≥ 0 on the volume's wall grid, depth z = c·t/2 [m] per time bin.
        Raises :class:`xnlos_core.errors.InputError` naming the input for a volume the solver cannot
        invert (all-zero counts, a non-square scan grid, too few time bins)."""


class TransientModel(Plugin, abc.ABC):
    """Scene → TransientVolume: a forward model of the optical (SPAD) modality for the
    cross-modality comparison (Sec. 5.1.2) — a confocal scan of a patch of the scene's
    relay wall. Not a pipeline stage: the study (:mod:`xnlos_core.app.crossmodal.study`) calls it, so that
    the core composes the SPAD simulator of ``sims`` through the registry.
    """

    kind: ClassVar[str] = "transient_model"
    stage: ClassVar[bool] = False

    @abc.abstractmethod
    def simulate(self, scene: "Scene", seed: int) -> "TransientVolume":
        """Photon counts (T, H, W) of a scan of ``scene`` drawn from ``numpy.random.default_rng(seed)``
        only (same scene and seed: same counts)."""

    @abc.abstractmethod
    def truth(self, scene: "Scene") -> np.ndarray:
        """Points (P, 3) [m] on the hidden objects' surfaces VISIBLE from the scan (those that return
        light to at least one scan point; the cross-modality score measures to them) in the scan's
        wall coordinates (x along the wall, y up, z in front of it: the frame of :meth:`TransientVolume.grid` and of an
        :class:`~xnlos_core.nlos_volume.NLOSVolume`'s (x, y, z)); (0, 3) for a scene without objects."""

    def facing_params(self, scene: "Scene", target, exclude: str | None = None) -> tuple[dict, dict] | None:
        """Optional: this model's parameters with its scan patch placed where the relay wall sees a
        hidden ``target`` (3,) [m] (world x, y, z), and a JSON-able record of the placement; the
        record's ``grid_offset`` is None when no patch both is seen by the sensor and sees the target.
        None (the default): the model places no patch, and the study keeps its parameters."""
        return None


# The one list of kinds, in the order ``xnlos plugins`` lists them: the registry, the config's
# stage tables, the conformance kit and the tests all derive from it.
BASES: dict[str, type[Plugin]] = {base.kind: base for base in (
    ForwardModel, Backend, Detector, WallEstimator, Reconstructor, Tracker, SceneGenerator, NLOSSolver,
    TransientModel)}
KINDS: tuple[str, ...] = tuple(BASES)
STAGE_KINDS: tuple[str, ...] = tuple(kind for kind, base in BASES.items() if base.stage)
