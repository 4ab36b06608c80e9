"""Batched identification of many tracks' motion over a small library of manoeuvres, and its forecast.

Every library entry is linear in its parameters θ once a few shape parameters are fixed on a grid,
so one batched least-squares solve per entry (numpy einsum + ``numpy.linalg.solve`` over all tracks
and grid values at once) identifies every due track of a frame. Times τ = t − t_ref [s] (τ ≤ 0 in the
window, t_ref its last sample), positions p(τ) = B(τ) θ with B (2, P):

* ``cv``: p₀ + v₀τ (P = 4).
* ``line``: p₀ + v₀τ + û βτ²/2 (P = 5): a constant acceleration β [m/s²] along the path's line û (the
  principal axis of the window's positions). It is **braking** when the speed along û falls to zero in
  the future (t* = −(ûᵀv₀)/β > 0: the forecast stops there, the car then stays), **reversing** when it
  went through zero inside the window (t* between the first sample and now: the speed changed sign)
  and the car has since run back farther than twice the residual SD (else it is braking that stopped
  at t*: it stays), **accelerating** otherwise. A reversal is forecast at its present (backward) speed
  (``Entry.coast`` = 0: a reversing car settles at a low reverse speed; the quadratic would have it
  speed up backwards for ever).
* ``turn``: p₀ + R(ω, τ) v₀ (P = 4 + ω): constant speed and turn rate ω [rad/s],
  R = (sin ωτ/ω) I + ((1 − cos ωτ)/ω) J (J the +90° rotation).
* ``turn_accel``: ``turn`` + M(ω, τ) a₀ (P = 6 + ω): an acceleration a₀ [m/s²] that turns with the
  heading, M = ((1 − cos ωτ)/ω²) I + ((ωτ − sin ωτ)/ω²) J — a speed change in a turn.
* ``lane``: p₀ + w û_φ τ + n_φ A σ((τ − τ_c)/s) (P = 4 + τ_c, φ): a **lane change**, driving at w [m/s]
  along the lane û_φ (the principal axis turned by φ) with a lateral offset A [m] across it
  (n_φ = Jû_φ) completed along a logistic σ of centre τ_c [s] and width s = 0.5 s (10–90 % of the offset
  in 2.2 s: the middle of a 4–5 s lane change, chosen on the calibration split): the lateral velocity is bounded and dies out, where a turn's heading
  keeps rotating.
* ``ramp``: p₀ + v₀τ + û β min(τ − τ_k, 0)²/2 (P = 5 + τ_k): a speed change along the line that **ended**
  at τ_k < 0 (a braking, speeding up or reversal that has settled): the forecast goes on at v₀.
* ``kink``: p₀ + v₀τ + d min(τ − τ_k, 0) (P = 6 + τ_k): a velocity that changed by −d [m/s] at τ_k < 0
  (the end of a turn or lane change, as a step): the forecast goes on at v₀, fitted on the window's
  recent part only, where CV over the whole window would follow the old heading.
  ``ramp`` and ``kink`` are reported as ``settled``; τ_k needs ``MIN_BEFORE`` samples before it.

ω, τ_c, φ and τ_k are grid parameters: ``OMEGA_GRID`` (step 0.01 rad/s), ``LANE_CENTRES`` ×
``LANE_ANGLES``, ``KINK_TIMES``.

Selection (the sparsest model that the data demand). Correlated errors count n_eff/n = (1 − ρ)/(1 + ρ)
of their samples (ρ ≥ 0 the lag-1 autocorrelation of the best-fitting entry's residuals; as in
:mod:`estimators.trackers.sindy_model`). An entry m with k_m parameters (its grid parameters included)
replaces CV only when its profile likelihood-ratio statistic

    D_m = f · N ln(RSS_cv / RSS_m)         (N = 2n rows, f = n_eff/n)                          (1)

exceeds the χ² quantile with k_m − 4 degrees of freedom at level α/M (``level`` α, default 0.01,
Bonferroni over the M = 6 alternatives): a straight track is given a manoeuvre model with probability
≈ α at most (under white noise; grid parameters counted as parameters make the test conservative
rather than exact). Among CV and the entries that pass, the least BIC_m = f N ln(RSS_m/N) + k_m ln(f N)
wins, ties within :func:`xnlos_core.numerics.criterion_tolerance` to the fewest parameters — except
that a turn needs a BIC ``TURN_OVER_LANE`` (6, "strong" evidence; Kass & Raftery 1995) below a passing
lane change's: in the first half of a lane change both fit the window alike, and a turn wrongly
followed extrapolates a rotation that the lane change's heading gives back (the margin chosen on the
calibration split, seed 1, of ``benchmarks/bicycle_forecasts.py``). Entries outside the road users'
envelope (``Envelope``) do not compete.

Doppler (a track given as (t, z, ĝ, y)). A hidden point's radial velocity y_i = ĝ_iᵀ dp/dτ(τ_i) + noise
(ĝ_i the unit mirrored line of sight; NaN: none) is linear in θ for every entry, through the derivative
of its basis (:func:`velocity_basis`): the rows λ(ĝ_iᵀ Ḃ(τ_i)θ − y_i) are stacked under the position rows
(at least ``MIN_RADIAL`` of them), and every grid value of every entry is refitted with them at once.
The weight λ = σ_p/σ_r [s] is :mod:`estimators.trackers.sindy_model`'s: first σ_p of the best
position-only fit over σ_r of the radial velocities' successive differences (robust), then, refitted,
the residual RMS of each kind of the best joint fit; σ_r is floored at the caller's ``radial_floor``
(the tracker's ``doppler_floor``, the least radial SD its filter assumes). A track's velocity then comes
from measured radial velocities where the positions give it only through differences of a wandering
centroid (a braking's deceleration shows in the radial velocities' ramp). The selection adds the radial
terms with their own variance profiled out, f_r the share of independent radial residuals (``radial_share``:
"ar1" from their lag-1 autocorrelation over adjacent samples, "full" 1, as in sindy_model):

    D_m = f N ln(RSS_cv/RSS_m) + f_r m ln(RSS_r,cv/RSS_r,m),
    BIC_m = f N ln(RSS_m/N) + f_r m ln(RSS_r,m/m) + k_m ln(f N + f_r m)                        (2)

(RSS_r the radial residuals' sum of squares [m²/s²], m their number), and Σ_θ = σ² (AᵀA)⁻¹/f of the
weighted design A with σ² = (RSS + λ² RSS_r)/(N + m − k).

Hand-written on numpy rather than with pysindy: pysindy fits one system at a time (an sklearn estimator
per fit, 6–17 ms a track with the ensemble's refits, ``benchmarks/tracking_speed.md``), where the batched
normal equations here fit every track of a frame in one matrix product per entry; with a library this
small every support is a candidate, so no sparse-regression path is needed to propose them.

Forecast (:func:`predict`, :func:`predict_many` for many tracks at once): the selected entry's B(τ)θ with covariance B Σ_θ Bᵀ, Σ_θ = σ² (BᵀB)⁻¹ / f
(σ² = RSS/(N − k)), plus the model-selection uncertainty Σ_j w_j (μ_j − μ)(μ_j − μ)ᵀ over the entries
with BIC weights w_j ∝ exp(−BIC_j/2) (Schwarz weights; Burnham & Anderson 2002, §6.4). A braking
entry's τ is cut at its stop; a reversal's goes on at its present speed (:func:`forecast_basis`).
Anchored (``predict_many``'s ``anchor``: a filter's position p and velocity v at the forecast's origin
τ₀): each entry's path keeps its shape about its own tangent at τ₀ and starts from (p, v), Eq. (3) of
:func:`predict_many` — the CV entry then forecasts exactly p + v h. A tracker whose filter measures the
velocity directly (Doppler) starts the forecast from its state, where the window fit's level and slope
carry the wander of a reconstructed car's points; and so does a fit whose window's own present velocity
is biased (:attr:`LibraryFit.local_origin`): a lane change — anchored, its forecast is the filter's
line bent by the rest of the fitted offset, A n_φ (σ(τ₀ + h) − σ(τ₀) − σ′(τ₀) h): the filter's lateral
velocity dies out as the lane change's does, where a CV forecast would carry it on for the whole horizon
— and a CV selection with a manoeuvre clearly better by BIC (CV weight < ``CV_BENT``), whose window
velocity averages a bend.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from functools import lru_cache

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.numerics import simplest_within

LIBRARY = ("cv", "line", "turn", "turn_accel", "lane", "ramp", "kink")
N_PARAMS = {"cv": 4, "line": 5, "turn": 5, "turn_accel": 7, "lane": 6, "ramp": 6, "kink": 7}  # grid parameters included
VECTORS = {"cv": (0, 2), "line": (0, 2), "turn": (0, 2), "turn_accel": (0, 2, 4), "lane": (0,), "ramp": (0, 2),
           "kink": (0, 2, 4)}  # 2-vectors of θ
N_LINEAR = {"cv": 4, "line": 5, "turn": 4, "turn_accel": 6, "lane": 4, "ramp": 5, "kink": 6}
OMEGA_GRID = np.linspace(-1.2, 1.2, 241)         # [rad/s], step 0.01
LANE_CENTRES = np.arange(-3.5, 1.01, 0.25)       # τ_c [s]: the lane change's midpoint, past to 1 s ahead
LANE_ANGLES = np.deg2rad(np.arange(-8.0, 8.1, 2.0))  # [rad] the lane's direction about the principal axis
KINK_TIMES = np.arange(-2.5, -0.49, 0.25)          # τ_k [s]: when a settled track's velocity last changed
LANE_SCALES = np.array([0.5])  # s [s]: 10–90 % of the offset in 4.4 s = 2.2 s, the middle of a 4–5 s lane change
LANE_MAX = 8.0                                   # [m] largest lateral offset of a lane change (two lanes)
BETA_MAX = 10.0                                  # [m/s²] about 1 g
MIN_SAMPLES = 8
MIN_BEFORE = 4     # samples a ramp or kink needs before its τ_k
TURN_OVER_LANE = 6.0  # BIC margin a turn needs over a passing lane change ("strong", Kass & Raftery 1995)
CV_SURE = 0.5  # BIC weight below which a CV selection forecasts with the "cv_uncertain" disc factor
CV_BENT = 0.1  # BIC weight below which a CV selection's window is not a straight line (LibraryFit.local_origin)
MIN_WEIGHT = 0.01  # entries of a smaller BIC weight leave the forecast mixture (< 1 % of their squared offset)


@dataclass(frozen=True)
class Envelope:
    """The road users' envelope: a speed-up ≤ ``max_speedup`` [m/s²], a lateral acceleration
    |ω|·speed (a lane change's peak A·0.096/s²) ≤ ``max_lateral`` [m/s²], |β| ≤ BETA_MAX."""

    max_speedup: float = 3.0
    max_lateral: float = 5.0


@dataclass(frozen=True)
class Entry:
    """One library entry fitted to one track: ``model`` (LIBRARY), ``hyper`` (5,) = (ω [rad/s], τ_c [s],
    s [s], û (2,)), θ (P,) (p₀ [m] first), ``cov`` (P, P) of θ, BIC ``weight`` (Schwarz), ``stop`` [s]
    (τ at which a braking entry stops; inf otherwise), ``coast`` [s] (τ after which a ``line`` entry's speed is
    held: 0 for a reversal; inf otherwise)."""

    model: str
    hyper: np.ndarray
    theta: np.ndarray
    cov: np.ndarray
    weight: float
    stop: float = float("inf")
    coast: float = float("inf")


@dataclass(frozen=True)
class LibraryFit:
    """A track's identification: ``label`` (cv, brake, accelerate, reverse, turn, lane_change, settled),
    t_ref [s] (its last sample), ``entries`` (the selected one first, then the others for the mixture), sigma [m]
    (the selected entry's per-axis residual SD), ``statistic`` D of Eq. (1) of the selected entry (0 for
    CV), ``rates`` (β [m/s²] tangential, ω [rad/s]) for a linear filter, ``evidence`` BIC(CV) − BIC(selected)
    (0 for CV)."""

    label: str
    t_ref: float
    entries: tuple
    sigma: float
    statistic: float
    rates: np.ndarray
    evidence: float = 0.0

    @property
    def interval_key(self) -> str:
        """The key of this fit's disc factor: its label, or ``cv_uncertain`` for a CV selection whose CV
        entry holds less than half the BIC weight (a manoeuvre model fits better by BIC but fails the
        test: the track may be starting one)."""
        if self.label == "cv" and self.entries[0].weight < CV_SURE:
            return "cv_uncertain"
        return self.label

    @property
    def local_origin(self) -> bool:
        """Whether this fit's forecast should start from a filter's position and velocity at its origin
        (``predict_many``'s ``anchor``, Eq. 3) rather than from the window fit's own (module docstring,
        forecast): a **lane change**, whose window fit gives the lateral offset's shape — how the lateral
        drift ends — but whose lane direction the window pins poorly (the second half of a lane change and
        the first half of an opposite one, about a slightly turned lane, fit a window alike), and a **CV**
        selection whose CV entry holds less than ``CV_BENT`` of the BIC weight: a manoeuvre fits the window
        clearly better without passing the test, so the window is no straight line and its least-squares
        velocity is the average over a bend, not the present one."""
        if self.label == "lane_change":
            return True
        return self.label == "cv" and self.entries[0].weight < CV_BENT

    def to_dict(self) -> dict:
        return {"label": self.label, "t_ref": float(self.t_ref), "sigma": float(self.sigma),
                "statistic": float(self.statistic), "rates": self.rates.tolist(), "evidence": float(self.evidence),
                "entries": [{"model": e.model, "hyper": e.hyper.tolist(), "theta": e.theta.tolist(),
                             "cov": e.cov.tolist(), "weight": float(e.weight),
                             "stop": None if np.isinf(e.stop) else float(e.stop),
                             "coast": None if np.isinf(e.coast) else float(e.coast)} for e in self.entries]}

    @classmethod
    def from_reader(cls, r) -> "LibraryFit":
        """From :meth:`to_dict` through an :class:`estimators.state.StateReader` (typed errors)."""
        from estimators.state import StateReader

        entries = []
        for i, d in enumerate(r.items("entries")):
            e = StateReader(d, f"{r.where}: entries[{i}]")
            model = e.text("model")
            if model not in LIBRARY:
                raise InputError(f"{e.where}: model must be one of {LIBRARY}, got {model!r}")
            p = N_LINEAR[model]
            stop = d.get("stop") if isinstance(d, dict) else None
            coast = d.get("coast") if isinstance(d, dict) else None
            entries.append(Entry(model, e.array("hyper", (5,)), e.array("theta", (p,)), e.array("cov", (p, p)),
                                 e.number("weight"), float("inf") if stop is None else e.number("stop"),
                                 float("inf") if coast is None else e.number("coast")))
        if not entries:
            raise InputError(f"{r.where}: entries must hold at least the selected model")
        evidence = r.number("evidence") if r.data.get("evidence") is not None else 0.0  # absent in older checkpoints
        return cls(r.text("label"), r.number("t_ref"), tuple(entries), r.number("sigma"), r.number("statistic"),
                   r.array("rates", (2,)), evidence)


def _kernels(omega, tau):
    """a = sin(ωτ)/ω, b = (1 − cos ωτ)/ω, c = (1 − cos ωτ)/ω², d = (ωτ − sin ωτ)/ω² (broadcast), with
    their limits at ω → 0 (τ, 0, τ²/2, 0)."""
    x = omega * tau
    a = tau * np.sinc(x / np.pi)
    c = tau * tau / 2 * np.sinc(x / (2 * np.pi)) ** 2
    b = omega * c
    small = np.abs(x) < 1e-2
    with np.errstate(divide="ignore", invalid="ignore"):
        d_direct = (x - np.sin(x)) / (omega * omega)
    d = np.where(small, tau * tau * (x / 6 - x ** 3 / 120), d_direct)
    return a, b, c, d


def _design(model: str, hyper, tau):
    """(ω, τ_c, s, û_x, û_y (…, 1), τ broadcast (…, L), zeros (…, L, 2, P)) of :func:`basis` and
    :func:`velocity_basis` for hyper (…, 5) and tau (…, L) [s]."""
    hyper = np.asarray(hyper, dtype=np.float64)
    tau = np.asarray(tau, dtype=np.float64)
    om, tc, s, ux, uy = (hyper[..., i, None] for i in range(5))
    shape = np.broadcast_shapes(om.shape, tau.shape)
    return om, tc, s, ux, uy, np.broadcast_to(tau, shape), np.zeros(shape + (2, N_LINEAR[model]))


def basis(model: str, hyper, tau) -> np.ndarray:
    """B (…, L, 2, P) of entry ``model`` at times tau (…, L) [s] for hyper (…, 5) (module docstring)."""
    om, tc, s, ux, uy, t, out = _design(model, hyper, tau)
    out[..., 0, 0] = out[..., 1, 1] = 1.0
    if model in ("cv", "line"):
        out[..., 0, 2] = out[..., 1, 3] = t
    if model == "line":
        out[..., 0, 4], out[..., 1, 4] = ux * t * t / 2, uy * t * t / 2
    if model in ("turn", "turn_accel"):
        a, b, c, d = _kernels(om, t)
        out[..., 0, 2], out[..., 1, 2], out[..., 0, 3], out[..., 1, 3] = a, b, -b, a
        if model == "turn_accel":
            out[..., 0, 4], out[..., 1, 4], out[..., 0, 5], out[..., 1, 5] = c, d, -d, c
    if model == "ramp":
        m = np.minimum(t - tc, 0.0)
        out[..., 0, 2] = out[..., 1, 3] = t
        out[..., 0, 4], out[..., 1, 4] = ux * m * m / 2, uy * m * m / 2
    if model == "kink":
        m = np.minimum(t - tc, 0.0)
        out[..., 0, 2] = out[..., 1, 3] = t
        out[..., 0, 4] = out[..., 1, 5] = m
    if model == "lane":
        g = 0.5 * (1.0 + np.tanh((t - tc) / (2 * s)))  # the logistic σ((τ − τ_c)/s)
        out[..., 0, 2], out[..., 1, 2] = ux * t, uy * t
        out[..., 0, 3], out[..., 1, 3] = -uy * g, ux * g
    return out


def velocity_basis(model: str, hyper, tau) -> np.ndarray:
    """dB/dτ (…, L, 2, P) [1/s on the p₀ columns: 0] of entry ``model`` at tau (…, L) [s]: the velocity
    dp/dτ = (dB/dτ) θ, the rows of a radial velocity y = ĝᵀ dp/dτ (module docstring, Doppler). Closed
    forms of the derivatives of :func:`basis` (a′ = cos ωτ, b′ = sin ωτ, c′ = a, d′ = b; the logistic's
    σ(1 − σ)/s; min(τ − τ_k, 0)′ = [τ < τ_k])."""
    om, tc, s, ux, uy, t, out = _design(model, hyper, tau)
    if model in ("cv", "line", "ramp", "kink"):
        out[..., 0, 2] = out[..., 1, 3] = 1.0
    if model == "line":
        out[..., 0, 4], out[..., 1, 4] = ux * t, uy * t
    if model in ("turn", "turn_accel"):
        a, b, _, _ = _kernels(om, t)
        co, si = np.cos(om * t), np.sin(om * t)
        out[..., 0, 2], out[..., 1, 2], out[..., 0, 3], out[..., 1, 3] = co, si, -si, co
        if model == "turn_accel":
            out[..., 0, 4], out[..., 1, 4], out[..., 0, 5], out[..., 1, 5] = a, b, -b, a
    if model == "ramp":
        m = np.minimum(t - tc, 0.0)
        out[..., 0, 4], out[..., 1, 4] = ux * m, uy * m
    if model == "kink":
        out[..., 0, 4] = out[..., 1, 5] = (t < tc).astype(np.float64)
    if model == "lane":
        g = 0.5 * (1.0 + np.tanh((t - tc) / (2 * s)))
        dg = g * (1.0 - g) / s
        out[..., 0, 2], out[..., 1, 2] = ux * np.ones_like(t), uy * np.ones_like(t)
        out[..., 0, 3], out[..., 1, 3] = -uy * dg, ux * dg
    return out



@lru_cache(maxsize=8)
def _grid(model: str) -> np.ndarray:
    """hyper (G, 5) of entry ``model`` in a track's own frame (û = +x) (read-only: shared)."""
    if model in ("turn", "turn_accel"):
        h = np.zeros((len(OMEGA_GRID), 5))
        h[:, 0] = OMEGA_GRID
    elif model == "lane":
        tc, s, phi = np.meshgrid(LANE_CENTRES, LANE_SCALES, LANE_ANGLES, indexing="ij")
        h = np.zeros((tc.size, 5))
        h[:, 1], h[:, 2], h[:, 3], h[:, 4] = tc.ravel(), s.ravel(), np.cos(phi.ravel()), np.sin(phi.ravel())
        return _readonly(h)
    elif model in ("kink", "ramp"):
        h = np.zeros((len(KINK_TIMES), 5))
        h[:, 1] = KINK_TIMES
    else:
        h = np.zeros((1, 5))
    h[:, 3] = 1.0
    return _readonly(h)


def _readonly(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


FULL = (("line", ("cv", "line")), ("turn_accel", ("turn", "turn_accel")), ("lane", ("lane",)), ("ramp", ("ramp",)),
        ("kink", ("kink",)))


@lru_cache(maxsize=32)
def _shared(key: bytes):
    """Per sample-time pattern τ (L,) (``key``: its bytes): for each full entry its design X (G, 2L, P) and
    for each nested entry (BᵀB)⁻¹ (G, P', P') of its first P' columns. Tracks sampled at the same
    relative times (every frame seen, the common case) share them, and successive frames repeat them.
    Also per full entry the grid values it may take (G,): a ``ramp`` or ``kink`` needs ``MIN_BEFORE``
    samples before its τ_k (else its extra columns vanish or fit a sample or two)."""
    tau = np.frombuffer(key, dtype=np.float64)
    out = {}
    for full, models in FULL:
        grid = _grid(full)
        valid = np.ones(len(grid), bool)
        if full in ("ramp", "kink"):
            valid = np.sum(tau[None, :] < grid[:, 1, None] - 1e-9, axis=1) >= MIN_BEFORE
        X = basis(full, grid, tau[None, :])                          # (G, L, 2, P)
        X = X.reshape(X.shape[0], 2 * len(tau), -1)
        A = np.swapaxes(X, -1, -2) @ X
        invs = {}
        for m in models:
            c = N_LINEAR[m]
            scale = np.sqrt(np.einsum("...ii->...i", A[:, :c, :c]))
            scale = np.where(scale > 0, scale, 1.0)                  # a vanishing column (an invalid grid value)
            An = A[:, :c, :c] / scale[:, :, None] / scale[:, None, :] + 1e-12 * np.eye(c)
            invs[m] = np.linalg.inv(An) / scale[:, :, None] / scale[:, None, :]
        G, K, P = X.shape
        flat = np.ascontiguousarray(X.transpose(1, 0, 2).reshape(K, G * P))  # (2L, G·P): one BLAS product fits all
        out[full] = (X, invs, valid, flat)
    return out


def _pick(rss: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Per track (T,) the grid index of least RSS (T, G), ties within a relative 1e-9 to the earliest in
    ``order`` (the grid values by preference): the choice never follows a last-bit difference."""
    r = rss[:, order]
    best = r.min(axis=1, keepdims=True)
    tied = r <= best + 1e-9 * np.abs(best) + 1e-300
    return order[np.argmax(tied, axis=1)]


def _fit_group(tau: np.ndarray, z: np.ndarray) -> dict:
    """Every entry of the library fitted to tracks sampled at the same τ (L,), local positions z (T, L, 2):
    {model: (grid index (T,), θ (T, P), RSS (T,), (BᵀB)⁻¹ (T, P, P), residuals (T, 2L))}."""
    shared = _shared(np.ascontiguousarray(tau).tobytes())
    T = len(z)
    zf = z.reshape(T, -1)
    zz = np.sum(zf * zf, axis=1)
    idx = np.arange(T)
    out = {}
    for full, models in FULL:
        X, invs, valid, flat = shared[full]
        G, K, P = X.shape
        b = (zf @ flat).reshape(T, G, P)                                       # one BLAS product: BᵀWz
        for m in models:
            c = N_LINEAR[m]
            bc = np.ascontiguousarray(b[..., :c].transpose(1, 2, 0))          # (G, c, T)
            theta = (invs[m] @ bc).transpose(2, 0, 1)                         # (T, G, c)
            rss = np.maximum(zz[:, None] - np.einsum("tgp,tgp->tg", theta, b[..., :c]), 0.0)
            rss = np.where(valid, rss, zz[:, None])                           # an invalid grid value fits nothing
            order = (np.argsort(np.abs(OMEGA_GRID), kind="stable") if m in ("turn", "turn_accel")
                     else np.arange(rss.shape[1]))
            g = _pick(rss, order)
            th = theta[idx, g]
            resid = zf - np.einsum("tkp,tp->tk", X[g][:, :, :c], th)     # (T, 2L) at the chosen grid values
            out[m] = (g, th, rss[idx, g], invs[m][g], resid)
    return out


@lru_cache(maxsize=64)
def lr_threshold(dof: int, level: float, tests: int) -> float:
    """χ²_dof quantile at 1 − level/tests (scipy.special here, not at import: cheap start-up)."""
    from scipy.special import chdtri

    return float(chdtri(dof, level / tests))


def line_direction(z: np.ndarray) -> np.ndarray:
    """Unit principal axis (2,) of a track's positions z (n, 2), sign-fixed so that the net displacement
    runs along it (ties: +x)."""
    d = z - z.mean(axis=0)
    _, vec = np.linalg.eigh(d.T @ d)
    u = vec[:, 1]
    return u if float((z[-1] - z[0]) @ u) >= 0 else -u


def _rotation(model: str, rot: np.ndarray) -> np.ndarray:
    """R (P, P) taking θ from a track's own frame (û = +x, n = +y) to the world: each 2-vector of θ
    (p₀, v₀, a₀) rotates by ``rot`` (2, 2) = [û, Jû], the scalars (β, A) stay."""
    R = np.eye(N_LINEAR[model])
    for j in VECTORS[model]:
        R[j:j + 2, j:j + 2] = rot
    return R


RADIAL_SHARES = ("ar1", "full")
MIN_RADIAL = 3  # radial velocities a track needs for its Doppler rows (a robust σ_r from their differences)


def identify_batch(tracks, level: float = 0.01, envelope: Envelope = Envelope(), radial_share: str = "ar1",
                   radial_floor: float = 0.1) -> list[LibraryFit]:
    """Identify every track of ``tracks`` — a sequence of (t (n,) [s] increasing, z (n, 2) [m]), n ≥ 8,
    optionally with its Doppler samples (…, ĝ (n, 2) unit directions, y (n,) [m/s] radial velocities,
    NaN where a sample has none) — over the library at once (module docstring): a :class:`LibraryFit`
    per track. ``radial_share`` ("ar1" or "full") and ``radial_floor`` [m/s] (the least σ_r): module
    docstring, Doppler.

    Each track is fitted in its own frame (centred at its mean position, û along +x): every entry is
    rotation-equivariant there, so tracks sampled at the same relative times share their designs and
    normal matrices (:func:`_shared`), and one matrix product per entry fits them all; a track with
    Doppler rows is then refitted with them, over every grid value at once (:func:`_fit_doppler`)."""
    if not 0 < level < 1:
        raise InputError(f"identify_batch: level must be in (0, 1), got {level}")
    if radial_share not in RADIAL_SHARES:
        raise InputError(f"identify_batch: radial_share must be one of {RADIAL_SHARES}, got {radial_share!r}")
    if not (np.isfinite(radial_floor) and radial_floor > 0):
        raise InputError(f"identify_batch: radial_floor must be a positive SD [m/s], got {radial_floor}")
    groups, local = {}, []
    for i, track in enumerate(tracks):
        if len(track) not in (2, 4):
            raise InputError(f"identify_batch: track {i} must be (t, z) or (t, z, ĝ, y)")
        t, zi = np.asarray(track[0], np.float64), np.asarray(track[1], np.float64)
        if t.ndim != 1 or zi.shape != (len(t), 2) or np.any(np.diff(t) <= 0) or not np.all(np.isfinite(zi)):
            raise InputError(f"identify_batch: track {i} needs t (n,) strictly increasing [s] and finite z (n, 2) [m]")
        if len(t) < MIN_SAMPLES:
            raise InputError(f"identify_batch: track {i} needs ≥ {MIN_SAMPLES} samples, got {len(t)}")
        centre = zi.mean(axis=0)
        u = line_direction(zi)
        rot = np.array([[u[0], -u[1]], [u[1], u[0]]])
        zl = (zi - centre) @ rot                                       # rows: (ûᵀ(z − c), nᵀ(z − c))
        tau = np.round((t - t[-1]) * 1e6) / 1e6                        # µs: one pattern for one frame grid
        radial = _radial_rows(i, track, len(t), rot, radial_floor) if len(track) == 4 else None
        local.append((t[-1], centre, u, tau, zl, radial))
        groups.setdefault(tau.tobytes(), []).append(i)
    out = [None] * len(local)
    k = np.array([N_PARAMS[m] for m in LIBRARY])
    thresholds = np.array([0.0] + [lr_threshold(int(kk - 4), level, len(LIBRARY) - 1) for kk in k[1:]])
    for members in groups.values():
        z = np.array([local[i][4] for i in members])
        tau = local[members[0]][3]
        fits = _fit_group(tau, z)
        T = len(members)
        radial = {"rss": np.zeros((T, len(LIBRARY))), "m": np.zeros(T), "lam": np.zeros(T), "resid": [None] * T}
        patterns = {}                                                  # Doppler tracks by their samples' indices
        for row, i in enumerate(members):
            if local[i][5] is not None:
                patterns.setdefault(local[i][5][0].tobytes(), []).append(row)
        for rows in patterns.values():
            rows = np.array(rows)
            _fit_doppler(fits, radial, rows, tau, z[rows], [local[members[r]][5] for r in rows], k)
        stats = _criteria(fits, z, k, radial, radial_share)
        for row, i in enumerate(members):
            out[i] = _select(fits, row, local[i], k, thresholds, envelope, [a[row] for a in stats])
    return out


def _radial_rows(i: int, track, n: int, rot: np.ndarray, floor: float):
    """(idx (m,), ĝ (m, 2) in the track's own frame, y (m,) [m/s], σ_r [m/s]) of track ``i``'s Doppler
    samples, or None with fewer than MIN_RADIAL; σ_r the robust SD of successive differences of y
    (:func:`estimators.trackers.sindy_model.radial_sigma`), at least ``floor``."""
    from .sindy_model import radial_sigma

    g, y = np.asarray(track[2], np.float64), np.asarray(track[3], np.float64)
    if g.shape != (n, 2) or y.shape != (n,):
        raise InputError(f"identify_batch: track {i}: ĝ must be (n, 2) and y (n,) with n = {n}")
    ok = np.flatnonzero(np.isfinite(y))
    norm = np.linalg.norm(g[ok], axis=1)
    if not np.all(np.isfinite(norm)) or np.any(norm == 0):
        raise InputError(f"identify_batch: track {i}: each sample with a radial velocity needs a finite, "
                         "nonzero direction ĝ (2,)")
    if len(ok) < MIN_RADIAL:
        return None
    sigma_r = max(radial_sigma(y), floor)
    return ok.astype(np.int64), (g[ok] / norm[:, None]) @ rot, y[ok], sigma_r, floor


@lru_cache(maxsize=32)
def _radial_basis(tau_key: bytes, idx_key: bytes) -> dict:
    """Per full entry dB/dτ (G, m, 2, P) at the samples ``idx`` of the sample-time pattern τ (keys: their
    bytes), and XᵀX (G, P, P) of its position design: shared by the tracks of that pattern (read-only)."""
    tau = np.frombuffer(tau_key, dtype=np.float64)
    idx = np.frombuffer(idx_key, dtype=np.int64)
    shared = _shared(tau_key)
    out = {}
    for full, _ in FULL:
        X = shared[full][0]
        out[full] = (_readonly(velocity_basis(full, _grid(full), tau[idx][None, :])),
                     _readonly(np.swapaxes(X, -1, -2) @ X))
    return out


def _fit_doppler(fits: dict, radial: dict, rows: np.ndarray, tau: np.ndarray, z: np.ndarray, samples: list,
                 k: np.ndarray) -> None:
    """Refit the tracks ``rows`` of a group (local positions z (T', L, 2); their Doppler samples
    ``samples``, all at the same sample indices) with their radial rows λ(ĝᵀ Ḃ(τ) θ − y) stacked under
    the position rows, over every grid value and track at once; their entries in ``fits`` and ``radial``
    (RSS_r, m, λ, the radial residuals) are replaced. λ = σ_p/σ_r [s] (module docstring, Doppler) as in
    :mod:`estimators.trackers.sindy_model`: first σ_p of the best position-only fit and σ_r of the radial
    velocities' successive differences; then, refitted, the residual RMS of each kind of the best joint
    fit (σ_r at least the floor)."""
    idx = samples[0][0]
    g = np.array([r[1] for r in samples])                              # (T', m, 2)
    y = np.array([r[2] for r in samples])                              # (T', m)
    sigma_r = np.array([r[3] for r in samples])
    floor = samples[0][4]
    Tn, L = z.shape[:2]
    N, n_r = 2 * L, len(idx)
    ar = np.arange(Tn)
    zf = z.reshape(Tn, -1)
    zz, yy = np.sum(zf * zf, axis=1), np.sum(y * y, axis=1)
    rss_pos = np.stack([fits[m][2][rows] for m in LIBRARY], axis=1)   # (T', M+1)
    j = np.argmin(rss_pos, axis=1)
    tiny = 1e-18 * np.maximum(zz, 1e-6) / N
    lam = np.sqrt(np.maximum(rss_pos[ar, j] / np.maximum(N - k[j], 1.0), tiny)) / sigma_r
    shared = _shared(np.ascontiguousarray(tau).tobytes())
    basis_r = _radial_basis(np.ascontiguousarray(tau).tobytes(), np.ascontiguousarray(idx, np.int64).tobytes())
    parts = {}
    for full, _ in FULL:
        X, _, valid, flat = shared[full]
        Vb, XtX = basis_r[full]
        G, K, P = X.shape
        D = np.einsum("tmc,gmcp->tgmp", g, Vb, optimize=True)          # (T', G, m, P): ĝᵀ dB/dτ
        parts[full] = (X, valid, XtX, (zf @ flat).reshape(Tn, G, P), D, np.einsum("tgmp,tgmq->tgpq", D, D, optimize=True),
                       np.einsum("tgmp,tm->tgp", D, y, optimize=True))
    for first in (True, False):
        used, out = lam, {}
        l2 = (lam * lam)[:, None, None]
        for full, models in FULL:
            X, valid, XtX, Xz, D, DtD, Dy = parts[full]
            for m in models:
                c = N_LINEAR[m]
                A = XtX[None, :, :c, :c] + l2[..., None] * DtD[..., :c, :c]   # (T', G, c, c)
                bz, by = Xz[..., :c], Dy[..., :c]
                scale = np.sqrt(np.einsum("...ii->...i", A))
                scale = np.where(scale > 0, scale, 1.0)
                An = A / scale[..., :, None] / scale[..., None, :] + 1e-12 * np.eye(c)
                theta = np.linalg.solve(An, ((bz + l2 * by) / scale)[..., None])[..., 0] / scale
                rss_p = zz[:, None] - 2 * np.einsum("tgp,tgp->tg", theta, bz) + np.einsum(
                    "tgp,gpq,tgq->tg", theta, XtX[:, :c, :c], theta, optimize=True)
                rss_r = yy[:, None] - 2 * np.einsum("tgp,tgp->tg", theta, by) + np.einsum(
                    "tgp,tgpq,tgq->tg", theta, DtD[..., :c, :c], theta, optimize=True)
                rss_p = np.where(valid, np.maximum(rss_p, 0.0), zz[:, None])  # an invalid grid value fits nothing
                rss_r = np.where(valid, np.maximum(rss_r, 0.0), yy[:, None])
                order = (np.argsort(np.abs(OMEGA_GRID), kind="stable") if m in ("turn", "turn_accel")
                         else np.arange(len(valid)))
                gi = _pick(rss_p + (lam * lam)[:, None] * rss_r, order)
                th = theta[ar, gi]
                rp = zf - np.einsum("tkp,tp->tk", X[gi][:, :, :c], th)
                rr = y - np.einsum("tmp,tp->tm", D[ar, gi][..., :c], th)
                sc = scale[ar, gi]                                     # (BᵀB + λ²DᵀD)⁻¹ at the chosen values only
                inv = np.linalg.inv(An[ar, gi]) / sc[:, :, None] / sc[:, None, :]
                out[m] = (gi, th, np.sum(rp * rp, axis=1), inv, rp, np.sum(rr * rr, axis=1), rr)
        if first:                                                      # λ from the best joint fit's residuals
            obj = np.stack([out[m][2] + lam * lam * out[m][5] for m in LIBRARY], axis=1)
            best = np.argmin(obj, axis=1)
            rp_best = np.stack([out[m][2] for m in LIBRARY], axis=1)[ar, best]
            rr_best = np.stack([out[m][5] for m in LIBRARY], axis=1)[ar, best]
            lam = np.sqrt(np.maximum(rp_best / N, tiny)) / np.maximum(np.sqrt(rr_best / n_r), floor)
    for m in LIBRARY:
        gi, th, rss_p, inv, rp, rss_r, rr = out[m]
        fits[m][0][rows], fits[m][1][rows], fits[m][2][rows], fits[m][3][rows], fits[m][4][rows] = gi, th, rss_p, inv, rp
        radial["rss"][rows, LIBRARY.index(m)] = rss_r
        for r, row in enumerate(rows):
            radial.setdefault("all", {})[(int(row), m)] = rr[r]
    radial["m"][rows], radial["lam"][rows] = n_r, used
    for row in rows:
        radial["resid"][int(row)] = idx


def _criteria(fits: dict, z: np.ndarray, k: np.ndarray, radial: dict | None = None, radial_share: str = "ar1") -> tuple:
    """Per track of a group (z (T, L, 2) its local positions) and entry: f (T,), the statistic D of
    Eq. (1), BIC and σ² (T, M+1) — the selection's arithmetic for all tracks at once; with ``radial``
    (from :func:`_fit_doppler`) the radial terms of the module docstring's Doppler section added."""
    T, L = z.shape[:2]
    N = 2 * L
    rss = np.stack([fits[m][2] for m in LIBRARY], axis=1)             # (T, M+1)
    floor = 1e-18 * np.maximum(np.sum(z.reshape(T, -1) ** 2, axis=1), 1e-6)
    rss = np.maximum(rss, floor[:, None])                              # rounding-level RSS never chooses
    m = np.zeros(T) if radial is None else radial["m"]
    lam = np.zeros(T) if radial is None else radial["lam"]
    rss_r = np.zeros_like(rss) if radial is None else radial["rss"]
    has = m > 0
    rss_r = np.where(has[:, None], np.maximum(rss_r, 1e-18), 1.0)
    best = np.argmin(rss + (lam * lam)[:, None] * rss_r, axis=1)
    resid = np.stack([fits[mm][4] for mm in LIBRARY])[best, np.arange(T)].reshape(T, L, 2)
    num = np.sum(resid[:, :-1] * resid[:, 1:], axis=(1, 2))
    den = np.sum(resid * resid, axis=(1, 2))
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.where(den > 1e-24 * L, np.clip(num / den, 0.0, 1.0), 0.0)
    f = np.maximum((1 - rho) / (1 + rho), 1.0 / L)                     # f = (1 − ρ)/(1 + ρ), ≥ 1/n
    f_r = np.ones(T)
    if radial is not None and radial_share == "ar1":
        for row in np.flatnonzero(has):                                # the best entry's radial residuals
            r = radial["all"][(row, LIBRARY[best[row]])]
            adj = np.flatnonzero(np.diff(radial["resid"][row]) == 1)
            d = float(r @ r)
            rho_r = float(np.clip(r[adj] @ r[adj + 1] / d, 0.0, 1.0)) if d > 1e-24 * len(r) else 0.0
            f_r[row] = max((1 - rho_r) / (1 + rho_r), 1.0 / len(r))
    f_r = np.where(has, f_r, 0.0)
    stat = f[:, None] * N * np.log(rss[:, :1] / rss) + (f_r * m)[:, None] * np.log(rss_r[:, :1] / rss_r)  # Eq. (1), (2)
    bic = (f[:, None] * N * np.log(rss / N) + (f_r * m)[:, None] * np.log(rss_r / np.maximum(m, 1)[:, None])
           + k * np.log((f * N + f_r * m)[:, None]))
    sigma2 = (rss + (lam * lam)[:, None] * np.where(has[:, None], rss_r, 0.0)) / np.maximum(N + m[:, None] - k, 1.0)
    return f, stat, bic, sigma2


def _select(fits: dict, row: int, track, k: np.ndarray, thresholds: np.ndarray, env: Envelope, crit) -> LibraryFit:
    """One track's selection and entries (module docstring, selection) from its group's fits and its
    row of :func:`_criteria`."""
    t_ref, centre, u, tau, zl, _ = track
    f, stat, bic, sigma2 = crit
    f = float(f)
    local = [(m, _grid(m)[fits[m][0][row]], fits[m][1][row], fits[m][3][row]) for m in LIBRARY]
    ok, described = np.ones(len(LIBRARY), bool), []
    for j, (m, hyper, theta, inv) in enumerate(local):  # in the track's own frame: labels and rates are invariant
        label, stop, rates, inside = _describe(m, hyper, theta, float(tau[0]), env, math.sqrt(sigma2[j]))
        ok[j] = inside
        described.append((label, rates, stop, 0.0 if label == "reverse" else float("inf")))
    passing = ok & (stat > thresholds)
    passing[0] = True
    cand = np.flatnonzero(passing)
    best = int(cand[simplest_within(bic[cand], k[cand])])
    lane = LIBRARY.index("lane")
    if LIBRARY[best] in ("turn", "turn_accel") and passing[lane] and bic[lane] <= bic[best] + TURN_OVER_LANE:
        best = lane                                                    # a turn needs strong evidence over a lane change
    wts = np.where(ok, np.exp(-0.5 * (bic - bic[ok].min())), 0.0)
    wts /= wts.sum()
    order = [best] + [j for j in range(len(LIBRARY)) if j != best and ok[j] and (wts[j] >= MIN_WEIGHT or j == 0)]
    # (CV always kept, for :func:`demote`; below MIN_WEIGHT it leaves the mixture: :func:`_spread_weight`)
    rot = np.array([[u[0], -u[1]], [u[1], u[0]]])
    ents = []
    for j in order:                                                    # to the world: the entries kept only
        m, hyper, theta, inv = local[j]
        R = _rotation(m, rot)
        th = R @ theta
        th[:2] += centre
        hyper = hyper.copy()
        hyper[3:5] = rot @ hyper[3:5]                                  # the line's direction in the world
        ents.append(Entry(m, hyper, th, sigma2[j] / f * (R @ inv @ R.T), float(wts[j]), described[j][2],
                          described[j][3]))
    ents = tuple(ents)
    return LibraryFit(described[best][0], float(t_ref), ents, float(np.sqrt(sigma2[best])), float(stat[best]),
                      np.asarray(described[best][1], dtype=np.float64), float(bic[0] - bic[best]))


def _describe(model: str, hyper, theta, tau_first: float, env: Envelope, sigma: float = 0.0):
    """(label, stop τ [s] or inf, rates (β, ω), inside the envelope) of a fitted entry (module docstring);
    sigma [m] the entry's residual SD: a reversal must have run back farther than 2σ since its turning
    point, else the window shows a car that stopped there (it stays)."""
    v = theta[2:4]
    speed = math.hypot(v[0], v[1])
    if model == "cv":
        return "cv", float("inf"), (0.0, 0.0), True
    if model == "line":
        s1, beta = float(hyper[3:5] @ v), float(theta[4])
        if abs(beta) > BETA_MAX:
            return "brake", float("inf"), (0.0, 0.0), False
        if beta * s1 < 0:                                             # the speed along û falls to zero at t* > 0
            return "brake", -s1 / beta, (-abs(beta), 0.0), True
        t_star = -s1 / beta if beta != 0 else -np.inf
        if tau_first < t_star <= 0:                                   # through zero inside the window
            if 0.5 * abs(beta) * t_star ** 2 <= 2.0 * sigma:           # no farther back than the noise: stopped
                return "brake", t_star, (-abs(beta), 0.0), True
            return "reverse", float("inf"), (abs(beta), 0.0), True
        return "accelerate", float("inf"), (abs(beta), 0.0), abs(beta) <= env.max_speedup
    if model in ("kink", "ramp"):
        return "settled", float("inf"), (0.0, 0.0), True
    omega = float(hyper[0])
    if model in ("turn", "turn_accel"):
        beta = float(theta[4:6] @ v) / max(speed, 1e-9) if model == "turn_accel" else 0.0
        inside = abs(omega) * speed <= env.max_lateral and beta <= env.max_speedup and abs(beta) <= BETA_MAX
        return "turn", float("inf"), (beta, omega), inside
    amp = float(theta[3])
    inside = abs(amp) <= LANE_MAX and abs(amp) * 0.0962 / hyper[2] ** 2 <= env.max_lateral
    return "lane_change", float("inf"), (0.0, 0.0), inside


def forecast_basis(model: str, hyper, tau, stop, coast) -> np.ndarray:
    """B (…, K, 2, P) of a forecast at tau (…, K) [s]: the entry's basis at min(τ, stop) (a braking entry
    stays at its stop), continued beyond ``coast`` c (a ``line`` entry only) at the speed it has there,
    B(c) + (τ − c) dB/dτ(c) — a reversal is forecast at its present (backward) speed, not accelerating on."""
    tau = np.minimum(np.asarray(tau, dtype=np.float64), stop)
    c = np.minimum(tau, coast)
    B = basis(model, hyper, c)
    extra = tau - c
    if model == "line" and np.any(extra > 0):
        h = np.asarray(hyper, dtype=np.float64)
        B[..., 0, 2] += extra
        B[..., 1, 3] += extra
        B[..., 0, 4] += h[..., 3, None] * c * extra
        B[..., 1, 4] += h[..., 4, None] * c * extra
    return B


def predict(fit: LibraryFit, tau) -> tuple[np.ndarray, np.ndarray]:
    """Mean (K, 2) [m] and covariance (K, 2, 2) [m²] of the position at tau (K,) ≥ 0 [s] after
    ``fit.t_ref``: the selected entry's, plus the entries' BIC-weighted spread about it (module
    docstring, forecast). No process noise here: the caller adds its own. :func:`predict_many` of one fit."""
    mean, cov = predict_many([fit], np.asarray(tau, dtype=np.float64).reshape(1, -1))
    return mean[0], cov[0]


def _spread_weight(w: float) -> float:
    """An entry's weight in the mixture spread: 0 below MIN_WEIGHT (module docstring, forecast)."""
    return w if w >= MIN_WEIGHT else 0.0


def demote(fit: LibraryFit) -> LibraryFit:
    """``fit`` with its CV entry selected (label ``cv``, no rates; the other entries stay for the
    mixture's spread): a manoeuvre whose evidence falls short of the caller's bar (the tracker's
    ``min_evidence``)."""
    cv = next(e for e in fit.entries if e.model == "cv")
    rest = tuple(e for e in fit.entries if e is not cv)
    return LibraryFit("cv", fit.t_ref, (cv,) + rest, fit.sigma, 0.0, np.zeros(2), 0.0)


def forecast_velocity_basis(model: str, hyper, tau, stop, coast) -> np.ndarray:
    """dB/dτ (…, K, 2, P) of the forecast path of :func:`forecast_basis` at tau (…, K) [s]: 0 past a
    braking entry's stop, the velocity at ``coast`` beyond it."""
    tau = np.asarray(tau, dtype=np.float64)
    D = velocity_basis(model, hyper, np.minimum(np.minimum(tau, stop), coast))
    return D * (tau < stop)[..., None, None]


def predict_many(fits, tau, anchor=None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`predict` of many fits at once: means (T, K, 2) [m], covariances (T, K, 2, 2) [m²] at tau (T, K)
    ≥ 0 [s] after each fit's ``t_ref`` — one basis evaluation per library entry over all tracks.

    ``anchor`` (p (T, 2) [m], v (T, 2) [m/s], τ₀ (T,) [s]): each track's filtered position and velocity
    at τ₀ after ``t_ref`` (the forecast's origin, tau[:, k] = τ₀ + h_k). Each entry's path S(τ) then
    keeps its shape about its own tangent at τ₀ and takes the filter's position and velocity there
    (module docstring, anchored forecast):

        μ(τ₀ + h) = p + v h + S(τ₀ + h) − S(τ₀) − S′(τ₀) h                                       (3)

    — the CV entry forecasts exactly p + v h. An entry that brakes to a standstill (``line`` with a stop,
    β along û; ``turn_accel`` whose a₀ has a part β < 0 along v₀) reaches it when the filter's speed runs
    out, and stays there (Eq. 3 would carry on at the difference of the two velocities past the fit's
    stop, and a braking turn's basis would reverse):

        μ(τ₀ + h) = μ₃(τ₀ + h_e),  h_e = min(h, t*),  t* = max(−ûᵀv/β, 0) (line), |v|/|β| (turn)    (4)

    with μ₃ Eq. (3) on the entry's basis without its own stop (for ``line``: p + v h_e + û β h_e²/2). A
    track whose p is not finite keeps its fit's own path. The covariance stays the fit's."""
    tau = np.asarray(tau, dtype=np.float64)
    T, K = tau.shape
    mean, cov = np.zeros((T, K, 2)), np.zeros((T, K, 2, 2))
    if T == 0:
        return mean, cov
    buckets = {}
    for i, f in enumerate(fits):
        for j, e in enumerate(f.entries):
            buckets.setdefault(e.model, []).append((i, j, e))
    others = []                                                        # (track, weight, mean (K, 2))
    for m, sel in buckets.items():
        idx = np.array([i for i, _, _ in sel])
        hyper = np.array([e.hyper for *_, e in sel])
        stop = np.array([e.stop for *_, e in sel])
        coast = np.array([e.coast for *_, e in sel])
        B = forecast_basis(m, hyper, tau[idx], stop[:, None], coast[:, None])  # (E, K, 2, P)
        theta = np.array([e.theta for *_, e in sel])
        mu = np.einsum("ekcp,ep->ekc", B, theta)
        if anchor is not None:                                         # Eq. (3)
            p, v, t0 = (np.asarray(a, np.float64)[idx] for a in anchor)
            h = tau[idx] - t0[:, None]                                 # (E, K)
            B0 = forecast_basis(m, hyper, t0[:, None], stop[:, None], coast[:, None])[:, 0]  # (E, 2, P)
            D0 = forecast_velocity_basis(m, hyper, t0[:, None], stop[:, None], coast[:, None])[:, 0]
            s0, v0 = np.einsum("ecp,ep->ec", B0, theta), np.einsum("ecp,ep->ec", D0, theta)
            shift = (p - s0)[:, None, :] + (v - v0)[:, None, :] * h[..., None]
            mu = mu + np.where(np.isfinite(shift), shift, 0.0)
            if m in ("line", "turn_accel"):                            # braking: Eq. (4), its stop from v
                with np.errstate(divide="ignore", invalid="ignore"):
                    if m == "line":
                        u, beta = hyper[:, 3:5], theta[:, 4]
                        brakes = np.isfinite(stop)
                        t_star = np.maximum(-np.sum(u * v, axis=1) / beta, 0.0)
                    else:                                              # the tangential part of a₀ along v₀
                        beta = np.sum(theta[:, 4:6] * theta[:, 2:4], axis=1) / np.linalg.norm(theta[:, 2:4], axis=1)
                        brakes = beta < 0
                        t_star = np.linalg.norm(v, axis=1) / -beta
                brakes &= np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(v), axis=1)
                if brakes.any():
                    he = np.minimum(h, np.where(brakes, t_star, 0.0)[:, None])
                    Bu = basis(m, hyper, t0[:, None] + he)             # (E, K, 2, P), without the fit's own stop
                    B0u, D0u = basis(m, hyper, t0[:, None])[:, 0], velocity_basis(m, hyper, t0[:, None])[:, 0]
                    bend = (np.einsum("ekcp,ep->ekc", Bu, theta) - np.einsum("ecp,ep->ec", B0u, theta)[:, None]
                            - np.einsum("ecp,ep->ec", D0u, theta)[:, None] * he[..., None])
                    own = p[:, None, :] + v[:, None, :] * he[..., None] + bend
                    mu = np.where(brakes[:, None, None], own, mu)
        first = np.array([j == 0 for _, j, _ in sel])
        if first.any():
            covs = np.array([e.cov for (_, j, e) in sel if j == 0])
            Bf = B[first]
            cov[idx[first]] = np.einsum("ekip,epq,ekjq->ekij", Bf, covs, Bf)
            mean[idx[first]] = mu[first]
        others += [(i, _spread_weight(e.weight), mu[r]) for r, (i, j, e) in enumerate(sel) if j > 0]
    if others:                                                         # the selected entries' spread, Σ w d dᵀ
        i = np.array([o[0] for o in others])
        d = np.array([o[2] for o in others]) - mean[i]                 # (O, K, 2)
        w = np.array([o[1] for o in others])
        np.add.at(cov, i, w[:, None, None, None] * d[..., :, None] * d[..., None, :])
    return mean, cov
