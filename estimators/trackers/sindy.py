"""Multi-target tracker ``sindy``: the Kalman tracker's association, birth and death (and Doppler
update), with each confirmed track's motion model identified over a manoeuvre library or by ensemble SINDy.

Identification ``library`` (the default): every track due in a frame (≥ ``min_samples`` in the window,
last fitted ``refit_every`` frames ago; all of them unless ``max_fits_per_frame`` caps them) is
identified at once by :func:`estimators.trackers.library.identify_batch` — straight, braking,
speeding up, reversing, turn (with or without a speed change), lane change, a settled speed change or
velocity step — selected by a likelihood-ratio test at ``selection_level`` against constant velocity
and then by BIC, from the positions and (with ``use_doppler`` and ``identify_doppler``) the radial
velocities of the track's updates (:mod:`estimators.trackers.library.doppler`; ``radial_share``, σ_r
floored at ``doppler_floor``). A manoeuvre whose evidence BIC(CV) − BIC(model) falls short of ``min_evidence``
(``braking_evidence`` for braking) is demoted to CV (:func:`estimators.trackers.library.demote`),
as in step 3 below. The track then forecasts from that fit (:func:`estimators.trackers.library.predict_many`,
plus ``accel_psd`` white acceleration noise from the fit's last sample) — started from the filter's
position and velocity, the fit's path kept about its tangent (Eqs. 3–4 there: the CV entry forecasts as
``kalman``), where ``library_origin`` says so ("doppler", the default: when the track has radial
velocities in its window, whose filter measures the velocity directly; the window fit's own level and
slope carry a reconstructed car's wandering centroid; and for a lane change or a CV fit whose window is
no straight line, :attr:`estimators.trackers.library.LibraryFit.local_origin`: the filter's line
then bends as the fitted lane change ends) — its disc radii scaled by
``interval_factors`` of its model (split-conformal, ``benchmarks/bicycle_forecasts.py --calibrate``);
its filter predicts with the fit's turn rate or matched speed change (:func:`library_motion`; CV for a
lane change, a reversal or a settled track); the reported ``model`` is the manoeuvre's name. Below
``min_speed`` a track's filter stays CV, and a turn or lane change fit is not followed (a heading is
unobservable there); a straight-line fit (braking, reversing through zero speed) still forecasts.
Identification ``ensemble``: steps 2–6 below.

Per frame, on top of :mod:`estimators.trackers.kalman`:
1. Every confirmed track keeps its history of (t, z, R, ĝ, y) — the measurements it was updated with —
   over the last ``window`` [s].
2. Identification (:func:`estimators.trackers.sindy_model.identify_motion`): once a track has
   ≥ ``min_samples`` samples in the window, and then every ``refit_every`` frames (not every frame:
   the time budget), its motion is identified from the window with the noise σ profiled out of the
   selection (identify_motion's sigma=None): a hidden point's R understates the scatter of a car's
   centroid (which parts of the body reflect changes), and a too-small σ inflates χ² until spurious
   turn terms pass any evidence margin. With ``use_doppler`` (and ``identify_doppler``) the history
   keeps each update's radial velocity y along ĝ too, and the identification fits them with the
   positions (sindy_model, Doppler): the radial velocity's ramp shows a deceleration that the
   centroid's wander hides. At most
   ``max_fits_per_frame`` tracks are fitted in one frame, the longest-unfitted first.
3. Model choice: the identified Ξ (turn / acceleration terms) replaces constant velocity only when it
   is not CV and its evidence BIC(CV) − BIC(Ξ) is ≥ ``min_evidence`` (10: "very strong" on the
   Kass–Raftery scale; the BIC alone — a margin of 0 — fits turns that are not there on noisy straight
   tracks; ``braking_evidence``, where set, is the bar of a model of braking alone — β < 0, no turn —
   a lower bar states higher prior odds for the manoeuvre a car approaching a junction often makes, and
   a braking model wrongly followed keeps the forecast on the track's line where a wrong turn leaves it),
   and when it lies in the road users' envelope: a speed-up β ≤ ``max_speedup`` (3 m/s²,
   ≈ 0.3 g, the upper range of everyday driving) and a lateral acceleration |ω|·|v| ≤ ``max_lateral``
   (5 m/s², ≈ 0.5 g: a brisk junction turn, 25 km/h on a 10 m radius; beyond it harsh cornering, and a
   synthetic car turning at 0.4 rad/s at 14 m/s lies outside). Braking is bounded by the
   identification's BETA_MAX, ≈ 1 g. Beyond the envelope a model
   is taken for an artefact of the track, not the road user's motion: a track still catching up with
   its car (its speed rising towards the car's) reads as a speed-up, a wrong relay's Doppler step as
   a sharp turn (``benchmarks/tracking_ablation.md``). Otherwise, and until the first fit,
   the track stays CV: it then behaves exactly as ``kalman``.
4. Invariant form. SINDy's library is the rotation-invariant (v̂, Jv) (sindy_model): a tangential
   acceleration β [m/s²] (braking < 0) and a turn rate ω [rad/s], whatever the road's direction. The
   filter and the forecast, linear in (p, v), take it at the track's speed s as Ξ = αI + ωJ with the α
   whose exponential speed change covers the same distance in ``MATCH_HORIZON`` (2 s) as β does, a stop
   included (:func:`matched_alpha`; β/s, the same acceleration at this instant, would overshoot a
   speed-up and undershoot a braking). Each identification, every ``refit_every`` frames, takes α afresh
   at the track's speed. The forecast clips α to [−``XI_MAX``, ``max_growth``] and ω to ±``XI_MAX`` (no
   exponential blow-up from a track that is nearly at rest, where Ξ is unconstrained); below
   ``min_speed`` the track stays CV.
5. With a model, the track's filter predicts with Φ(Δt) = expm(A(Ξ)Δt) (:mod:`estimators.trackers.forecast`)
   and the forecast is the mixture over M = ``n_models`` members Ξ_m: member m takes the refitted
   coefficients of the m-th bagging model's support (model uncertainty: which terms) plus one seeded
   draw from their refit covariance (coefficient uncertainty). Reported ``model``: the terms, e.g.
   "vx'=vy vy'=vx" (a turn), "vx'=vx vy'=vy" (braking or speeding up along the path), or "cv".
6. Forecast covariance of the true centre (:mod:`estimators.trackers.forecast`, Eq. 1): a track with a
   model forecasts with the process noise ``model_accel_psd`` (a model that explains the manoeuvre
   leaves less unexplained acceleration than CV's ``accel_psd``) and the members' spread scaled by
   ``member_spread``; the filter itself keeps ``accel_psd`` (so that association survives a model that
   stops fitting until the next identification). A CV track forecasts exactly as ``kalman``. The
   defaults are calibrated on synthetic straight, turning and braking cars by
   ``benchmarks/forecast_calibration.py``.

Timestamps must increase strictly: a repeated timestamp (Δt = 0) is an InputError here — the
identification needs distinct sample times — where ``kalman`` takes it as a second measurement.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from pydantic import Field

from xnlos_core.errors import InputError, InsufficientDataError

from . import forecast as fc
from .kalman import CV, KalmanParams, KalmanTracker, Scale, KalmanTrack
from .measurements import Measurements
from estimators.state import StateReader
from .library import Envelope, LibraryFit, demote, identify_batch, predict_many
from .sindy_model import GENERATORS, MIN_SAMPLES, XI_MAX, MotionModel, identify_motion

MODEL_ACCEL_PSD = 4.0  # [m²/s³] calibrated defaults (benchmarks/forecast_calibration.py)
MEMBER_SPREAD = 0.0
MAX_SPEEDUP = 3.0  # [m/s²] ≈ 0.3 g: the upper range of everyday driving's acceleration (module docstring, 3)
MAX_LATERAL = 5.0  # [m/s²] ≈ 0.5 g: a brisk junction turn; beyond it, harsh cornering
# Per-model disc factors of library forecasts: split-conformal on the calibration split (seed 1, 20 cars per class,
# the manoeuvring cars during their manoeuvre; `benchmarks/bicycle_forecasts.py --calibrate --per-class 20`:
# cv 2.69 of 63 forecasts, cv_uncertain 1.99 of 68, accelerate 0.88 of 138, brake 1.62 of 129, turn 1.28 of 129,
# lane_change 2.12 of 50, settled 3.19 of 52). reverse (5 forecasts) had fewer than the 9 a 90 % split-conformal
# quantile needs: it takes the largest of the others. cv_uncertain and lane_change recalibrated with lane changes
# and bent-window CV fits forecast from the filter's state (LibraryFit.local_origin): cv_uncertain 2.37 of 127,
# lane_change 2.09 of 23 (the same run: accelerate 0.72, brake 1.47, turn 1.14, settled 3.30, left as they were).
INTERVAL_FACTORS = {"cv": 2.69, "cv_uncertain": 2.37, "brake": 1.62, "accelerate": 0.88, "reverse": 3.19, "turn": 1.28,
                    "lane_change": 2.09, "settled": 3.19}


class SindyParams(KalmanParams):
    min_samples: int = Field(8, ge=MIN_SAMPLES, le=10_000, description="measurements a track needs within "
                                                                       "the window before its motion is identified "
                                                                       "(8 and refit_every 2: chosen on the val split of "
                                                                       "the sequence data, see configs/ablations/tracking.toml)")
    window: float = Field(3.0, gt=0, le=60, description="length [s] of the history identified from")
    refit_every: int = Field(2, ge=1, le=10_000, description="frames between two identifications of a track")
    max_fits_per_frame: int | None = Field(None, ge=1, le=100_000, description="identifications at most per "
                                           "frame (the longest-unfitted due tracks first); None: every due track, "
                                           "so each is refitted every refit_every frames however many there are")
    identification: Literal["library", "ensemble"] = Field("library", description="'library': every due track "
                                                           "identified at once over the manoeuvre library (straight, "
                                                           "braking, speeding up, reversing, turn, lane change; "
                                                           "trackers/library/) by a likelihood-ratio test at "
                                                           "selection_level, from the positions and radial velocities; "
                                                           "'ensemble': one "
                                                           "track at a time by ensemble SINDy (sindy_model.py)")
    max_fit_age: float = Field(0.5, gt=0, le=60, description="a library fit forecasts the track for this long [s] "
                                                           "after its last sample; an older one (fits capped by "
                                                           "max_fits_per_frame, missed frames) forecasts through the "
                                                           "filter's state with the fit's turn rate or speed change")
    library_origin: Literal["fit", "filter", "doppler"] = Field("doppler", description="where a library fit's "
                                                              "forecast starts: 'fit' its own position and velocity "
                                                              "at the forecast's origin, 'filter' the Kalman state's "
                                                              "(the fit's path kept about its tangent, "
                                                              "library.predict_many Eq. 3: the CV entry then "
                                                              "forecasts as kalman), 'doppler' the filter's when the "
                                                              "track has radial velocities in its window or the fit "
                                                              "asks for it (a lane change, a CV fit of a bent window: "
                                                              "library.LibraryFit.local_origin), else the fit's")
    selection_level: float = Field(0.01, gt=0, lt=1, description="level α of the library's likelihood-ratio test "
                                                                 "against constant velocity (Bonferroni over the "
                                                                 "alternatives): a straight track is given a manoeuvre "
                                                                 "model with probability ≈ α")
    interval_factors: dict[Literal["cv", "cv_uncertain", "brake", "accelerate", "reverse", "turn", "lane_change",
                                 "settled"],
                           Scale] = Field(
        default_factory=lambda: dict(INTERVAL_FACTORS), description="factor on the 50 % and 90 % disc radii of a "
        "library-identified track by its model ('cv_uncertain': CV selected with less than half the BIC weight, "
        "library.LibraryFit.interval_key): split-conformal factors learned on a calibration split of "
        "kinematic-bicycle tracks (benchmarks/bicycle_forecasts.py --calibrate); a model missing here: 1")
    n_models: int = Field(5, ge=2, le=200, description="bagging ensemble size (members of the forecast mixture); "
                                                        "5: as well calibrated as 10 by benchmarks/forecast_calibration.py, "
                                                        "and cheaper to identify")
    identify_doppler: bool = Field(True, description="with use_doppler, the identification fits the track's "
                                                     "radial velocities too (sindy_model and library.doppler, "
                                                     "Doppler)")
    radial_share: Literal["ar1", "full"] = Field("ar1", description="how many independent samples the radial "
                                                  "residuals count in the identification's evidence: 'ar1' from "
                                                  "their lag-1 autocorrelation, 'full' all (sindy_model, Doppler: "
                                                  "'full' finds braking sooner; with one row per cluster it also "
                                                  "finds turns in rows that mix two relay walls, so pair it with "
                                                  "doppler_rows 'wall')")
    screen_radial: bool = Field(False, description="the identification first leaves out the radial velocities "
                                                   "that the richest model, refitted without each, misses by more "
                                                   "than 5 robust SDs (at most 10 % of them: a wrong relay wall's "
                                                   "rows; sindy_model._screen_radial)")
    min_evidence: float = Field(10.0, ge=0, le=1e6, description="BIC(CV) − BIC(model) an identified model "
                                                                "needs to replace constant velocity (either "
                                                                "identification: a library fit short of it is "
                                                                "demoted to CV)")
    braking_evidence: float | None = Field(None, ge=0, le=1e6, description="BIC(CV) − BIC(model) a model of braking "
                                                                         "alone (β < 0, no turn) needs; None: min_evidence "
                                                                         "(module docstring, 3)")
    min_speed: float = Field(0.5, ge=0, le=100, description="speed [m/s] below which a track stays constant "
                                                            "velocity (its turn and acceleration are unobservable)")
    max_growth: float = Field(0.5, ge=0, le=XI_MAX, description="largest tangential growth rate α [1/s] "
                                                               "(speeding up) a forecast uses")
    max_speedup: float = Field(MAX_SPEEDUP, gt=0, le=100, description="largest acceleration along the path β [m/s²] "
                                                                      "of a model the track may follow (module "
                                                                      "docstring, 3: the road users' envelope)")
    max_lateral: float = Field(MAX_LATERAL, gt=0, le=100, description="largest lateral acceleration |ω|·|v| [m/s²] of "
                                                                      "a model the track may follow (module docstring, 3)")
    model_accel_psd: float = Field(MODEL_ACCEL_PSD, gt=0, le=1e4,
                                   description="process-noise PSD q [m²/s³] of the forecast (and arrival draws) of a "
                                               "track that follows an identified model; the default is calibrated "
                                               "by benchmarks/forecast_calibration.py")
    model_interval_scale: tuple[Scale, Scale] = Field((1.0, 1.0), description="interval_scale of a track that "
                                                      "follows an identified model (calibrated apart from the CV "
                                                      "tracks' by benchmarks/interval_calibration.py)")
    member_spread: float = Field(MEMBER_SPREAD, ge=0, le=100,
                                 description="scale s of the ensemble members' spread in the forecast covariance "
                                             "(forecast.py Eq. 1; 1: the plain mixture moment match); calibrated "
                                             "by benchmarks/forecast_calibration.py")


@dataclass
class _SindyTrack(KalmanTrack):
    history: list = field(default_factory=list)   # [(t [s], z (2,) [m], R (2, 2) [m²], ĝ (2,), y [m/s] or NaN)]
    motion: fc.LinearMotion = field(default_factory=lambda: CV)
    fitted_frame: int = -1                         # tracker frame of the last identification (−1: none)
    identified: MotionModel | None = None
    library: LibraryFit | None = None              # the library identification (identification "library")


def bounded(coef, max_growth: float) -> np.ndarray:
    """Ξ' = αI + ωJ (…, 2, 2) [1/s] of the coefficients (α, ω) (…, 2), α clipped to [−XI_MAX,
    max_growth] and ω to ±XI_MAX (module docstring, 4)."""
    c = np.asarray(coef, dtype=np.float64)
    alpha = np.clip(c[..., 0], -XI_MAX, max_growth)
    omega = np.clip(c[..., 1], -XI_MAX, XI_MAX)
    return alpha[..., None, None] * GENERATORS[0] + omega[..., None, None] * GENERATORS[1]


MATCH_HORIZON = 2.0  # [s] the horizon at which the linear form's path matches the identified one


def matched_alpha(beta, speed: float, horizon: float = MATCH_HORIZON) -> np.ndarray:
    """α [1/s] (…) of the exponential speed change dv/dt = αv that covers, from ``speed`` [m/s], the
    distance the constant tangential acceleration ``beta`` [m/s²] (…) covers in ``horizon`` [s]:
    s(e^{αH} − 1)/α = sH + βH²/2, or s²/(2|β|) when the car stops before H (module docstring, 4).

    The filter and forecast are linear in (p, v), so an identified β enters them as α; β/s (the same
    acceleration at this instant) overshoots a speed-up (exponential growth against linear) and
    undershoots a braking (an exponential never stops) — by a factor e/2 in speed over 2 s at
    αH = 1. Matched, the 2 s forecast of a straight path follows the identified model exactly; α is
    kept within ±XI_MAX."""
    from scipy.optimize import brentq

    b = np.asarray(beta, dtype=np.float64)
    out = np.zeros(b.shape)
    s = max(float(speed), 1e-9)
    for idx, bi in np.ndenumerate(b):
        if bi == 0.0:
            continue
        dist = s * horizon + bi * horizon ** 2 / 2 if bi > 0 or s + bi * horizon > 0 else s ** 2 / (2 * -bi)
        ratio = dist / (s * horizon)                                        # (e^x − 1)/x with x = αH

        def f(x, r=ratio):
            return np.expm1(x) / x - r if x != 0 else 1.0 - r

        lo, hi = -XI_MAX * horizon, XI_MAX * horizon
        out[idx] = (lo if f(lo) > 0 else hi if f(hi) < 0 else brentq(f, lo, hi, xtol=1e-10)) / horizon
    return out


def within_envelope(rates, speed: float, p: "SindyParams") -> bool:
    """Whether the rates (β [m/s²], ω [rad/s]) at ``speed`` [m/s] lie in the road users' envelope:
    β ≤ ``max_speedup`` and |ω|·speed ≤ ``max_lateral`` (module docstring, 3)."""
    beta, omega = (float(r) for r in rates)
    return beta <= p.max_speedup and abs(omega) * speed <= p.max_lateral


def evidence_bar(rates, p: "SindyParams") -> float:
    """The evidence BIC(CV) − BIC(model) a model of rates (β [m/s²], ω [rad/s]) needs to be followed:
    ``braking_evidence`` for braking alone (β < 0, ω = 0) where set, ``min_evidence`` otherwise."""
    beta, omega = (float(r) for r in rates)
    return p.braking_evidence if p.braking_evidence is not None and beta < 0 and omega == 0 else p.min_evidence


def motion_from(model: MotionModel, v, seed, p: "SindyParams") -> fc.LinearMotion:
    """The forecast model of an identification at the track's velocity v (2,) [m/s] (module docstring,
    3–5): CV unless supported."""
    terms = model.terms()
    v = np.asarray(v, dtype=np.float64)
    if not terms or model.evidence < evidence_bar(model.rates, p) or np.linalg.norm(v) < max(p.min_speed, 1e-9):
        return CV
    if not within_envelope(model.rates, float(np.linalg.norm(v)), p):
        return CV
    rng = np.random.default_rng(seed)
    members = np.zeros((len(model.fits), len(GENERATORS)))  # (β, ω) of each member
    for m, (mask, theta, cov) in enumerate(model.fits):
        if mask.any():
            lam, vec = np.linalg.eigh(cov[4:, 4:])  # a pseudo-inverse covariance: PSD, maybe singular
            members[m, mask] = theta[4:] + vec @ (np.sqrt(np.clip(lam, 0, None)) * rng.standard_normal(len(lam)))
    speed = float(np.linalg.norm(v))
    point = np.r_[matched_alpha(model.rates[0], speed), model.rates[1]]
    members[:, 0] = matched_alpha(members[:, 0], speed)
    return fc.LinearMotion(bounded(point, p.max_growth), bounded(members, p.max_growth), " ".join(terms))


def library_motion(fit: LibraryFit, speed: float, p: "SindyParams") -> fc.LinearMotion:
    """The linear filter's motion of a library fit at ``speed`` [m/s]: a turn ωJ (+ matched α of a speed
    change), braking or speeding up as the matched α (module docstring, 4); CV for the rest (a lane
    change or a reversal, whose forecast comes from the fit itself)."""
    if fit.label not in ("turn", "brake", "accelerate"):
        return CV
    point = bounded(np.r_[matched_alpha(fit.rates[0], speed), fit.rates[1]], p.max_growth)
    return fc.LinearMotion(point, point[None], fit.label)


def _legacy(identified) -> bool:
    """Whether a checkpoint's identified model comes from an earlier library — the world-frame one
    (support masks (2, 2)) or the exponential speed change dv/dt = αv (no ``rates``): it is dropped on
    load (the track keeps its forecast model, and is identified afresh at its next refit)."""
    if isinstance(identified, dict) and "rates" not in identified:
        return True
    fits = identified.get("fits") if isinstance(identified, dict) else None
    mask = fits[0].get("mask") if isinstance(fits, list) and fits and isinstance(fits[0], dict) else None
    return isinstance(mask, list) and len(mask) == 2 and all(isinstance(row, list) and len(row) == 2 for row in mask)


class SindyTracker(KalmanTracker):
    """Kalman association/birth/death with per-track motion models identified by ensemble SINDy.

    Its checkpoint (:meth:`KalmanTracker.state`) adds per track the history window, the forecast
    model (Ξ, members, label: what the filter and the forecast use, so nothing is re-identified on a
    resume), the frame of the last identification and the identified :class:`MotionModel` itself."""

    Params = SindyParams

    def _frame_time(self, points, timestamp) -> float:
        t = super()._frame_time(points, timestamp)
        if self._t_last is not None and t == self._t_last:
            raise InputError(f"SindyTracker.update: timestamp {t} s repeats the previous frame's; timestamps "
                             "must increase strictly (Δt > 0) for the motion identification")
        return t

    def _track_state(self, tr: _SindyTrack) -> dict:
        m, ident = tr.motion, tr.identified
        out = {**super()._track_state(tr), "fitted_frame": tr.fitted_frame,
               "history": [[float(t), z.tolist(), R.tolist(), g.tolist(), None if np.isnan(y) else float(y)]
                           for t, z, R, g, y in tr.history],
               "motion": {"xi": m.xi.tolist(), "members": m.members.tolist(), "label": m.label}, "identified": None}
        if ident is not None:
            out["identified"] = {"coefficients": ident.coefficients.tolist(), "ensemble": ident.ensemble.tolist(),
                                 "fits": [{"mask": mask.tolist(), "theta": theta.tolist(), "cov": cov.tolist()}
                                          for mask, theta, cov in ident.fits],
                                 "t_last": float(ident.t_last), "sigma": float(ident.sigma),
                                 "evidence": float(ident.evidence), "rates": ident.rates.tolist()}
        out["library"] = None if tr.library is None else tr.library.to_dict()
        return out

    def _track_from(self, r: StateReader) -> _SindyTrack:
        base = super()._track_from(r)
        history = []
        for i, h in enumerate(r.items("history")):
            if not isinstance(h, list) or len(h) not in (3, 5):
                raise InputError(f"{r.where}: history[{i}] must be [t, z (2,), R (2, 2)] or [t, z, R, ĝ (2,), y or "
                                 "null]")
            e = StateReader(dict(zip(("t", "z", "R", "g", "y"), h)), f"{r.where}: history[{i}]")
            g, y = (e.array("g", (2,)), np.nan if h[4] is None else e.number("y")) if len(h) == 5 else (np.zeros(2), np.nan)
            history.append((e.number("t"), e.array("z", (2,)), e.array("R", (2, 2)), g, y))
        m = r.sub("motion")
        motion = fc.LinearMotion(m.array("xi", (2, 2)), m.array("members", (None, 2, 2)), m.text("label"))
        identified = None
        if r.data.get("identified") is not None and not _legacy(r.data["identified"]):
            d = r.sub("identified")
            fits = []
            for i, f in enumerate(d.items("fits")):
                e = StateReader(f, f"{d.where}: fits[{i}]")
                mask = e.array("mask", (len(GENERATORS),), dtype=bool)
                theta = e.array("theta", (4 + int(mask.sum()),))
                fits.append((mask, theta, e.array("cov", (len(theta), len(theta)))))
            identified = MotionModel(d.array("coefficients", (2, 2)), d.array("ensemble", (None, 2, 2)), tuple(fits),
                                     d.number("t_last"), d.number("sigma"), d.number("evidence"),
                                     d.array("rates", (len(GENERATORS),)))
        library = None
        if r.data.get("library") is not None:
            library = LibraryFit.from_reader(r.sub("library"))
        return _SindyTrack(base.id, base.x, base.P, base.t, base.frames, base.hits, base.misses, base.confirmed,
                           history=history, motion=motion, fitted_frame=r.integer("fitted_frame", -1),
                           identified=identified, library=library)

    def _new_track(self, track_id, x, P, t) -> _SindyTrack:
        return _SindyTrack(track_id, x, P, t, history=[(t, x[:2].copy(), P[:2, :2].copy(), np.zeros(2), np.nan)])

    def _correct(self, tr: _SindyTrack, meas: Measurements, k: int) -> None:
        super()._correct(tr, meas, k)
        y = float(meas.y[k]) if meas.doppler[k] else np.nan
        tr.history.append((tr.t, meas.z[k].copy(), meas.R[k].copy(), meas.g[k].copy(), y))

    def _motion(self, tr: _SindyTrack) -> fc.LinearMotion:
        return tr.motion

    def _forecast_psd(self, tr: _SindyTrack) -> float:
        return self.params.accel_psd if tr.motion.is_cv else self.params.model_accel_psd

    def _fresh(self, tr: _SindyTrack) -> bool:
        """Whether ``tr`` forecasts from its library fit: it has one, at most ``max_fit_age`` old."""
        return tr.library is not None and tr.t - tr.library.t_ref <= self.params.max_fit_age + 1e-9

    def _anchored(self, tr: _SindyTrack) -> bool:
        """Whether ``tr``'s library forecast starts from the filter's state (``library_origin``)."""
        origin = self.params.library_origin
        return origin == "filter" or (origin == "doppler" and (tr.library.local_origin
                                                              or any(np.isfinite(h[4]) for h in tr.history)))

    def _interval_scale(self, tr: _SindyTrack) -> tuple[float, float]:
        if self._fresh(tr):
            f = self.params.interval_factors.get(tr.library.interval_key, 1.0)
            return f, f
        return self.params.interval_scale if tr.motion.is_cv else self.params.model_interval_scale

    def _forecast(self, tr: _SindyTrack, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A library-identified track forecasts from its fit (library.predict) at τ = t − t_ref + h,
        with the white-acceleration noise of ``accel_psd`` over τ added; any other as ``kalman``."""
        if not self._fresh(tr):
            return super()._forecast(tr, h)
        mean, cov = self._forecasts([tr], h)[0]
        return mean, cov

    def _forecasts(self, trs: list, h: np.ndarray) -> list:
        """The library-identified tracks' forecasts in one batch (library.predict_many), the others
        as ``kalman``'s (:meth:`_forecast`)."""
        lib = [i for i, tr in enumerate(trs) if self._fresh(tr)]
        out = [None if self._fresh(tr) else super(SindyTracker, self)._forecast(tr, h) for tr in trs]
        if lib:
            t0 = np.array([trs[i].t - trs[i].library.t_ref for i in lib])
            tau = t0[:, None] + np.asarray(h, np.float64)[None]
            anchored = [self._anchored(trs[i]) for i in lib]
            anchor = None
            if any(anchored):  # the filter's state where anchored, NaN (the fit's own) elsewhere
                nan = np.full(4, np.nan)
                x = np.array([trs[i].x[:4] if a else nan for i, a in zip(lib, anchored)])
                anchor = (x[:, :2], x[:, 2:], t0)
            mean, cov = predict_many([trs[i].library for i in lib], tau, anchor)
            cov = cov + fc.cv_process_noise(tau, self.params.accel_psd)[..., :2, :2]
            for r, i in enumerate(lib):
                out[i] = (mean[r], cov[r])
        return out

    def _label(self, tr: _SindyTrack) -> str:
        return tr.library.label if self._fresh(tr) else tr.motion.label

    def _spread(self, tr: _SindyTrack) -> float:
        return self.params.member_spread

    def _after_update(self, t: float) -> None:
        p = self.params
        due = []
        for tr in self._tracks:
            while tr.history and tr.history[0][0] < t - p.window:
                tr.history.pop(0)
            stale = self._frame - tr.fitted_frame
            ready = tr.confirmed and not self._lost(tr) and len(tr.history) >= p.min_samples
            if ready and (tr.fitted_frame < 0 or stale >= p.refit_every):
                due.append((-stale if tr.fitted_frame >= 0 else -np.inf, tr.id, tr))
        due = [tr for *_, tr in sorted(due, key=lambda d: (d[0], d[1]))[:p.max_fits_per_frame]]
        if p.identification == "library":
            self._identify_library(due)
            return
        for tr in due:
            self._identify(tr)

    def _identify_library(self, due: list) -> None:
        """Every due track identified at once over the manoeuvre library (library.identify_batch)."""
        if not due:
            return
        p = self.params
        doppler = p.use_doppler and p.identify_doppler
        fits = identify_batch([(np.array([h[0] for h in tr.history]), np.array([h[1] for h in tr.history]))
                               + ((np.array([h[3] for h in tr.history]), np.array([h[4] for h in tr.history]))
                                  if doppler else ()) for tr in due],
                              p.selection_level, Envelope(p.max_speedup, p.max_lateral), p.radial_share,
                              p.doppler_floor)
        for tr, fit in zip(due, fits):
            tr.fitted_frame, tr.identified = self._frame, None
            speed = float(np.linalg.norm(tr.x[2:]))
            if speed < p.min_speed and fit.label in ("turn", "lane_change"):  # a heading's turn is unobservable
                tr.library, tr.motion = None, CV
                continue
            if fit.label != "cv" and fit.evidence < evidence_bar(fit.rates, p) - 1e-9:
                fit = demote(fit)                                      # short of the evidence bar: CV
            tr.library = fit
            tr.motion = library_motion(fit, speed, p)

    def _identify(self, tr: _SindyTrack) -> None:
        p = self.params
        ts = np.array([h[0] for h in tr.history])
        zs = np.array([h[1] for h in tr.history])
        doppler = {}
        if p.use_doppler and p.identify_doppler:
            doppler = {"direction": np.array([h[3] for h in tr.history]), "radial": np.array([h[4] for h in tr.history])}
        tr.fitted_frame = self._frame
        try:
            model = identify_motion(ts, zs, None, n_models=p.n_models, seed=p.seed + tr.id,
                                    radial_share=p.radial_share, screen_radial=p.screen_radial, **doppler)
        except InsufficientDataError:  # e.g. an axis-aligned noiseless path: nothing to identify
            tr.identified, tr.motion = None, CV
            return
        tr.identified = model
        tr.motion = motion_from(model, tr.x[2:], [p.seed, tr.id, self._frame], p)
