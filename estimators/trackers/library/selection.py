"""Selection among the library's entries (the sparsest model that the data demand), the entries'
labels, and the demotion to CV.

Correlated errors count n_eff/n = (1 − ρ)/(1 + ρ) of their samples (ρ ≥ 0 the lag-1 autocorrelation of
the best-fitting entry's residuals; as in :mod:`estimators.trackers.sindy_model`). An entry m with k_m
parameters (its grid parameters included) replaces CV only when its profile likelihood-ratio statistic

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

With Doppler rows (:mod:`estimators.trackers.library.doppler`) the selection adds the radial terms with
their own variance profiled out, f_r the share of independent radial residuals (``radial_share``:
"ar1" from their lag-1 autocorrelation over adjacent samples, "full" 1, as in sindy_model):

    D_m = f N ln(RSS_cv/RSS_m) + f_r m ln(RSS_r,cv/RSS_r,m),
    BIC_m = f N ln(RSS_m/N) + f_r m ln(RSS_r,m/m) + k_m ln(f N + f_r m)                        (2)

(RSS_r the radial residuals' sum of squares [m²/s²], m their number), and Σ_θ = σ² (AᵀA)⁻¹/f of the
weighted design A with σ² = (RSS + λ² RSS_r)/(N + m − k).
"""
from __future__ import annotations

import math

import numpy as np

from xnlos_core.numerics import simplest_within

from .bases import hyper_grid
from .entries import (BETA_MAX, LANE_MAX, LIBRARY, MIN_WEIGHT, N_LINEAR, TURN_OVER_LANE, VECTORS, Entry, Envelope,
                      LibraryFit)


def criteria(fits: dict, z: np.ndarray, k: np.ndarray, radial: dict | None = None, radial_share: str = "ar1") -> tuple:
    """Per track of a group (z (T, L, 2) its local positions) and entry: f (T,), the statistic D of
    Eq. (1), BIC and σ² (T, M+1) — the selection's arithmetic for all tracks at once; with ``radial``
    (from :func:`fit_doppler`) the radial terms of Eq. (2) added."""
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


def select_fit(fits: dict, row: int, track, k: np.ndarray, thresholds: np.ndarray, env: Envelope, crit) -> LibraryFit:
    """One track's selection and entries (module docstring) from its group's fits and its
    row of :func:`criteria`."""
    t_ref, centre, u, tau, zl, _ = track
    f, stat, bic, sigma2 = crit
    f = float(f)
    local = [(m, hyper_grid(m)[fits[m][0][row]], fits[m][1][row], fits[m][3][row]) for m in LIBRARY]
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
    # (CV always kept, for :func:`demote`; below MIN_WEIGHT it leaves the mixture: predict.predict_many)
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
    """(label, stop τ [s] or inf, rates (β, ω), inside the envelope) of a fitted entry (the labels:
    :mod:`estimators.trackers.library.bases`); sigma [m] the entry's residual SD: a reversal must have run
    back farther than 2σ since its turning point, else the window shows a car that stopped there (it
    stays)."""
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


def _rotation(model: str, rot: np.ndarray) -> np.ndarray:
    """R (P, P) taking θ from a track's own frame (û = +x, n = +y) to the world: each 2-vector of θ
    (p₀, v₀, a₀) rotates by ``rot`` (2, 2) = [û, Jû], the scalars (β, A) stay."""
    R = np.eye(N_LINEAR[model])
    for j in VECTORS[model]:
        R[j:j + 2, j:j + 2] = rot
    return R


def demote(fit: LibraryFit) -> LibraryFit:
    """``fit`` with its CV entry selected (label ``cv``, no rates; the other entries stay for the
    mixture's spread): a manoeuvre whose evidence falls short of the caller's bar (the tracker's
    ``min_evidence``)."""
    cv = next(e for e in fit.entries if e.model == "cv")
    rest = tuple(e for e in fit.entries if e is not cv)
    return LibraryFit("cv", fit.t_ref, (cv,) + rest, fit.sigma, 0.0, np.zeros(2), 0.0)
