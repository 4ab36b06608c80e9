"""The manoeuvre library's names, sizes, grids and limits, and the types of its results (:class:`Envelope`,
:class:`Entry`, :class:`LibraryFit`).

``LIBRARY`` names the entries (:mod:`estimators.trackers.library.bases` gives their equations);
``N_PARAMS`` counts each entry's parameters k_m with its grid parameters (the selection's degrees of
freedom, :mod:`estimators.trackers.library.selection`), ``N_LINEAR`` the linear ones P of θ and
``VECTORS`` where θ holds 2-vectors (p₀, v₀, a₀: they rotate with the track's frame). ω, τ_c, φ and τ_k
are grid parameters: ``OMEGA_GRID`` (step 0.01 rad/s), ``LANE_CENTRES`` × ``LANE_ANGLES`` (width
``LANE_SCALES``), ``KINK_TIMES``. ``CV_SURE``, ``CV_BENT`` and ``MIN_WEIGHT`` are BIC-weight
thresholds of a fit's forecast (:class:`LibraryFit`, :mod:`estimators.trackers.library.predict`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from xnlos_core.errors import InputError


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
        (``predict_many``'s ``anchor``, Eq. 3) rather than from the window fit's own
        (:mod:`estimators.trackers.library.predict`): a **lane change**, whose window fit gives the lateral
        offset's shape — how the lateral drift ends — but whose lane direction the window pins poorly (the
        second half of a lane change and the first half of an opposite one, about a slightly turned lane,
        fit a window alike), and a **CV** selection whose CV entry holds less than ``CV_BENT`` of the BIC
        weight: a manoeuvre fits the window clearly better without passing the test, so the window is no
        straight line and its least-squares velocity is the average over a bend, not the present one."""
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
