"""The conformance checks, one per kind (``check_<kind>``, :data:`CHECKS`), and :func:`check_params`.

Each takes a component instance and raises AssertionError naming the broken contract; each part of a
check that held is recorded with :func:`passed`, so that :func:`~xnlos_core.testing.check_component`
can say what was checked.
"""
from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any

import numpy as np

from ..errors import ConfigError, InputError, InsufficientDataError
from ..frame_record import wall_record
from ..geometry import line_from_points, mirror_reflect
from ..interfaces import (BASES, Backend, Detector, ForwardModel, NLOSSolver, Reconstructor, SceneGenerator,
                          Tracker, WallEstimator)
from ..radar import RadarConfig
from ..types import LOS, MNLOS, Detections, Frame, HiddenPoints, RAMap, Tracks, WallPosterior
from .frames import KIT_WALL, kit_transient, small_radar, synthetic_frame

_STEPS: ContextVar[list[str] | None] = ContextVar("xnlos_check_steps", default=None)


def passed(step: str) -> None:
    """Record that one part of a check held (listed in :func:`~xnlos_core.testing.check_component`'s
    report); outside :func:`record_steps` nothing is recorded."""
    steps = _STEPS.get()
    if steps is not None:
        steps.append(step)


@contextmanager
def record_steps() -> Iterator[list[str]]:
    """Collect the parts that :func:`passed` records inside the block, in order, into the list it yields."""
    steps: list[str] = []
    token = _STEPS.set(steps)
    try:
        yield steps
    finally:
        _STEPS.reset(token)


def _assert(cond: bool, who: Any, msg: str) -> None:
    if not cond:
        raise AssertionError(f"{type(who).__name__}: {msg}")


def check_params(plugin) -> None:
    """Params is a strict pydantic model and get_params() round-trips into an equal clone."""
    cls = type(plugin)
    _assert(hasattr(cls, "Params"), plugin, "has no Params model")
    _assert(cls.Params.model_config.get("extra") == "forbid", plugin,
            "Params must set model_config = ConfigDict(extra='forbid') so misspelt keys fail")
    passed("a strict Params model (extra='forbid')")
    clone = cls(cls.Params(**plugin.get_params()))
    _assert(clone.get_params() == plugin.get_params(), plugin, "get_params() does not round-trip")
    passed("get_params() round-trips into an equal clone")
    try:
        cls({**plugin.get_params(), "__no_such_key__": 1})
    except ConfigError:
        pass
    else:
        raise AssertionError(f"{cls.__name__}: an unknown parameter key was accepted")
    passed("an unknown key is a ConfigError")


def _same(a: Detections, b: Detections) -> bool:
    return len(a) == len(b) and all(np.array_equal(getattr(a, f), getattr(b, f))
                                    for f in ("range", "azimuth", "label", "confidence"))


def check_detector(detector: Detector, radar: RadarConfig | None = None) -> None:
    """Returns valid Detections inside the map, deterministically, without mutating the frame;
    finds a 35 dB point target; copes with a non-square map and an all-zero map."""
    _assert(isinstance(detector, Detector), detector, "is not a xnlos_core.Detector")
    frame = synthetic_frame(radar)
    before = frame.ra_map.data.copy()
    det = detector.detect(frame)
    _assert(isinstance(det, Detections), detector, f"detect() returned {type(det).__name__}, not Detections")
    _assert(np.array_equal(before, frame.ra_map.data), detector, "detect() modified the RA map in place")
    passed("returns Detections, the RA map untouched")
    ra = frame.ra_map
    if len(det):
        _assert(det.range.min() >= ra.range_axis[0] - 1e-9 and det.range.max() <= ra.range_axis[-1] + 1e-9,
                detector, "detections outside the map's range axis")
        _assert(np.abs(det.azimuth).max() <= np.abs(ra.azimuth_axis).max() + 1e-9, detector,
                "detections outside the map's azimuth axis")
    passed("detections inside the map's axes")
    _assert(_same(det, detector.detect(frame)), detector, "two calls on the same frame differ")
    passed("the same detections twice")
    gt = frame.ground_truth
    truth = np.concatenate([gt.los_points, gt.mnlos_points])
    if len(det):
        d = np.min(np.linalg.norm(det.position[:, None] - truth[None], axis=-1), axis=1)
        hit = (d < 2.0).sum()
    else:
        hit = 0
    _assert(hit > 0, detector, "no detection within 2 m of any 35 dB synthetic target")
    passed("finds a 35 dB target within 2 m")
    odd = small_radar(n_samples=128, max_range=30.0, n_azimuth_bins=33)
    det2 = detector.detect(synthetic_frame(odd, seed=1))
    _assert(isinstance(det2, Detections), detector, "failed on a 121×33 map")
    zero = Frame(RAMap.from_radar(np.zeros((odd.n_range_bins, odd.n_azimuth_bins), np.complex64), odd))
    det3 = detector.detect(zero)
    _assert(isinstance(det3, Detections), detector, "failed on an all-zero map")
    passed("copes with a 121×33 map and an all-zero map")


def _line_detections(points: np.ndarray, label: int) -> Detections:
    return Detections.from_points(points, label, confidence=0.9, range_std=0.05, azimuth_std=0.005)


def check_wall_estimator(estimator: WallEstimator) -> None:
    """Recovers a wall from noisy LOS points (2°, 0.3 m), ignores mNLOS points, and raises
    InsufficientDataError for fewer than two LOS points (after :meth:`~WallEstimator.reset`). One that
    pools earlier frames (:attr:`~xnlos_core.interfaces.FrameState.carries_state`) forgets them on reset
    and, with a checkpoint, resumes from ``load_state(state())`` with the uninterrupted walls
    (:func:`check_frame_state`)."""
    _assert(isinstance(estimator, WallEstimator), estimator, "is not a xnlos_core.WallEstimator")
    estimator.reset()
    rng = np.random.default_rng(0)
    t = np.linspace(0.1, 0.8, 25)[:, None]
    pts = KIT_WALL.start + t * (KIT_WALL.end - KIT_WALL.start) + rng.normal(0, 0.05, (25, 2))
    far = np.array([[39.0, 3.0], [41.0, 5.0]])
    det = _line_detections(pts, LOS)
    mn = _line_detections(far, MNLOS)
    walls = estimator.estimate(Detections.concat(det, mn))
    _assert(isinstance(walls, list) and walls and all(isinstance(w, WallPosterior) for w in walls), estimator,
            "estimate() must return a non-empty list of WallPosterior")
    passed("returns a list of WallPosterior")
    w = walls[0]
    n_true, b_true = KIT_WALL.normal, KIT_WALL.offset
    if w.model == "line":
        ang = math.degrees(math.acos(min(1.0, abs(float(w.normal @ n_true)))))
        _assert(ang < 2.0 and abs(w.offset - b_true) < 0.3, estimator,
                f"wall off by {ang:.2f}° / {abs(w.offset - b_true):.2f} m (allowed 2°, 0.3 m)")
        passed(f"the wall within 2° and 0.3 m ({ang:.2f}°, {abs(w.offset - b_true):.2f} m), mNLOS rows ignored")
    for few in (Detections.empty(), _line_detections(pts[:1], LOS), mn):
        estimator.reset()
        try:
            estimator.estimate(few)
        except InsufficientDataError:
            continue
        raise AssertionError(f"{type(estimator).__name__}: {len(few)} detections with < 2 LOS did not raise "
                             "InsufficientDataError")
    passed("InsufficientDataError below 2 LOS points")
    estimator.reset()
    if estimator.carries_state:
        frames = [Detections.concat(_line_detections(pts[k::3] + rng.normal(0, 0.05, pts[k::3].shape), LOS), mn)
                  for k in (0, 1, 2, 0, 1, 2)]
        check_frame_state(estimator, lambda k: [wall_record(w) for w in estimator.estimate(frames[k])], len(frames))


def check_frame_state(stage, step, n: int = 6) -> list:
    """A stage that carries state from frame to frame (:class:`xnlos_core.interfaces.FrameState`):
    ``step(k)`` feeds it frame k and returns a JSON-able output. After :meth:`reset` frame 0 gives
    the same output again; with a checkpoint (:attr:`supports_state`), the state after frame 2
    survives ``json`` and, loaded after a reset, gives the uninterrupted outputs of frames 3 … n − 1.
    Returns the uninterrupted outputs (through ``json``)."""
    import json

    stage.reset()
    outs, state = [], None
    for k in range(n):
        outs.append(json.dumps(step(k)))
        if k == 2 and stage.supports_state:
            state = json.dumps(stage.state())
    stage.reset()
    _assert(json.dumps(step(0)) == outs[0], stage, "after reset() frame 0 gave another output than at first")
    passed("reset() forgets earlier frames")
    stage.reset()
    if state is not None:
        stage.load_state(json.loads(state))
        for k in range(3, n):
            _assert(json.dumps(step(k)) == outs[k], stage,
                    f"after load_state(state()) frame {k} gave another output than the uninterrupted run")
        passed("load_state(state()) resumes the uninterrupted outputs")
        stage.reset()
    return [json.loads(o) for o in outs]


def check_reconstructor(reconstructor: Reconstructor, atol: float = 0.5) -> None:
    """Mirrors mNLOS detections across a known wall to within ``atol`` m, indexes its sources,
    returns PSD covariances, ignores LOS rows and returns empty output for no mNLOS."""
    _assert(isinstance(reconstructor, Reconstructor), reconstructor, "is not a xnlos_core.Reconstructor")
    hidden = np.array([[22.0, -14.0], [24.0, -12.0], [20.0, -16.0]])
    virt = mirror_reflect(hidden, KIT_WALL.normal, KIT_WALL.offset)
    los = KIT_WALL.start + np.linspace(0.2, 0.7, 4)[:, None] * (KIT_WALL.end - KIT_WALL.start)
    a, b = _line_detections(los, LOS), _line_detections(virt, MNLOS)
    det = Detections.concat(a, b)
    n, off = line_from_points(KIT_WALL.start, KIT_WALL.end)
    wall = WallPosterior.line(n, off, np.diag([1e-4, 1e-2]), n_points=4, extent=np.stack([KIT_WALL.start, KIT_WALL.end]))
    out = reconstructor.reconstruct(det, [wall])
    _assert(isinstance(out, HiddenPoints), reconstructor, "reconstruct() must return HiddenPoints")
    _assert(len(out) == 3 and set(out.source_index.tolist()) == {4, 5, 6}, reconstructor,
            f"expected 3 points from detections 4, 5, 6; got sources {out.source_index.tolist()}")
    passed("one hidden point per mNLOS detection, indexed by it")
    err = np.linalg.norm(out.mean - hidden[out.source_index - 4], axis=1).max()
    _assert(err < atol, reconstructor, f"hidden points off by up to {err:.3f} m (allowed {atol})")
    passed(f"mirrored across the wall within {atol} m (off by {err:.3f} m)")
    _assert(np.all(np.linalg.eigvalsh(out.cov) > -1e-9), reconstructor, "covariances are not PSD")
    passed("PSD covariances")
    none = reconstructor.reconstruct(a, [wall])
    _assert(len(none) == 0, reconstructor, "LOS-only detections must give no hidden points")
    passed("no hidden points from LOS rows")


def check_forward_model(model: ForwardModel, scene=None, radar: RadarConfig | None = None) -> None:
    """Returns a Frame of the radar's shape with ground truth; same seed → same map."""
    from ..scene import load_scene

    _assert(isinstance(model, ForwardModel), model, "is not a xnlos_core.ForwardModel")
    scene = scene or load_scene({"builtin": "corner"}, "conformance")
    radar = radar or small_radar()
    f1 = model.simulate(scene, radar, np.random.default_rng(3), timestamp=0.5, index=2)
    _assert(isinstance(f1, Frame), model, "simulate() must return a Frame")
    _assert(f1.ra_map.shape == (radar.n_range_bins, radar.n_azimuth_bins), model,
            f"RA map shape {f1.ra_map.shape} ≠ radar grid {(radar.n_range_bins, radar.n_azimuth_bins)}")
    _assert(f1.ground_truth is not None, model, "simulated frames must carry ground truth")
    _assert(f1.timestamp == 0.5 and f1.index == 2, model, "timestamp/index not passed through")
    passed("a Frame on the radar's grid with ground truth, timestamp and index")
    f2 = model.simulate(scene, radar, np.random.default_rng(3), timestamp=0.5, index=2)
    _assert(np.array_equal(f1.ra_map.data, f2.ra_map.data), model, "same seed gave different RA maps")
    passed("the same seed gives the same RA map")


def check_backend(backend: Backend, radar: RadarConfig | None = None) -> None:
    """Yields at least one and at most max_frames Frames in time order, each RA map on the grid
    of the radar it carries (n_range_bins × n_azimuth_bins; complex64, as RAMap guarantees): a live
    backend's is ``radar``, a recording's the one it was made with. Refuses a negative max_frames
    with InputError; close() is idempotent."""
    _assert(isinstance(backend, Backend), backend, "is not a xnlos_core.Backend")
    with backend:
        backend.open(radar or RadarConfig())
        frames = list(backend.frames(2))
    backend.close()
    _assert(len(frames) >= 1, backend, "frames(2) yielded no frame")
    _assert(len(frames) <= 2 and all(isinstance(f, Frame) for f in frames), backend,
            "frames(2) must yield at most 2 Frame objects")
    for f in frames:
        grid = (f.ra_map.radar.n_range_bins, f.ra_map.radar.n_azimuth_bins)
        _assert(f.ra_map.shape == grid, backend, f"frame {f.index}: RA map shape {f.ra_map.shape} ≠ its radar's "
                f"grid {grid} (n_range_bins × n_azimuth_bins)")
    ts = [f.timestamp for f in frames]
    _assert(ts == sorted(ts), backend, "frames out of time order")
    passed("frames(2) yields 1–2 Frames on their radar's grid, in time order")
    try:
        list(backend.frames(-1))
    except InputError:
        pass
    else:
        raise AssertionError(f"{type(backend).__name__}: frames(-1) did not raise InputError")
    passed("frames(-1) is an InputError")


def check_tracker(tracker: Tracker) -> None:
    """Keeps one track id for one point moving at constant velocity; forgets it on reset and, with a
    checkpoint (:attr:`Tracker.supports_state`), resumes from ``load_state(state())`` with the
    uninterrupted tracks (:func:`check_frame_state`)."""
    _assert(isinstance(tracker, Tracker), tracker, "is not a xnlos_core.Tracker")

    def step(k: int) -> dict:
        p = np.array([[20.0, -10.0 + 1.0 * k]])
        out = tracker.update(HiddenPoints(p, np.tile(np.eye(2) * 0.01, (1, 1, 1)), [0], [0]), 0.5 * k)
        _assert(isinstance(out, Tracks), tracker, "update() must return Tracks")
        return {f: getattr(out, f).tolist() for f in ("track_id", "position", "velocity")}

    outs = check_frame_state(tracker, step, 6)
    ids = {i for out in outs for i in out["track_id"]}
    _assert(len(ids) == 1, tracker, f"one moving point produced track ids {sorted(ids)}")
    passed("one track id for one point moving at constant velocity")


def check_scene_generator(generator: SceneGenerator, seed: int = 3) -> None:
    """Returns a Scene drawn from the seed alone: the same seed gives the same scene, and the global
    RNGs (numpy's and ``random``'s) are neither drawn from nor changed (so nothing else can feed it)."""
    import random

    from ..scene import Scene

    _assert(isinstance(generator, SceneGenerator), generator, "is not a xnlos_core.SceneGenerator")
    np_state, py_state = np.random.get_state(), random.getstate()
    first = generator.generate(seed)
    _assert(isinstance(first, Scene), generator, f"generate() must return a Scene, got {type(first).__name__}")
    _assert(_same_state(np_state, np.random.get_state()) and py_state == random.getstate(), generator,
            "generate() drew from a global RNG; draw from numpy.random.default_rng(seed) only")
    passed("a Scene, no global RNG touched")
    again = generator.generate(seed)
    _assert(again.model_dump(mode="json") == first.model_dump(mode="json"), generator,
            f"seed {seed} gave two different scenes")
    passed("the same seed gives the same scene")


def check_nlos_solver(solver: NLOSSolver) -> None:
    """Reconstructs a hidden point within one depth bin and one scan cell of where it is, returns an
    NLOSVolume on the input's grid (depth z_k = c·t_k/2), the same twice, and refuses a volume without
    counts with InputError."""
    from ..nlos_volume import NLOSVolume
    from ..transient import TransientVolume

    _assert(isinstance(solver, NLOSSolver), solver, "is not a xnlos_core.interfaces.NLOSSolver")
    vol = kit_transient([(0.125, -0.0625, 0.5)])
    out = solver.reconstruct(vol)
    _assert(isinstance(out, NLOSVolume), solver, f"reconstruct() must return an NLOSVolume, got {type(out).__name__}")
    _assert(out.shape[1:] == vol.shape[1:], solver, f"albedo grid {out.shape[1:]} differs from the wall grid {vol.shape[1:]}")
    dz, cell = vol.bin_length / 2, vol.wall_width / vol.shape[2]
    z, y, x = out.peak()
    _assert(abs(z - 0.5) <= dz + 1e-9 and abs(y + 0.0625) <= cell + 1e-9 and abs(x - 0.125) <= cell + 1e-9, solver,
            f"a point at (z, y, x) = (0.5, -0.0625, 0.125) m came back at ({z:.4f}, {y:.4f}, {x:.4f}) m "
            f"(tolerance one bin {dz:.4f} m, one cell {cell:.4f} m)")
    passed("a hidden point within one depth bin and one scan cell")
    _assert(np.array_equal(solver.reconstruct(vol).albedo, out.albedo), solver, "two runs on one volume differ")
    try:
        solver.reconstruct(TransientVolume(np.zeros(vol.shape), vol.bin_width, 1.0, 1.0))
    except InputError:
        pass
    else:
        _assert(False, solver, "an all-zero volume must raise InputError")
    passed("the same volume twice; an all-zero volume is an InputError")


def check_transient_model(model) -> None:
    """Scans a scene with one box in front of its relay wall: a TransientVolume with counts, the same
    for one seed, hidden-surface truth points (P, 3) with z > 0 (in front of the wall)."""
    from ..interfaces import TransientModel
    from ..scene import ObjectSpec, Scene, WallSpec
    from ..transient import TransientVolume

    _assert(isinstance(model, TransientModel), model, "is not a xnlos_core.interfaces.TransientModel")
    scene = Scene(name="kit", walls=[WallSpec(name="relay", start=(5.0, 5.0), end=(5.0, -5.0))],
                  objects=[ObjectSpec(name="box", shape="box", center=(4.0, 0.0), size=(0.5, 0.5))])
    vol = model.simulate(scene, 3)
    _assert(isinstance(vol, TransientVolume), model, f"simulate() must return a TransientVolume, got {type(vol).__name__}")
    _assert(np.array_equal(model.simulate(scene, 3).data, vol.data), model, "two scans with one seed differ")
    passed("a TransientVolume, the same for one seed")
    pts = np.asarray(model.truth(scene))
    _assert(pts.ndim == 2 and pts.shape[1] == 3 and len(pts) > 0, model, f"truth() must be (P, 3), got {pts.shape}")
    _assert(bool(np.all(pts[:, 2] > 0)), model, "truth points of an object in front of the wall must have z > 0")
    passed("truth points (P, 3) in front of the wall")


def _same_state(a, b) -> bool:
    return a[0] == b[0] and np.array_equal(a[1], b[1]) and tuple(a[2:]) == tuple(b[2:])


# kind → its check, named check_<kind> after the kinds of xnlos_core.interfaces.BASES.
CHECKS = {kind: globals()[f"check_{kind}"] for kind in BASES}
