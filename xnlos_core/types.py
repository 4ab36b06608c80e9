"""Core data types passed between pipeline stages; every one validates itself on construction.

Conventions (DESIGN.md): SI units, ego frame x forward / y left, azimuth θ = atan2(y, x).
Points are (N, 2) float64 arrays of bird's-eye (x, y) positions in metres.
Every array a type stores is read-only once validated (``flags.writeable = False``; the caller's
own arrays are copied, not locked), so what was checked — finiteness above all — stays true: a stage
that needs to edit one works on a copy.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import InputError
from .geometry import cartesian_to_polar, canonical_line, line_from_points, polar_to_cartesian
from .radar import RadarConfig
from .validation import as_array, check_ascending, check_length, frozen
from .wall import flip_normal

LOS, MNLOS, UNCLASSIFIED = 0, 1, 2
CLASS_NAMES = ("LOS", "mNLOS", "unclassified")


def set_attribute(obj, name, value):
    object.__setattr__(obj, name, value)


class ReadOnlyArrays:
    """Keeps a validated type's arrays read-only through pickle and copy.deepcopy, which rebuild the
    object from its ``__dict__`` (bypassing ``__post_init__``) with writable array copies."""

    def __setstate__(self, state):
        for k, v in state.items():
            if isinstance(v, np.ndarray):
                v = frozen(v)
            elif isinstance(v, tuple) and any(isinstance(x, np.ndarray) for x in v):
                v = tuple(frozen(x) if isinstance(x, np.ndarray) else x for x in v)
            object.__setattr__(self, k, v)


def _points(name: str, value) -> np.ndarray:
    arr = as_array(name, np.empty((0, 2)) if value is None else value, shape=(None, 2), readonly=True)
    return arr


@dataclass(frozen=True, eq=False)
class RAMap(ReadOnlyArrays):
    """Complex range–azimuth map κ ∈ ℂ^{H×W} (Sec. 3.2).

    data: complex64 (n_range, n_azimuth); range_axis: float64 (n_range,) [m], ascending;
    azimuth_axis: float64 (n_azimuth,) [rad], ascending; radar: the configuration that made it;
    velocity, velocity_std: float64 (n_range, n_azimuth) or None: each cell's radial velocity
    v̂_r = dR/dt [m/s] (positive receding) and its σ [m/s] when the map came from Doppler
    processing (:func:`xnlos_core.signal.doppler.doppler_ra_maps`), both or neither.
    """

    data: np.ndarray
    range_axis: np.ndarray
    azimuth_axis: np.ndarray
    radar: RadarConfig
    velocity: np.ndarray | None = None
    velocity_std: np.ndarray | None = None

    def __post_init__(self):
        data = as_array("RAMap.data", self.data, dtype=np.complex64, ndim=2, readonly=True)
        if min(data.shape) < 2:
            raise InputError(f"RAMap.data: expected at least 2×2 cells, got shape {data.shape}")
        r = as_array("RAMap.range_axis", self.range_axis, ndim=1, readonly=True)
        a = as_array("RAMap.azimuth_axis", self.azimuth_axis, ndim=1, readonly=True)
        check_length("RAMap.range_axis", r, data.shape[0], "RAMap.data axis 0")
        check_length("RAMap.azimuth_axis", a, data.shape[1], "RAMap.data axis 1")
        check_ascending("RAMap.range_axis", r)
        check_ascending("RAMap.azimuth_axis", a)
        if r[0] < 0:
            raise InputError(f"RAMap.range_axis: ranges must be ≥ 0 m, got {r[0]}")
        if np.any(np.abs(a) > np.pi):
            raise InputError("RAMap.azimuth_axis: azimuths must lie in [−π, π] rad")
        if not isinstance(self.radar, RadarConfig):
            raise InputError(f"RAMap.radar: expected a RadarConfig, got {type(self.radar).__name__}")
        set_attribute(self, "data", data)
        set_attribute(self, "range_axis", r)
        set_attribute(self, "azimuth_axis", a)
        if (self.velocity is None) != (self.velocity_std is None):
            raise InputError("RAMap.velocity, RAMap.velocity_std: give both (Doppler maps) or neither")
        if self.velocity is not None:
            set_attribute(self, "velocity", as_array("RAMap.velocity", self.velocity, shape=data.shape, readonly=True))
            std = as_array("RAMap.velocity_std", self.velocity_std, shape=data.shape, readonly=True)
            if np.any(std < 0):
                raise InputError("RAMap.velocity_std: σ must be ≥ 0 m/s")
            set_attribute(self, "velocity_std", std)

    @classmethod
    def from_radar(cls, data, radar: RadarConfig) -> "RAMap":
        """Wrap ``data`` with the axes of ``radar`` (shape must be radar.n_range_bins × n_azimuth_bins)."""
        return cls(data, radar.range_axis, radar.azimuth_axis, radar)

    @property
    def shape(self) -> tuple[int, int]:
        return self.data.shape

    @property
    def power(self) -> np.ndarray:
        """|κ|² (linear power, float64), shape (n_range, n_azimuth)."""
        return np.abs(self.data.astype(np.complex128)) ** 2

    def power_db(self, floor_db: float = -300.0) -> np.ndarray:
        """10·log10|κ|² [dB], floored at ``floor_db`` so zeros stay finite."""
        with np.errstate(divide="ignore"):
            return np.maximum(10 * np.log10(self.power), floor_db)


@dataclass(frozen=True, eq=False)
class WallSegment(ReadOnlyArrays):
    """A vertical planar relay wall seen from above: the segment start→end [m], each (2,)."""

    start: np.ndarray
    end: np.ndarray
    name: str = "wall"

    def __post_init__(self):
        set_attribute(self, "start", as_array(f"{self.name}.start", self.start, shape=(2,), readonly=True))
        set_attribute(self, "end", as_array(f"{self.name}.end", self.end, shape=(2,), readonly=True))
        n, b = line_from_points(self.start, self.end)
        set_attribute(self, "_line", (frozen(np.asarray(n, dtype=np.float64)), b))

    @property
    def normal(self) -> np.ndarray:
        """Unit normal n (2,) pointing to the radar side."""
        return self._line[0]

    @property
    def offset(self) -> float:
        """b [m] ≥ 0 in nᵀx + b = 0."""
        return self._line[1]

    @property
    def length(self) -> float:
        return float(np.hypot(*(self.end - self.start)))


@dataclass(frozen=True, eq=False)
class GroundTruth(ReadOnlyArrays):
    """What a simulator knows about a frame; only returns a radar could see are included.

    los_points (N, 2): visible scatterers of LOS surfaces (walls, LOS objects) [m];
    mnlos_points (M, 2): virtual scatterers o' = R_Π(o) whose mirror path is open [m];
    hidden_points (M, 2): the true positions o behind the corner, row-aligned with mnlos_points;
    mnlos_object (M,) int: index into ``object_names`` of the object each hidden point belongs to;
    walls: the relay walls of the scene;
    los_snr_db (N,), mnlos_snr_db (M,): the expected RA-map SNR [dB] of each point's return (its
    resolution cell's power over the noise power per RA cell); NaN where the simulator did not
    record it. Simulators list points above a detectability threshold (``min_snr_db``).
    hidden_velocity (M, 2) [m/s] or None: the velocity of each hidden point o (rigid-body, of its
    object; 0 for static surfaces); mnlos_velocity (M, 2) [m/s] or None: that of its virtual image o',
    (I − 2nnᵀ)·hidden_velocity across its wall (mirror Doppler). Both or neither.
    los_object (N,) int or None: index into ``object_names`` of the object each LOS point belongs
    to, −1 for walls and other static surfaces that are not scene objects; None where the source
    did not record it (dataset shards, recordings).
    los_radial_velocity (N,) [m/s] or None: the range rate r̂ᵀv of each LOS point (0 on static
    surfaces; a road user in line of sight moves), row-aligned with los_points; None where the
    source did not record it (datasets rendered without Doppler, recordings).
    """

    los_points: np.ndarray = None
    mnlos_points: np.ndarray = None
    hidden_points: np.ndarray = None
    mnlos_object: np.ndarray = None
    object_names: tuple[str, ...] = ()
    walls: tuple[WallSegment, ...] = ()
    los_snr_db: np.ndarray = None
    mnlos_snr_db: np.ndarray = None
    hidden_velocity: np.ndarray | None = None
    mnlos_velocity: np.ndarray | None = None
    los_object: np.ndarray | None = None
    los_radial_velocity: np.ndarray | None = None

    def __post_init__(self):
        set_attribute(self, "los_points", _points("GroundTruth.los_points", self.los_points))
        m = _points("GroundTruth.mnlos_points", self.mnlos_points)
        h = _points("GroundTruth.hidden_points", self.hidden_points)
        check_length("GroundTruth.hidden_points", h, len(m), "GroundTruth.mnlos_points")
        obj = np.zeros(len(m), dtype=np.int64) if self.mnlos_object is None else self.mnlos_object
        obj = as_array("GroundTruth.mnlos_object", obj, dtype=np.int64, shape=(len(m),), readonly=True)
        if len(obj) and (obj.min() < 0 or obj.max() >= max(len(self.object_names), 1)):
            raise InputError("GroundTruth.mnlos_object: indices must address GroundTruth.object_names")
        set_attribute(self, "mnlos_points", m)
        set_attribute(self, "hidden_points", h)
        set_attribute(self, "mnlos_object", obj)
        set_attribute(self, "object_names", tuple(self.object_names))
        set_attribute(self, "walls", tuple(self.walls))
        for name, n in (("los_snr_db", len(self.los_points)), ("mnlos_snr_db", len(m))):
            v = getattr(self, name)
            v = np.full(n, np.nan) if v is None else v
            set_attribute(self, name, as_array(f"GroundTruth.{name}", v, shape=(n,), finite=False, readonly=True))
        if (self.hidden_velocity is None) != (self.mnlos_velocity is None):
            raise InputError("GroundTruth.hidden_velocity/mnlos_velocity: give both or neither")
        for name in ("hidden_velocity", "mnlos_velocity") if self.hidden_velocity is not None else ():
            set_attribute(self, name, as_array(f"GroundTruth.{name}", getattr(self, name), shape=(len(m), 2), readonly=True))
        if self.los_object is not None:
            lo = as_array("GroundTruth.los_object", self.los_object, dtype=np.int64, shape=(len(self.los_points),),
                          readonly=True)
            if len(lo) and (lo.min() < -1 or lo.max() >= len(self.object_names)):
                raise InputError(f"GroundTruth.los_object: indices must be −1 (a wall) or address "
                                 f"GroundTruth.object_names (0 … {len(self.object_names) - 1}), got "
                                 f"[{lo.min()}, {lo.max()}]")
            set_attribute(self, "los_object", lo)
        if self.los_radial_velocity is not None:
            set_attribute(self, "los_radial_velocity", as_array("GroundTruth.los_radial_velocity", self.los_radial_velocity,
                                                       shape=(len(self.los_points),), readonly=True))

    def above_snr(self, min_snr_db: float) -> "GroundTruth":
        """The points whose recorded SNR is ≥ ``min_snr_db`` [dB] (points with unknown SNR are kept)."""
        keep_l = ~(self.los_snr_db < min_snr_db)
        keep_m = ~(self.mnlos_snr_db < min_snr_db)
        velocities = () if self.hidden_velocity is None else (self.hidden_velocity[keep_m],
                                                               self.mnlos_velocity[keep_m])
        return GroundTruth(self.los_points[keep_l], self.mnlos_points[keep_m], self.hidden_points[keep_m],
                           self.mnlos_object[keep_m], self.object_names, self.walls, self.los_snr_db[keep_l],
                           self.mnlos_snr_db[keep_m], *(velocities or (None, None)),
                           los_object=None if self.los_object is None else self.los_object[keep_l],
                           los_radial_velocity=None if self.los_radial_velocity is None
                           else self.los_radial_velocity[keep_l])


FRAME_IN_SCENE = "frame_in_scene"  # Frame.meta key: the frame's position in its sequence (0 starts one)


@dataclass(frozen=True, eq=False)
class Frame:
    """One radar measurement: an RA map, its timestamp [s], and ground truth when simulated.

    meta: what the source knows besides (free-form). A sequence dataset's frames carry
    ``frame_in_scene`` (int), the frame's position in its sequence: 0 starts a new one, whose
    timestamps start again, and :meth:`xnlos_core.pipeline.Pipeline.process` then resets the stages
    that carry state (tracks, a wall estimator's history)."""

    ra_map: RAMap
    timestamp: float = 0.0
    ground_truth: GroundTruth | None = None
    index: int = 0
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        if not isinstance(self.ra_map, RAMap):
            raise InputError(f"Frame.ra_map: expected an RAMap, got {type(self.ra_map).__name__}")
        if not np.isfinite(self.timestamp):
            raise InputError(f"Frame.timestamp: expected a finite time in seconds, got {self.timestamp}")
        if self.ground_truth is not None and not isinstance(self.ground_truth, GroundTruth):
            raise InputError(f"Frame.ground_truth: expected GroundTruth or None, got {type(self.ground_truth).__name__}")


@dataclass(frozen=True, eq=False)
class Detections(ReadOnlyArrays):
    """Peaks found in an RA map.

    range (K,) [m]; azimuth (K,) [rad]; label (K,) int8 in {LOS=0, MNLOS=1, UNCLASSIFIED=2};
    confidence (K,) in [0, 1]; range_std / azimuth_std (K,) 1-σ measurement errors [m], [rad];
    velocity (K,) or None: radial (Doppler) velocity [m/s], positive receding, along the line of
    sight (for mNLOS the virtual one, radar → o'); velocity_var (K,) its variance [m²/s²] (zeros
    when velocity is given without it; None without velocity).
    ``position`` (K, 2) [m] is derived: (r cos θ, r sin θ). For mNLOS it is the virtual point o'.
    """

    range: np.ndarray
    azimuth: np.ndarray
    label: np.ndarray
    confidence: np.ndarray
    range_std: np.ndarray | None = None
    azimuth_std: np.ndarray | None = None
    velocity: np.ndarray | None = None
    velocity_var: np.ndarray | None = None

    def __post_init__(self):
        r = as_array("Detections.range", self.range, ndim=1, readonly=True)
        k = len(r)
        a = as_array("Detections.azimuth", self.azimuth, shape=(k,), readonly=True)
        lab = as_array("Detections.label", self.label, dtype=np.int8, shape=(k,), readonly=True)
        c = as_array("Detections.confidence", self.confidence, shape=(k,), readonly=True)
        if k and r.min() < 0:
            raise InputError(f"Detections.range: ranges must be ≥ 0 m, got min {r.min()}")
        if k and np.any(np.abs(a) > np.pi):
            raise InputError("Detections.azimuth: azimuths must lie in [−π, π] rad")
        if k and not np.all(np.isin(lab, (LOS, MNLOS, UNCLASSIFIED))):
            raise InputError(f"Detections.label: values must be LOS=0, MNLOS=1 or UNCLASSIFIED=2, got {np.unique(lab)}")
        if k and (c.min() < 0 or c.max() > 1):
            raise InputError(f"Detections.confidence: must lie in [0, 1], got [{c.min()}, {c.max()}]")
        rs = np.zeros(k) if self.range_std is None else self.range_std
        az = np.zeros(k) if self.azimuth_std is None else self.azimuth_std
        rs = as_array("Detections.range_std", rs, shape=(k,), readonly=True)
        az = as_array("Detections.azimuth_std", az, shape=(k,), readonly=True)
        if k and (rs.min() < 0 or az.min() < 0):
            raise InputError("Detections.range_std/azimuth_std: standard deviations must be ≥ 0")
        for name, v in (("range", r), ("azimuth", a), ("label", lab), ("confidence", c),
                        ("range_std", rs), ("azimuth_std", az)):
            set_attribute(self, name, v)
        set_attribute(self, "position", frozen(polar_to_cartesian(r, a)))
        self._doppler(k)

    def _doppler(self, k: int):
        if self.velocity is None:
            if self.velocity_var is not None:
                raise InputError("Detections.velocity_var: given without Detections.velocity")
            return
        v = as_array("Detections.velocity", self.velocity, shape=(k,), readonly=True)
        var = as_array("Detections.velocity_var", np.zeros(k) if self.velocity_var is None else self.velocity_var,
                       shape=(k,), readonly=True)
        if k and var.min() < 0:
            raise InputError(f"Detections.velocity_var: variances must be ≥ 0 [m²/s²], got min {var.min()}")
        set_attribute(self, "velocity", v)
        set_attribute(self, "velocity_var", var)

    @classmethod
    def empty(cls) -> "Detections":
        z = np.empty(0)
        return cls(z, z, np.empty(0, np.int8), z)

    @classmethod
    def from_points(cls, points, label=LOS, confidence=1.0, range_std=0.0, azimuth_std=0.0) -> "Detections":
        """Detections at Cartesian points (K, 2) [m]; scalar or (K,) label, confidence and stds."""
        pts = as_array("Detections.from_points: points", points).reshape(-1, 2)
        r, a = cartesian_to_polar(pts)
        k = len(pts)
        full = lambda v, dtype=np.float64: np.broadcast_to(np.asarray(v, dtype), (k,))  # noqa: E731
        return cls(r, a, full(label, np.int8), full(confidence), full(range_std), full(azimuth_std))

    @classmethod
    def concat(cls, *parts: "Detections") -> "Detections":
        """Rows of several Detections, in order."""
        fields = ("range", "azimuth", "label", "confidence", "range_std", "azimuth_std")
        doppler = ("velocity", "velocity_var")
        if not all(p.velocity is not None for p in parts):  # a velocity for every row or none
            doppler = ()
        return cls(*(np.concatenate([getattr(p, f) for p in parts]) for f in fields + doppler))

    def __len__(self) -> int:
        return len(self.range)

    def select(self, mask) -> "Detections":
        """Subset by boolean mask or index array (the rows keep their order)."""
        idx = np.asarray(mask)
        doppler = () if self.velocity is None else (self.velocity[idx], self.velocity_var[idx])
        return Detections(self.range[idx], self.azimuth[idx], self.label[idx], self.confidence[idx],
                          self.range_std[idx], self.azimuth_std[idx], *doppler)

    def of_class(self, label: int) -> np.ndarray:
        """Indices of detections with this label."""
        return np.flatnonzero(self.label == label)

    def position_cov(self) -> np.ndarray:
        """Cartesian covariance of each position (K, 2, 2) [m²] from (range_std, azimuth_std)."""
        c, s = np.cos(self.azimuth), np.sin(self.azimuth)
        j = np.stack([np.stack([c, -self.range * s], -1), np.stack([s, self.range * c], -1)], -2)
        d = np.zeros((len(self), 2, 2))
        d[:, 0, 0] = self.range_std**2
        d[:, 1, 1] = self.azimuth_std**2
        return j @ d @ np.swapaxes(j, -1, -2)


@dataclass(frozen=True, eq=False)
class WallPosterior(ReadOnlyArrays):
    """Estimate of one relay wall with its uncertainty.

    model: name of the wall model, with n = (cos φ, sin φ) the unit normal and u = (−sin φ, cos φ)
      the along-wall direction:

      * "line": parameters (φ, b); the wall is nᵀx + b = 0.
      * "arc": parameters (φ, b, κ); a circular arc of signed curvature κ [1/m] tangent to the
        line nᵀx + b = 0 at its tangent point p₀ = a − (nᵀa + b)·n, the projection onto that line
        of the fixed ``anchor`` point a (2,) [m] (estimators put it at the centroid of the wall's
        LOS points, so (φ, b) describe the wall where it was seen; None means the radar at the
        origin). Its centre is p₀ − n/κ: κ > 0 bulges towards the radar (convex seen from the
        radar), κ < 0 is concave, κ = 0 is the line. Signed distance (Karimäki form, smooth
        through κ = 0), v = x − p₀: δ(x) = A/(1 + √(1 + κA)), A = 2nᵀv + κ|v|²
        (:mod:`xnlos_core.wall`).

    mean (P,): parameter estimate; cov (P, P): its covariance (symmetric PSD);
    param_names: names of the P parameters; n_points: LOS detections used;
    extent (2, 2): end points of the supported segment or arc [m] (projections of the used points);
    samples (S, P) or None: posterior draws when the estimator has them (in the orientation of
    the estimator's fit; flipping (n, b) to the canonical sign does not change the wall, so a
    sample need not be canonical itself); info: diagnostics; anchor: the arc's anchor point (2,)
    [m] or None (unused by a line). (φ, b) are kept canonical, b ≥ 0 (the radar side positive):
    flipping n maps φ → φ + π, b → −b, κ → −κ (the same wall; p₀ and the anchor stay), and the
    covariance changes sign in the flipped rows.
    """

    model: str
    mean: np.ndarray
    cov: np.ndarray
    param_names: tuple[str, ...] = ("phi", "b")
    n_points: int = 0
    extent: np.ndarray | None = None
    samples: np.ndarray | None = None
    info: dict[str, Any] = field(default_factory=dict)
    anchor: np.ndarray | None = None

    def __post_init__(self):
        m = as_array("WallPosterior.mean", self.mean, ndim=1, readonly=True)
        p = len(m)
        if len(self.param_names) != p:
            raise InputError(f"WallPosterior.param_names: {len(self.param_names)} names for {p} parameters")
        c = as_array("WallPosterior.cov", self.cov, shape=(p, p), readonly=True)
        if not np.allclose(c, c.T, rtol=1e-8, atol=1e-12 * max(1.0, np.abs(c).max())):
            raise InputError("WallPosterior.cov: covariance must be symmetric")
        if p and np.linalg.eigvalsh(c).min() < -1e-9 * max(1.0, np.abs(c).max()):
            raise InputError("WallPosterior.cov: covariance must be positive semi-definite")
        if self.extent is not None:
            set_attribute(self, "extent", as_array("WallPosterior.extent", self.extent, shape=(2, 2), readonly=True))
        if self.samples is not None:
            set_attribute(self, "samples", as_array("WallPosterior.samples", self.samples, shape=(None, p), readonly=True))
        if self.anchor is not None:
            set_attribute(self, "anchor", as_array("WallPosterior.anchor", self.anchor, shape=(2,), readonly=True))
        if self.model in ("line", "arc"):
            want = {"line": 2, "arc": 3}[self.model]
            if p != want:
                names = {"line": "(phi, b)", "arc": "(phi, b, kappa)"}[self.model]
                raise InputError(f"WallPosterior: a {self.model!r} has {want} parameters {names}, got {p}")
            n, b = canonical_line([np.cos(m[0]), np.sin(m[0])], m[1])
            if b != m[1] or not np.allclose(n, [np.cos(m[0]), np.sin(m[0])]):
                # keep (φ, b) canonical (b ≥ 0); φ and b are then taken from the unit normal
                if m[1] < 0:
                    m, c, _ = flip_normal(m, c)
                m = np.concatenate([[np.arctan2(n[1], n[0]), b], m[2:]])
        set_attribute(self, "mean", frozen(m))
        set_attribute(self, "cov", frozen(c))

    @classmethod
    def line(cls, normal, offset: float, cov=None, **kw) -> "WallPosterior":
        """A 'line' posterior from a normal (2,) and offset [m]; cov over (φ, b) defaults to 0."""
        n, b = canonical_line(normal, offset)
        cov = np.zeros((2, 2)) if cov is None else cov
        return cls("line", np.array([np.arctan2(n[1], n[0]), b]), cov, **kw)

    @classmethod
    def arc(cls, normal, offset: float, curvature: float, anchor=None, cov=None, **kw) -> "WallPosterior":
        """An 'arc' posterior: tangent line (normal (2,), offset [m]) touching the arc at the
        projection of ``anchor`` (2,) [m] (None: the radar), curvature κ [1/m]; cov over (φ, b, κ)
        defaults to 0."""
        n = np.asarray(normal, dtype=np.float64)
        norm = float(np.hypot(*n)) if n.shape == (2,) else 0.0
        if not norm > 0 or not np.isfinite(norm):
            raise InputError(f"WallPosterior.arc: normal must be a finite non-zero 2-vector, got {n.tolist()}")
        cov = np.zeros((3, 3)) if cov is None else cov
        return cls("arc", np.array([np.arctan2(n[1], n[0]), float(offset) / norm, float(curvature)]), cov,
                   param_names=("phi", "b", "kappa"), anchor=anchor, **kw)

    @property
    def normal(self) -> np.ndarray:
        """Unit normal n (2,) of the wall line ('line') or of the tangent line at p₀ ('arc')."""
        self._need_line()
        return np.array([np.cos(self.mean[0]), np.sin(self.mean[0])])

    @property
    def offset(self) -> float:
        """Offset b [m] of the wall line ('line') or of the tangent line at p₀ ('arc')."""
        self._need_line()
        return float(self.mean[1])

    @property
    def curvature(self) -> float:
        """Signed curvature κ [1/m]: 0 for a line, mean[2] for an arc (see the class doc)."""
        self._need_line()
        return float(self.mean[2]) if self.model == "arc" else 0.0

    @property
    def anchor_point(self) -> np.ndarray:
        """The anchor a (2,) [m]; the radar (origin) when None."""
        return np.zeros(2) if self.anchor is None else self.anchor

    @property
    def tangent_point(self) -> np.ndarray:
        """p₀ = a − (nᵀa + b)·n (2,) [m]: the projection of the anchor a onto the (tangent) line —
        where an arc touches it; for a line without anchor the foot of the perpendicular from
        the radar."""
        n, a = self.normal, self.anchor_point
        return a - (n @ a + self.offset) * n

    def _need_line(self):
        if self.model not in ("line", "arc"):
            raise InputError(f"WallPosterior: normal/offset are defined for models 'line' and 'arc', "
                             f"this is {self.model!r}")


@dataclass(frozen=True, eq=False)
class HiddenPoints(ReadOnlyArrays):
    """Reconstructed hidden points o with uncertainty.

    mean (M, 2) [m]; cov (M, 2, 2) [m²]; source_index (M,): the mNLOS detection each came from;
    wall_index (M,): the wall (index into the estimator's list) used for the mirror;
    velocity (M, 2) [m/s] and velocity_cov (M, 2, 2) [m²/s²], or None: the hidden velocity where
    the reconstructor had one (from a radial velocity only its observed component,
    :func:`plugins.mirror.mirror_doppler.unmirror_radial_velocity`);
    view (M, 2) [-] or None: the unit direction of the mirrored line of sight at o, from the bounce
    point on the wall towards o (the radar mirrored across the wall sees o from there). An object's
    seen points lie on its side facing that way; trackers use it to place the object's centre.
    gated (G,) int: the mNLOS detections the reconstructor refused as ghosts, their mirror image
    lying where the relay wall cannot show it (:mod:`plugins.mirror.visibility`); not among the M
    points, counted in the frame's ``n_gated``. Empty by default.
    """

    mean: np.ndarray
    cov: np.ndarray
    source_index: np.ndarray
    wall_index: np.ndarray
    velocity: np.ndarray | None = None
    velocity_cov: np.ndarray | None = None
    view: np.ndarray | None = None
    gated: np.ndarray | None = None

    def __post_init__(self):
        m = _points("HiddenPoints.mean", self.mean)
        k = len(m)
        c = as_array("HiddenPoints.cov", self.cov, shape=(k, 2, 2), readonly=True)
        s = as_array("HiddenPoints.source_index", self.source_index, dtype=np.int64, shape=(k,), readonly=True)
        w = as_array("HiddenPoints.wall_index", self.wall_index, dtype=np.int64, shape=(k,), readonly=True)
        if k and (s.min() < 0 or w.min() < 0):
            raise InputError("HiddenPoints.source_index/wall_index: indices must be ≥ 0")
        for name, v in (("mean", m), ("cov", c), ("source_index", s), ("wall_index", w)):
            set_attribute(self, name, v)
        if (self.velocity is None) != (self.velocity_cov is None):
            raise InputError("HiddenPoints.velocity/velocity_cov: give both or neither")
        if self.velocity is not None:
            set_attribute(self, "velocity", as_array("HiddenPoints.velocity", self.velocity, shape=(k, 2), readonly=True))
            set_attribute(self, "velocity_cov", as_array("HiddenPoints.velocity_cov", self.velocity_cov, shape=(k, 2, 2),
                                                readonly=True))
        if self.view is not None:
            v = as_array("HiddenPoints.view", self.view, shape=(k, 2), readonly=True)
            if k and not np.allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-6):
                raise InputError("HiddenPoints.view: expected unit vectors (M, 2), one per hidden point")
            set_attribute(self, "view", v)
        g = as_array("HiddenPoints.gated", np.empty(0, np.int64) if self.gated is None else self.gated,
                     dtype=np.int64, shape=(None,), readonly=True)
        if len(g) and g.min() < 0:
            raise InputError("HiddenPoints.gated: detection indices must be ≥ 0")
        set_attribute(self, "gated", g)

    @classmethod
    def empty(cls) -> "HiddenPoints":
        return cls(np.empty((0, 2)), np.empty((0, 2, 2)), np.empty(0, np.int64), np.empty(0, np.int64))

    def __len__(self) -> int:
        return len(self.mean)


@dataclass(frozen=True, eq=False)
class Tracks(ReadOnlyArrays):
    """Tracked objects after a frame: id (T,), position (T, 2) [m], velocity (T, 2) [m/s],
    predicted (T, 2) [m] position at the next expected timestamp, timestamp [s].

    Optional forecast (all or none, a tracker that forecasts fills them):
    horizons (K,) [s] ahead of ``timestamp`` (each in [0, 3]); forecast (T, K, 2) [m] the predicted
    mean position of each track at each horizon; radius50 / radius90 (T, K) [m] the radii of discs
    around ``forecast`` that hold 50 % / 90 % of the predictive distribution (NaN where the tracker
    has no interval yet); model (T,) str, the motion model each track follows ("cv", or the
    identified terms such as "vx'=vy vy'=vx").
    Optional time-to-appearance (both or none): arrival (T,) [s] the predicted absolute time at which
    each track enters the tracker's named region (NaN: not within the horizon; ``timestamp`` when it
    is already inside), arrival_interval (T, 2) [s] its 5 %–95 % interval (upper +inf when fewer
    than 95 % of the predictive draws arrive within the horizon).
    """

    track_id: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    predicted: np.ndarray
    timestamp: float = 0.0
    horizons: np.ndarray | None = None
    forecast: np.ndarray | None = None
    radius50: np.ndarray | None = None
    radius90: np.ndarray | None = None
    model: tuple | None = None
    arrival: np.ndarray | None = None
    arrival_interval: np.ndarray | None = None

    FORECAST = ("horizons", "forecast", "radius50", "radius90", "model")

    def __post_init__(self):
        i = as_array("Tracks.track_id", self.track_id, dtype=np.int64, ndim=1, readonly=True)
        k = len(i)
        set_attribute(self, "track_id", i)
        for name in ("position", "velocity", "predicted"):
            set_attribute(self, name, as_array(f"Tracks.{name}", getattr(self, name), shape=(k, 2), readonly=True))
        given = [getattr(self, n) is not None for n in self.FORECAST]
        if any(given) and not all(given):
            raise InputError(f"Tracks: give all of {', '.join(self.FORECAST)} or none")
        if all(given):
            h = as_array("Tracks.horizons", self.horizons, ndim=1, readonly=True)
            if len(h) and (h.min() < 0 or h.max() > 3.0):
                raise InputError(f"Tracks.horizons: each must be within [0, 3] s, got {h.tolist()}")
            set_attribute(self, "horizons", h)
            set_attribute(self, "forecast", as_array("Tracks.forecast", self.forecast, shape=(k, len(h), 2), readonly=True))
            for name in ("radius50", "radius90"):
                set_attribute(self, name, as_array(f"Tracks.{name}", getattr(self, name), shape=(k, len(h)),
                                          finite=False, readonly=True))
            model = tuple(str(m) for m in self.model)
            if len(model) != k:
                raise InputError(f"Tracks.model: expected {k} entries (one per track), got {len(model)}")
            set_attribute(self, "model", model)
        if (self.arrival is None) != (self.arrival_interval is None):
            raise InputError("Tracks.arrival/arrival_interval: give both or neither")
        if self.arrival is not None:
            set_attribute(self, "arrival", as_array("Tracks.arrival", self.arrival, shape=(k,), finite=False, readonly=True))
            set_attribute(self, "arrival_interval", as_array("Tracks.arrival_interval", self.arrival_interval, shape=(k, 2),
                                                    finite=False, readonly=True))

    def __len__(self) -> int:
        return len(self.track_id)
