"""A pipeline: frame source → detector → wall estimator → reconstructor (→ tracker), timed per stage.

The tracker follows the reconstructor's hidden points; without a reconstructor it follows the
line-of-sight detections (:func:`xnlos_core.los_points.detection_points`), e.g. road users in
one's own recording (``[backend] adc`` → ``[detector]`` → ``[tracker]``).

Every random draw derives from ``config.seed``: frame k is simulated with a generator seeded by
``SeedSequence(seed).spawn`` child k, so a frame does not depend on how many frames are run.
"""
from __future__ import annotations

import time
import warnings
from collections.abc import Collection, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import metrics
from .config import PipelineConfig
from .errors import ConfigError, InsufficientDataError, PipelineWarning
from .los_points import detection_points
from .frame_record import SCHEMA_VERSION, detections_record, hidden_record, wall_record
from .interfaces import FrameState
from .provenance import provenance
from .radar import RadarConfig, load_radar
from .registry import PluginManager, Registry, get_registry
from .scene import load_scene
from .core_share import adapt_torch_threads
from .threads import blas_limit
from .track_record import tracks_record
from .types import FRAME_IN_SCENE, MNLOS, Detections, Frame, HiddenPoints, Tracks, WallPosterior


@dataclass
class FrameResult:
    """Everything one frame produced, with per-stage wall time [s] and notes on skipped stages."""

    frame: Frame
    detections: Detections
    walls: list[WallPosterior]
    hidden: HiddenPoints
    tracks: Tracks | None = None
    timings: dict[str, float] = field(default_factory=dict)
    metrics: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def record(self) -> dict[str, Any]:
        """JSON-ready summary of this frame (one line of results.jsonl); NaN becomes None.

        With Doppler two keys are added, only then (records without it stay as they were):
        ``detection_doppler`` (per detection: range [m], azimuth [rad], label, radial velocity [m/s]
        and its variance [m²/s²]) and ``hidden_velocity`` (per hidden point, in the order of
        ``hidden_points``: velocity (2,) [m/s], velocity_cov (2, 2) [m²/s²] and source_index, the
        row of ``detection_doppler`` it was mirrored from). ``tracks`` gains the forecast and
        time-to-appearance fields when the tracker gives them (:mod:`xnlos_core.track_record`).

        Schema 2 adds ``schema_version``, ``detection_table`` (every detection: range,
        azimuth, label, class, confidence, range_std, azimuth_std, velocity/velocity_var with Doppler),
        each wall's param_names, params, extent and anchor, and ``hidden`` (mean, cov, source_index,
        wall_index, velocity/velocity_cov with Doppler): :mod:`xnlos_core.frame_record`. The keys of
        version 1 stay as they were, so old readers and resumed runs keep working. The whole line is
        described by :data:`xnlos_core.app.results_schema.RESULTS_SCHEMA`."""
        return _no_nan({**self._base_record(), **self._doppler_record()})

    def _doppler_record(self) -> dict[str, Any]:
        d, h, out = self.detections, self.hidden, {}
        if d.velocity is not None:
            out["detection_doppler"] = {"range": d.range.tolist(), "azimuth": d.azimuth.tolist(),
                                        "label": d.label.tolist(), "velocity": d.velocity.tolist(),
                                        "velocity_var": d.velocity_var.tolist()}
        if h.velocity is not None:
            out["hidden_velocity"] = {"velocity": h.velocity.tolist(), "velocity_cov": h.velocity_cov.tolist(),
                                      "source_index": h.source_index.tolist()}
        return out

    def _base_record(self) -> dict[str, Any]:
        d = self.detections
        return {
            "schema_version": SCHEMA_VERSION,
            "frame": self.frame.index,
            "timestamp": self.frame.timestamp,
            "detections": {"LOS": int((d.label == 0).sum()), "mNLOS": int((d.label == 1).sum()),
                           "unclassified": int((d.label == 2).sum())},
            "detection_table": detections_record(d),
            "walls": [wall_record(w) for w in self.walls],
            "hidden_points": self.hidden.mean.tolist(),
            "hidden": hidden_record(self.hidden),
            "n_gated": len(self.hidden.gated),
            "tracks": None if self.tracks is None else tracks_record(self.tracks),
            "metrics": self.metrics,
            "timings_s": self.timings,
            "notes": self.notes,
        }


def _no_nan(x):
    """NaN → None recursively (JSON has no NaN; ±inf stays, e.g. Chamfer with an empty side)."""
    if isinstance(x, float) and x != x:
        return None
    if isinstance(x, dict):
        return {k: _no_nan(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_no_nan(v) for v in x]
    return x


def timed_frames(frames: Iterable[Frame]) -> Iterator[tuple[Frame, float]]:
    """(frame, seconds the source took to deliver it) for each frame of ``frames``."""
    it = iter(frames)
    while True:
        t0 = time.perf_counter()
        try:
            frame = next(it)
        except StopIteration:
            return
        yield frame, time.perf_counter() - t0


class Pipeline:
    """Builds the configured plugins from a registry and runs frames through them."""

    def __init__(self, config: PipelineConfig, registry: Registry | None = None, source: str = "<config>"):
        self.config = config
        self.source = source
        if registry is None:
            p = config.plugins
            if p.autoload and p.allow is None and not p.load:
                registry = get_registry()
            else:
                mgr = PluginManager(autoload=p.autoload, allow=p.allow)
                mgr.load_named(p.load, source)  # installed entry points only; never a module a config names
                registry = mgr.registry
        self.registry = registry
        self.radar = load_radar(config.radar, source, config.base_dir)
        self.stages = {}
        for kind, stage in config.stages().items():
            self.stages[kind] = registry.create(kind, stage.name, stage.params, source=source,
                                               base_dir=config.base_dir)
            try:  # bounds that depend on the map size: checked here, so `check` refuses what `run` would
                self.stages[kind].check_radar(self.radar)
            except ConfigError as exc:
                raise ConfigError(f"{source}: [{kind}] {stage.name}: {exc}") from None
        self._warm = False  # detector and wall estimator warmed up (warm_up)
        self.scene = None
        if "forward_model" in self.stages:
            self.scene = load_scene(config.scene, source, config.base_dir, registry=registry)
        self.validate()

    def validate(self) -> None:
        """The checks a run would fail on, without running (called on construction, so ``xnlos check``
        and ``xnlos run`` refuse the same configs): the radar's measured coupling matrix is read
        and checked, the forward model checks the scene (:meth:`ForwardModel.check`)."""
        from xnlos_core.signal.antenna import coupling_matrix

        if self.radar.coupling_file is not None:
            coupling_matrix(self.radar)
        if self.scene is not None:
            self.stages["forward_model"].check(self.scene, self.radar)
        self.warn_unreachable()

    def check_inputs(self) -> dict[str, str]:
        """Read and check the files a run reads before its first frame, without running: every
        stage's learned state (:meth:`state_sha256`, as a run's provenance does: a learned detector's
        checkpoint is loaded with ``torch.load(weights_only=True)`` and its hashes checked) and the
        backend's source (:meth:`xnlos_core.interfaces.Backend.check_source`: a recording's file is
        opened and its shape checked). ``xnlos check`` calls it, so that it refuses a missing or
        damaged checkpoint or recording as ``xnlos run`` would. Returns the state hashes."""
        state = self.state_sha256()
        if "backend" in self.stages:
            self.stages["backend"].check_source()
        self.model_mismatches()
        return state

    @property
    def frame_radar(self) -> RadarConfig | None:
        """The radar of the maps the detector will see: the pipeline's with a forward model or a live
        sensor; a source's own (:meth:`xnlos_core.interfaces.Backend.source_radar`: a recording's
        description, a dataset's manifest); None when the source has its own radar but cannot tell it
        before the first frame (a learned detector then compares each frame's radar as it comes)."""
        backend = self.stages.get("backend")
        if backend is None:
            return self.radar
        radar = backend.source_radar()
        if radar is None and not backend.own_radar:
            return self.radar
        return radar

    def model_mismatches(self) -> dict[str, list[str]]:
        """kind → the differences between a learned stage's training radar and :attr:`frame_radar` that
        it accepts (:meth:`xnlos_core.interfaces.Detector.check_model`, which raises ConfigError on those
        it refuses); only stages with any. ``check_inputs``, :meth:`warm_up` and :meth:`provenance`
        call it, so ``xnlos check`` refuses what a run would before its first frame."""
        radar = self.frame_radar
        found = self.stages["detector"].check_model(radar) if radar is not None else []
        return {"detector": list(found)} if found else {}

    def warn_unreachable(self) -> None:
        """:class:`PipelineWarning` when the configured stages can never deliver what they are there
        for: a detector that cannot classify (``Detector.classifies`` False: every detection
        UNCLASSIFIED) gives a wall estimator no LOS and a reconstructor no mNLOS detection, so the
        run never reconstructs anything. A warning, not an error: such a pipeline still scores its
        detections class-agnostically (``dense.all``), which is what a CFAR ablation compares; a
        pipeline meant to detect only leaves [wall_estimator] and [reconstructor] out."""
        det = self.stages["detector"]
        behind = [k for k in ("wall_estimator", "reconstructor") if k in self.stages]
        if behind and not getattr(det, "classifies", True):
            warnings.warn(
                f"{self.source}: [detector] {self.config.detector.name!r} cannot classify (every detection is "
                f"UNCLASSIFIED), so [{'] and ['.join(behind)}] never get LOS / mNLOS input: this pipeline can never "
                "reconstruct a hidden object. Use a classifying detector (e.g. nlos_cfar) or, to detect only, "
                "remove [wall_estimator] and [reconstructor].", PipelineWarning, stacklevel=2)

    def plugin_info(self) -> dict[str, dict]:
        """kind → {name, provider, params} for provenance."""
        out = {}
        for kind, stage in self.config.stages().items():
            comp = self.registry.get(kind, stage.name)
            out[kind] = {"name": stage.name, "provider": comp.provider,
                         "params": self.stages[kind].get_params()}
        return out

    def state_sha256(self) -> dict[str, str]:
        """kind → hash of the learned state of each stage that reads one from a file
        (:meth:`xnlos_core.interfaces.Plugin.state_sha256`)."""
        out = {}
        for kind, stage in self.stages.items():
            digest = stage.state_sha256()
            if digest is not None:
                out[kind] = digest
        return out

    def provenance(self) -> dict:
        """The run's record (:func:`xnlos_core.provenance.provenance`); refuses (ConfigError) a learned
        detector trained on another radar unless its settings accept it (:meth:`model_mismatches`), and
        then records what differs (``accepted_mismatch``)."""
        return provenance(self.config, self.plugin_info(), self.state_sha256(), self.model_mismatches())

    def frames(self, start: int = 0, skip: Collection[int] = ()) -> Iterator[Frame]:
        """Frames ``start`` … ``run.frames``−1 from the forward model or the backend, leaving out
        those whose index is in ``skip`` (simulated frames are then not even drawn: frame k's
        generator is child k of the seed, so any subset is the same frames as a full run)."""
        n = self.config.run.frames
        skip = frozenset(skip)
        if "forward_model" in self.stages:
            fm = self.stages["forward_model"]
            seeds = np.random.SeedSequence(self.config.seed).spawn(n)
            for k in range(start, n):
                if k in skip:
                    continue
                t = k * self.config.run.frame_interval
                with blas_limit(self.config.run.blas_threads):
                    frame = fm.simulate(self.scene, self.radar, np.random.default_rng(seeds[k]), timestamp=t, index=k)
                yield frame
        else:
            backend = self.stages["backend"]
            backend.open(self.radar)
            try:
                for k, frame in enumerate(backend.frames(n)):
                    if k >= start and frame.index not in skip:
                        yield frame
            finally:
                backend.close()

    def warm_up(self) -> int:
        """Prepare the stages before the first frame: the detector
        (:meth:`xnlos_core.interfaces.Detector.warm_up`: a learned detector loads its network and runs
        it once on an empty map of the radar's grid) and the wall estimator
        (:meth:`xnlos_core.interfaces.WallEstimator.warm_up`: casadi problems built per size), so that
        no frame's timings include model loading, compilation or problem building. Once per pipeline
        (later calls do nothing); :meth:`run` and :meth:`process` call it. Returns the warm-up passes
        and problems built (0 when already warm)."""
        if self._warm:
            return 0
        with blas_limit(self.config.run.blas_threads):
            self.model_mismatches()
            radar = self.frame_radar
            n = self.stages["detector"].warm_up(self.radar if radar is None else radar)
            if self.stages.get("wall_estimator") is not None:
                n += self.stages["wall_estimator"].warm_up()
        self._warm = True
        return n

    def process(self, frame: Frame) -> FrameResult:
        """Run detection, wall estimation, reconstruction and tracking on one frame (and score it),
        with BLAS limited to ``run.blas_threads`` threads meanwhile (:mod:`xnlos_core.threads`) and torch's
        threads kept to the cores other processes leave free (``run.share_cores``, :mod:`xnlos_core.core_share`).
        The first call warms the detector up first (:meth:`warm_up`, outside the stage timings).

        A frame that starts a sequence (``frame.meta["frame_in_scene"] == 0``, as a sequence dataset's
        frames carry: its timestamps start again at 0) resets the stages first (:meth:`reset`): no
        track or wall history carries over from the sequence before, and a run over a dataset of
        several sequences tracks each on its own."""
        self.warm_up()
        if frame.meta.get(FRAME_IN_SCENE) == 0:
            self.reset()
        adapt_torch_threads(self.config.run.share_cores)
        with blas_limit(self.config.run.blas_threads):
            return self._process(frame)

    def _process(self, frame: Frame) -> FrameResult:
        timings: dict[str, float] = {}
        notes: list[str] = []

        def timed(name, fn, *args):
            t0 = time.perf_counter()
            try:
                return fn(*args)
            finally:
                timings[name] = timings.get(name, 0.0) + time.perf_counter() - t0

        det = timed("detector", self.stages["detector"].detect, frame)
        walls: list[WallPosterior] = []
        if "wall_estimator" in self.stages:  # absent: a detection-only pipeline
            try:
                walls = timed("wall_estimator", self.stages["wall_estimator"].estimate, det)
            except InsufficientDataError as exc:
                notes.append(f"wall_estimator: {exc}")
        hidden = HiddenPoints.empty()
        n_mnlos = int((det.label == MNLOS).sum())
        if "reconstructor" not in self.stages:
            pass
        elif walls and n_mnlos:
            hidden = timed("reconstructor", self.stages["reconstructor"].reconstruct, det, walls)
            if len(hidden.gated):
                notes.append(f"reconstructor: {len(hidden.gated)} of {n_mnlos} mNLOS detections gated as ghosts (their "
                             "mirror image lies where the relay wall cannot show it); not reported as hidden")
            missing = n_mnlos - len(np.unique(hidden.source_index)) - len(np.unique(hidden.gated))
            if missing:
                notes.append(f"reconstructor: {missing} of {n_mnlos} mNLOS detections matched no wall; not reconstructed")
        elif n_mnlos:
            notes.append(f"reconstructor: {n_mnlos} mNLOS detections but no wall estimate; nothing reconstructed")
        tracks = None
        if "tracker" in self.stages:
            # without a reconstructor the tracker follows what the radar sees directly: the
            # line-of-sight detections as points (xnlos_core.los_points)
            points = hidden if "reconstructor" in self.stages else detection_points(det)
            tracks = timed("tracker", self.stages["tracker"].update, points, frame.timestamp)
        res = FrameResult(frame, det, walls, hidden, tracks, timings, notes=notes)
        if frame.ground_truth is not None:
            res.metrics = self.score(res)
        return res

    def score(self, res: FrameResult) -> dict[str, Any]:
        """Metrics of one frame against its ground truth (module :mod:`xnlos_core.metrics`).

        ``dense``: detections (F1/CD against what the radar can resolve). With a reconstructor:
        ``reconstruction`` (LOS + hidden points, scene F1/CD, and ``object_error_m`` [m] per object
        against its full illuminated surface: the one object-error figure a run reports) and
        ``hidden`` (hidden points alone; F1/precision/recall/CD are None, not the vacuous 1 of
        0/0, when there was nothing to reconstruct and nothing was). ``mirror_paths``: object
        name → number of its points with an open mirror path (mNLOS ground truth); 0 means the
        object is not observable through a relay wall in this frame. ``los_points``: object name →
        number of its points the radar sees directly (LOS ground truth), only when the ground truth
        records their owners (``GroundTruth.los_object``; not for frames read from a dataset): an
        object with LOS points and no mirror path is in plain view, not hidden.
        """
        gt, det, hidden = res.frame.ground_truth, res.detections, res.hidden
        r = self.config.run.match_radius
        resolved = metrics.thin_to_resolution(gt, res.frame.ra_map.radar)
        out: dict[str, Any] = {"dense": metrics.dense_metrics(det, resolved, r)}
        if "reconstructor" in self.stages:
            recon = metrics.scene_metrics(det, hidden, resolved, r)
            recon["object_error_m"] = metrics.reconstruction_metrics(hidden, gt, r)["object_error_m"]
            alone = metrics.reconstruction_metrics(hidden, resolved, r)
            del alone["object_error_m"]  # against thinned truth: a second, different figure
            if not len(resolved.hidden_points) and not len(hidden):
                alone.update(precision=None, recall=None, f1=None, cd=None)
            out.update(reconstruction=recon, hidden=alone)
        out["mirror_paths"] = {name: int(np.sum(gt.mnlos_object == k)) for k, name in enumerate(gt.object_names)}
        if gt.los_object is not None:
            out["los_points"] = {name: int(np.sum(gt.los_object == k)) for k, name in enumerate(gt.object_names)}
        return out

    def stateful(self) -> dict[str, Any]:
        """kind → stage for the stages whose output depends on earlier frames
        (:attr:`xnlos_core.interfaces.FrameState.carries_state`): the tracker, and a wall estimator
        that pools earlier frames' LOS detections. Empty: every frame stands alone."""
        return {kind: stage for kind, stage in self.stages.items()
                if isinstance(stage, FrameState) and stage.carries_state}

    def reset(self) -> None:
        """Forget what earlier frames left in every stage (the tracks, a wall estimator's history):
        the start of a run or of a sequence."""
        for stage in self.stages.values():
            if isinstance(stage, FrameState):
                stage.reset()

    def run(self, start: int = 0, skip: Collection[int] = (), restored: bool = False) -> Iterator[FrameResult]:
        """Yield results of frames ``start`` … in order, except those whose index is in ``skip``
        (the frames a resumed run already holds); the source's time is stage 'source'.

        A tracker (and a wall estimator with a history) carries state from frame to frame
        (:meth:`stateful`), so with one configured every frame from 0 is replayed through all stages
        and only the wanted ones are yielded: a resumed or gap-filled frame gets the walls and tracks
        an uninterrupted run would have given it. ``restored``: those stages already hold their state
        after the frames in ``skip`` (loaded from a checkpoint, :mod:`xnlos_core.checkpoint`; the
        caller guarantees ``skip`` is every frame before the
        first wanted one): it is not reset and nothing is replayed. With a simulated source and every
        frame ``start`` … ``run.frames`` − 1 in ``skip`` nothing runs at all (a finished run).
        """
        skip = frozenset(skip)
        if "forward_model" in self.stages and skip.issuperset(range(start, self.config.run.frames)):
            return
        self.warm_up()  # before the first frame is drawn: not in the source's or the detector's time
        replay = bool(self.stateful()) and not restored
        if replay:
            self.reset()
        frames = self.frames(0) if replay else self.frames(start, skip)
        for frame, src in timed_frames(frames):
            res = self.process(frame)
            res.timings = {"source": src, **res.timings}
            if not replay or (frame.index >= start and frame.index not in skip):
                yield res
