"""The plugin kinds. A plugin is a class with a pydantic ``Params`` model; ``__init__`` only
stores the validated parameters (scikit-learn style) and the stage method does the work.

Six kinds are pipeline stages; the seventh, ``scene_generator``, draws the random scenes a
dataset is rendered from (a dataset config names them in ``families``). Any registered plugin of
a kind can replace any other of that kind by a one-line config change, and a config can name
nothing else: no module, no function.
"""
from __future__ import annotations

import abc
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict

from .radar import RadarConfig
from .types import Detections, Frame, HiddenPoints, Tracks, WallPosterior

if TYPE_CHECKING:
    from .scene import Scene

KINDS = ("forward_model", "backend", "detector", "wall_estimator", "reconstructor", "tracker", "scene_generator")


class NoParams(BaseModel):
    """Parameter model of a plugin without parameters (unknown keys are rejected)."""

    model_config = ConfigDict(extra="forbid")


class Plugin:
    """Common base: stores a validated ``Params`` instance as ``self.params``."""

    Params: ClassVar[type[BaseModel]] = NoParams

    def __init__(self, params: BaseModel | dict[str, Any] | None = None):
        if params is None:
            params = self.Params()
        elif isinstance(params, dict):
            from .config import validate_model

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


class Backend(Plugin, abc.ABC):
    """A source of measured frames (hardware, a recording). Used as a context manager."""

    kind: ClassVar[str] = "backend"

    def open(self, radar: RadarConfig) -> None:
        """Connect and configure the sensor; the default does nothing."""

    def close(self) -> None:
        """Release the sensor; must be safe to call twice."""

    @abc.abstractmethod
    def frames(self, max_frames: int | None = None) -> Iterator[Frame]:
        """Yield complete frames in order; never yields a partial or corrupted frame."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class Detector(Plugin, abc.ABC):
    """Frame → Detections (range, azimuth, LOS/mNLOS class, confidence)."""

    kind: ClassVar[str] = "detector"

    @abc.abstractmethod
    def detect(self, frame: Frame) -> Detections:
        """Find peaks in ``frame.ra_map``; an empty map region gives empty Detections, not an error."""


class WallEstimator(Plugin, abc.ABC):
    """LOS detections → relay walls with uncertainty."""

    kind: ClassVar[str] = "wall_estimator"

    @abc.abstractmethod
    def estimate(self, detections: Detections) -> list[WallPosterior]:
        """Fit walls to the LOS detections. Raises InsufficientDataError with < 2 LOS points."""


class Reconstructor(Plugin, abc.ABC):
    """mNLOS detections + walls → hidden points (Eq. 7)."""

    kind: ClassVar[str] = "reconstructor"

    @abc.abstractmethod
    def reconstruct(self, detections: Detections, walls: list[WallPosterior]) -> HiddenPoints:
        """Mirror each mNLOS detection across its wall; rows reference ``detections`` by index."""


class Tracker(Plugin, abc.ABC):
    """Hidden points over frames → tracks with predictions."""

    kind: ClassVar[str] = "tracker"

    @abc.abstractmethod
    def update(self, points: HiddenPoints, timestamp: float) -> Tracks:
        """Ingest one frame's hidden points at ``timestamp`` [s]; return the current tracks."""

    def reset(self) -> None:
        """Forget all tracks (called at the start of a run)."""


class SceneGenerator(Plugin, abc.ABC):
    """seed → Scene: one scene family (Sec. 5.1), its ``Params`` the family's parameters.

    A dataset config lists registered scene generators by name in ``families``; its
    ``generator_params`` and ``family_overrides.<name>`` tables are validated by ``Params``.
    """

    kind: ClassVar[str] = "scene_generator"

    @abc.abstractmethod
    def generate(self, seed: int) -> "Scene":
        """A random :class:`xnlos_core.scene.Scene` drawn from ``numpy.random.default_rng(seed)``
        only (``seed`` an integer ≥ 0): the same parameters and seed give the same scene, in any
        process. Raises :class:`xnlos_core.errors.InputError` when no valid scene can be drawn."""


BASES: dict[str, type[Plugin]] = {
    "forward_model": ForwardModel,
    "backend": Backend,
    "detector": Detector,
    "wall_estimator": WallEstimator,
    "reconstructor": Reconstructor,
    "tracker": Tracker,
    "scene_generator": SceneGenerator,
}
