"""``dimensions`` = "auto": 2-D or 3-D propagation, decided from the scene in closed form.

What "the 3-D terms change the map" means (the metric the decision bounds and
``benchmarks/dimensions_auto.py`` measures by rendering both): the normalised L1 difference of the
noise-free RA power maps P = |A|² of one frame rendered in 3-D and in 2-D (same random phases),

    Δ = 10·log10(1 + Σ_c |P3_c − P2_c| / Σ_c P2_c)   [dB],                                   (D1)

over the cells c where P2_c or P3_c reaches the expected noise power of a cell
(:func:`xnlos_core.signal.chain.noise_floor`, SNR ≥ 0 dB). A uniform gain change of g dB on every
cell gives Δ = |g| for a gain and 10·log10(2 − 10^(−g/10)) ≈ |g| for a small loss. Threshold: the
forward model's ``tolerance_db`` (default 0.1 dB), the one every optional component's "auto" uses to
leave a term out: 0.1 dB is 2.3 % of a cell's power, so a detection decision changes only for a cell
within 0.1 dB of its threshold.

The estimate (no path, no rendering). A scatterer's response changes in 3-D in two ways: its power by
the factor G(d, h_t, θ) of :func:`sims.ground.power_factor` (two-ray interference over the ground,
elevation pattern and tilt), a closed form of its horizontal distance d, height h_t and azimuth θ;
and its peak moves, because a path arriving at elevation ε puts the phase y·sinθ·cos ε (+ z·sin ε)
on channel (y, z): the share S(θ, ε) of its power stays in its 2-D peak cell
(:func:`steering_keep`), the rest lands in the neighbours, and (D1) counts that power twice, once
lost, once gained. Per scatterer the L1 change is thus δ = |G − 1| + 2·G·(1 − S). The scene's
scatterers fall in classes of one height (classes of equal height merged): the static surfaces
(walls, meshes: strips at the radar's height h_r) and each object (its scattering centres at
``centre_height``, default min(h_r, height)). A class's range span is [d_min, max_range]: d_min the
plan distance from the radar to its nearest point (walls: the nearest point of any segment; objects:
the centre's distance at the frame's time less half a box's diagonal, a lower bound; meshes:
:data:`MESH_MIN_RANGE`), max_range the radar's (longer paths fall off the map; mirror paths
are longer than direct ones). The estimate is

    Ê = 10·log10(1 + max δ) over classes, d ∈ [d_min, max_range], θ ∈ [−fov, fov]   [dB],   (D2)

on a grid fine enough to resolve the two-ray lobes (phase steps ≤ π/6 in k(R_G − R_D), at most
:data:`MAX_GRID` points per class) and :data:`N_AZIMUTHS` azimuths; per class max δ is bounded by
max|G − 1| + 2·max G·max(1 − S), S on 64 distances (S falls as |ε| grows, towards d_min). Classes are
taken walls first, then objects; once one exceeds the tolerance the choice is 3-D and the rest are
not evaluated (``estimate_db`` is then that class's value, a lower bound of Ê). Ê bounds Δ where
each cell holds one scatterer, and in expectation over the random phases where several add: no
scatterer's response changes by more. So 2-D when Ê ≤ tolerance_db is safe; it is conservative
where a strongly changed scatterer carries little of the map's power (a low object among bright walls: 3-D is chosen though
Δ is smaller). Typical outcomes: no ground, no tilt, every centre at h_r → G = S = 1, 2-D; a ground
of |Γ| ≈ 1 (every real ground near grazing) → two-ray lobes and nulls, Ê ≈ 11 dB, 3-D; a ground of
|Γ| ≲ 0.005 → |G − 1| ≤ (1 + |Γ|)⁴ − 1 ≈ 2 %, 2-D.

Stable choice: the structural case (no ground, no tilt, every centre at h_r: the inputs, not a
computed float) is decided without a comparison; otherwise 3-D only when Ê exceeds tolerance_db by
more than :data:`DECISION_TOL_DB` — ties within it go to 2-D, the simpler model
(:mod:`xnlos_core.numerics`' rule), so a last-bit difference of Ê cannot flip the choice.
"""
from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from xnlos_core.radar import RadarConfig
from xnlos_core.signal.antenna import array_response, azimuth_weights, channel_positions

from .ground import centre_height, power_factor, sweep_wavelength

log = logging.getLogger(__name__)

#: Ties of Ê and tolerance_db within this [dB] go to 2-D (Ê rounds at ~1e-13 dB).
DECISION_TOL_DB = 1e-6
#: Nearest range [m] assumed for a scene's meshes (their geometry is not loaded to decide).
MESH_MIN_RANGE = 1.0
#: Nearest range [m] of any class (a scatterer nearer than this is taken at it).
MIN_RANGE = 0.1
#: Grid points per class and azimuth, at most (the lobes of a class nearer than ~1 m are not all resolved).
MAX_GRID = 4000
#: Azimuths [rad] per class: this many, evenly over the field of view.
N_AZIMUTHS = 3


@dataclasses.dataclass(frozen=True)
class DimensionsDecision:
    """The outcome of :func:`decide_dimensions`.

    use_3d: render in 3-D; reason: why, in words; estimate_db: Ê of (D2) [dB] (0 in the structural
    2-D case, NaN when switched); threshold_db: the tolerance it was compared with [dB].
    """

    use_3d: bool
    reason: str
    estimate_db: float
    threshold_db: float

    @property
    def label(self) -> str:
        """"3d: reason" or "2d: reason", as ``frame.meta["components"]["dimensions"]`` records it."""
        return ("3d: " if self.use_3d else "2d: ") + self.reason


def _segment_distance(seg) -> float:
    """Plan distance [m] from the radar (origin) to a wall segment."""
    a, b = np.asarray(seg.start, float), np.asarray(seg.end, float)
    ab = b - a
    t = float(np.clip(-(a @ ab) / max(float(ab @ ab), 1e-300), 0.0, 1.0))
    return float(np.hypot(*(a + t * ab)))


def scatterer_classes(scene, radar_height: float, timestamp: float = 0.0) -> list[tuple[str, float, float]]:
    """[(name, height h_t [m], nearest plan distance d_min [m])] of the scene's scatterer classes
    (module doc): "walls" (and meshes) at the radar's height, then one per object."""
    h_r = float(radar_height)
    out = []
    near = [_segment_distance(s) for s in scene.wall_segments()]
    if scene.meshes:
        near.append(MESH_MIN_RANGE)
    if near:
        out.append(("walls", h_r, min(near)))
    for obj in scene.objects:
        c = obj.center_at(timestamp)
        reach = 0.0 if obj.shape == "point" else 0.5 * math.hypot(*obj.size)  # a box's outline lies within it
        out.append((obj.name, float(centre_height(obj, h_r)), max(float(np.hypot(*c)) - reach, MIN_RANGE)))
    return out


def range_grid(d_min: float, d_max: float, h_t: float, radar: RadarConfig, radar_height: float,
               ground) -> np.ndarray:
    """Horizontal distances [m] from ``d_min`` to ``d_max`` (both included) where (D2) is evaluated:
    uniform in 1/d, the variable in which the two-ray phase k(R_G − R_D) ≈ 2k·h_r·h_t/d is linear, at
    ≤ π/6 per step with a ground (64 points without: G is then monotone in d)."""
    d_min = max(float(d_min), 1e-3)
    n = 64
    if ground is not None:
        k = 2 * math.pi / sweep_wavelength(radar)
        span = 2 * k * float(radar_height) * max(float(h_t), 1e-3) * (1 / d_min - 1 / d_max)
        n = int(min(MAX_GRID, max(64, math.ceil(span / (math.pi / 6)) + 1)))
    return 1.0 / np.linspace(1.0 / d_min, 1.0 / d_max, n)


def steering_keep(radar: RadarConfig, azimuth, elevation) -> np.ndarray:
    """S(θ, ε): the share of a scatterer's power at azimuth θ [rad] that stays in its 2-D peak cell
    when it arrives at elevation ε [rad] (board frame), ``radar``'s virtual array with its azimuth
    taper beamformed to θ: |Σ w_k a_k(θ, ε) a_k*(θ, 0)|² / |Σ w_k|² (shapes broadcast). The phase
    y·sinθ·cos ε + z·sin ε of channel (y, z) moves the peak to the azimuth of sinθ·cos ε (and channels
    at several heights add a phase slope); S = 1 at ε = 0."""
    th, el = np.broadcast_arrays(np.asarray(azimuth, dtype=np.float64), np.asarray(elevation, dtype=np.float64))
    pos, w = channel_positions(radar), azimuth_weights(radar)
    lam = radar.wavelength
    a = array_response(pos, lam, th.ravel(), el.ravel())
    a0 = array_response(pos, lam, th.ravel(), 0.0)
    return (np.abs(np.einsum("k,kp->p", w, a * a0.conj())) ** 2 / np.sum(w) ** 2).reshape(th.shape)


def _by_height(classes: list[tuple[str, float, float]]) -> list[tuple[str, float, float]]:
    """Classes of equal height merged (one G(d) each): names joined, the nearest d_min, first-seen order."""
    merged: dict[float, tuple[list[str], float]] = {}
    for name, h, d in classes:
        names, near = merged.get(h, ([], math.inf))
        merged[h] = (names + [name], min(near, d))
    return [(names[0] if len(names) == 1 else f"{names[0]} and {len(names) - 1} more", h, near)
            for h, (names, near) in merged.items()]


def decide_dimensions(scene, radar: RadarConfig, params, timestamp: float = 0.0) -> DimensionsDecision:
    """2-D or 3-D for ``scene`` at ``timestamp`` [s] under forward-model ``params``
    (:class:`sims.params.ForwardParams`: ``dimensions``, ``radar_height``, ``radar_tilt``,
    ``tolerance_db``) and ``radar`` (max_range, field of view, carrier, antenna): the module doc's
    rule, from the scene in closed form (about a millisecond; no path is found or rendered)."""
    switch, tol = params.dimensions, float(params.tolerance_db)
    if switch != "auto":
        return DimensionsDecision(switch == "3d", "switched on" if switch == "3d" else "switched off", math.nan, tol)
    out = _auto(scene, radar, float(params.radar_height), float(params.radar_tilt), tol, timestamp)
    log.debug("dimensions: %s (scene %r, t = %g s)", out.label, scene.name, timestamp)
    return out


def _auto(scene, radar: RadarConfig, h_r: float, tilt: float, tol: float, timestamp: float) -> DimensionsDecision:
    ground = scene.ground
    off = any(centre_height(o, h_r) != h_r for o in scene.objects)  # the inputs: no rounding decides
    if ground is None and tilt == 0.0 and not off:
        return DimensionsDecision(False, "no ground, no tilt, every scatterer at the radar's height", 0.0, tol)
    classes = _by_height(scatterer_classes(scene, h_r, timestamp))
    d_max = float(radar.max_range)
    az = np.linspace(-radar.field_of_view, radar.field_of_view, N_AZIMUTHS)
    worst, where = 0.0, None
    for name, h_t, d_min in classes:
        if d_min >= d_max:
            continue
        d = range_grid(d_min, d_max, h_t, radar, h_r, ground)
        g = power_factor(d[None, :], h_t, az[:, None], radar, h_r, tilt, ground)
        loss = 0.0  # max (1 − S): S falls with |ε|, so a coarse grid from d_min suffices
        if h_t != h_r or tilt != 0.0:  # else ε = 0 and S = 1
            coarse = np.geomspace(d_min, d_max, 64)
            keep = steering_keep(radar, az[:, None], np.arctan2(h_t - h_r, coarse)[None, :] - tilt)
            loss = max(float(np.max(1 - keep)), 0.0)
        dev = np.abs(g - 1)
        i = np.unravel_index(int(np.argmax(dev)), dev.shape)
        db = float(10 * np.log10(1 + dev[i] + 2 * float(np.max(g)) * loss))  # (D2), ≥ the pointwise maximum
        if where is None or db > worst:
            worst, where = db, (name, h_t, float(d[i[1]]))
        if worst > tol + DECISION_TOL_DB:
            break  # 3-D: the classes after this one cannot change the choice
    if where is None:
        return DimensionsDecision(False, f"no scatterer within {d_max:g} m", 0.0, tol)
    terms = [t for t, on in (("ground", ground is not None), (f"tilt {tilt:.3g} rad", tilt != 0.0),
                             ("scatterers off the radar's height", off)) if on]
    name, h_t, d = where
    why = (f"largest change of a scatterer's response {worst:.3g} dB ({name}, height {h_t:.3g} m, at {d:.3g} m; "
           f"{', '.join(terms)})")
    use = worst > tol + DECISION_TOL_DB
    return DimensionsDecision(use, f"{why} {'>' if use else '≤'} tolerance {tol:g} dB", worst, tol)
