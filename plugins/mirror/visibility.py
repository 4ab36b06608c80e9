"""Where a relay wall lets the radar see: the visibility gate for hidden points.

A hidden point o, reconstructed across wall Π from the virtual point o' (Eq. 7), was seen along
radar → q → o, where the bounce point q is the crossing of the ray radar → o' with the wall. A
specular reflection off a finite wall can put o only in some places:

1. **The wedge.** q lies on the part of the wall the estimator observed: ``WallPosterior.extent``
   lengthened by ``margin`` [m] at both ends (an arc: the ray's hit on the arc, its coordinate along
   the tangent line inside the extent's ± margin; a wall without extent is an unbounded line).
   By the mirror symmetry this is the same as o lying in the wedge that the wall segment subtends
   from the mirrored radar R_Π(0): the region the wall lets the radar see. The reconstructors take
   ``margin`` from their ``wedge_margin`` (else their anchoring ``extent_margin``): a bounce point past
   the last LOS point the wall showed is where the facade may have ended (a corner, a gap).
2. **In front of the mirror.** o lies on the radar's side of the wall (δ(o) has the sign of δ(0)),
   and o' beyond it (q between the radar and o'): a mirror shows what stands in front of it.
3. **Ahead of the radar.** o lies ahead of the radar's aperture (x ≥ ``ahead`` [m] in the radar
   frame, boresight +x), unless ``behind_radar`` is allowed. A wall can in principle show the
   radar what is behind it, but only a wall facing the radar across its boresight does, and the
   wall the estimator then returns is almost always a spurious fit near the radar that mirrors far
   echoes 10–20 m behind the vehicle (the tracks "behind the radar" of a run).

4. **Not a wall's own echo.** o' does not lie on an estimated wall (within ``wall_echo`` [m] of
   its line, inside its extent ± ``margin``) with a radial velocity consistent with rest
   (|v_r| ≤ max(``static_speed``, 3σ_v)), where the detections carry Doppler. Such an echo is the
   facade itself (or a pole on it), labelled mNLOS: mirrored through a far wall it lands among the
   road users, static, and pulls their tracks and velocities towards zero. A hidden road user seen
   through a wall is behind it, not on it, or it moves. Without Doppler the rule is not applied
   (a parked car beside a wall looks the same).
5. **One relay.** The ray radar → o' crosses no estimated wall but its own inside the seen extents
   (± ``margin``), when ``one_relay`` is asked for. In the plane the nearer of two crossed walls
   blocks the farther, so the anchoring takes the first crossing; but a short "wall" fitted to a
   stopped or broadside car (its LOS echoes at rest, 4–6 m long) does not block a facade it stands
   in front of, and one bounce cannot tell which of the two relayed the echo. On the sequence test
   split (oracle detections, benchmarks/doppler_detector.md) 438 of 460 such points mirrored
   through the nearer wall landed more than 2 m from every object; a farther wall would have put
   them right, yet no rule from the walls alone (length, support, σ_φ) picks it reliably. The point
   is ambiguous, and an ambiguous hidden point is not reported.

A point that fails any of them is a **ghost**: not reported as hidden, but counted (the frame's
``n_gated``, :attr:`xnlos_core.types.HiddenPoints.gated` lists the detections) and named in the
frame's notes with the rule it broke. :func:`visibility` returns the reason per point; the
reconstructors of :mod:`plugins.mirror` apply it (``gate``, ``behind_radar`` parameters).
"""
from __future__ import annotations

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.types import WallPosterior

from .association import crossing_parameters, signed_distances, wall_support

VISIBLE, OUTSIDE_WEDGE, BEHIND_WALL, BEHIND_RADAR, WALL_ECHO, TWO_RELAYS = 0, 1, 2, 3, 4, 5
REASONS = {OUTSIDE_WEDGE: "outside its wall's visibility wedge", BEHIND_WALL: "not in front of its wall",
           BEHIND_RADAR: "behind the radar", WALL_ECHO: "a static echo on a wall",
           TWO_RELAYS: "behind two seen walls (ambiguous relay)"}
STATIC_SIGMAS = 3.0  # a radial velocity within this many σ of 0 is consistent with rest


def visibility(hidden, virtual, walls: list[WallPosterior], wall_index, margin: float = 2.0,
               ahead: float | None = 0.0, velocity=None, velocity_var=None, wall_echo: float = 1.0,
               static_speed: float = 0.3, one_relay: bool = False) -> np.ndarray:
    """(M,) int reason code per hidden point (module doc): ``VISIBLE`` (0) or the first rule it breaks,
    ``OUTSIDE_WEDGE`` (1), ``BEHIND_WALL`` (2), ``BEHIND_RADAR`` (3), ``WALL_ECHO`` (4), ``TWO_RELAYS`` (5).

    hidden: (M, 2) hidden points o [m]; virtual: (M, 2) the virtual points o' [m] they were mirrored
    from; wall_index: (M,) the wall of each (index into ``walls``); margin [m] ≥ 0; ahead [m]: the
    least x of a hidden point (None: no such rule); velocity, velocity_var: (M,) the detections'
    radial velocity [m/s] and its variance [m²/s²], or None (no Doppler: rule 4 not applied);
    wall_echo [m]: how near a wall o' is on it; static_speed [m/s]: the least |v_r| that is motion
    whatever σ_v says; one_relay: apply rule 5 (another wall crossed inside its extent ± margin)."""
    o = np.asarray(hidden, dtype=np.float64).reshape(-1, 2)
    v = np.asarray(virtual, dtype=np.float64).reshape(-1, 2)
    j = np.asarray(wall_index, dtype=np.int64).reshape(-1)
    if not (len(o) == len(v) == len(j)):
        raise InputError(f"visibility: hidden {o.shape}, virtual {v.shape} and wall_index {j.shape} must have one "
                         "row per hidden point")
    if len(j) and (j.min() < 0 or j.max() >= len(walls)):
        raise InputError(f"visibility: wall_index must index the {len(walls)} wall(s), got {j.min()} … {j.max()}")
    if not margin >= 0:
        raise InputError(f"visibility: margin must be ≥ 0 m, got {margin}")
    reason = np.zeros(len(o), dtype=np.int64)
    crossings = np.isfinite(crossing_parameters(v, list(walls), margin))  # (M, J): rules 1 and 5
    for w in np.unique(j):
        m = np.flatnonzero(j == w)
        wall = [walls[w]]
        crossed = crossings[m, w]
        radar_side = np.sign(signed_distances(np.zeros((1, 2)), wall)[0, 0]) or 1.0
        in_front = signed_distances(o[m], wall)[:, 0] * radar_side > 0
        beyond = signed_distances(v[m], wall)[:, 0] * radar_side < 0
        reason[m] = np.where(~crossed, OUTSIDE_WEDGE, np.where(~(in_front & beyond), BEHIND_WALL, VISIBLE))
    if ahead is not None:
        reason = np.where((reason == VISIBLE) & ~(o[:, 0] >= ahead), BEHIND_RADAR, reason)
    if velocity is not None and len(o):
        vr = np.asarray(velocity, dtype=np.float64).reshape(-1)
        sd = np.sqrt(np.maximum(np.asarray(velocity_var, dtype=np.float64).reshape(-1), 0.0)) \
            if velocity_var is not None else np.zeros_like(vr)
        static = np.abs(vr) <= np.maximum(static_speed, STATIC_SIGMAS * sd)
        on_wall = np.zeros(len(o), dtype=bool)
        for idx in wall_support(v, list(walls), wall_echo, margin):
            on_wall[idx] = True
        reason = np.where((reason == VISIBLE) & static & on_wall, WALL_ECHO, reason)
    if one_relay:
        reason = np.where((reason == VISIBLE) & (np.count_nonzero(crossings, axis=1) > 1), TWO_RELAYS, reason)
    return reason


def describe_gated(reason: np.ndarray, source_index) -> str | None:
    """One line for a frame's notes naming the gated detections by rule, or None when none was gated."""
    reason, src = np.asarray(reason), np.asarray(source_index)
    parts = [f"{int(np.sum(reason == r))} {text} (detections {src[reason == r].tolist()})"
             for r, text in REASONS.items() if np.any(reason == r)]
    if not parts:
        return None
    return "visibility gate: ghost(s) not reported as hidden: " + "; ".join(parts)
