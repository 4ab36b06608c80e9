"""Diffuse NLOS paths: radar → rough relay wall (diffuse) → hidden object → wall (diffuse) → radar.

The mirror (mNLOS) path of a rough relay wall keeps only the coherent part of the reflection,
ρ_s·|Γ|² in power with ρ_s = exp(−(4πσ_h cosθ/λ)²) (:mod:`sims.roughness`); the remainder
F = (1 − ρ_s)|Γ|² leaves the wall in the diffuse lobe. At 77 GHz a facade with σ_h ≈ 1 mm is
almost entirely diffuse (ρ_s(0) ≈ 3·10⁻⁵), at 10 GHz almost a mirror (ρ_s(0) ≈ 0.84) (paper
Sec. 1, Fig. 2b). The diffuse power still reaches hidden objects by the three-bounce path that
optical (SPAD) NLOS imaging uses; this module gives its power and, in :func:`wall_paths`, the paths of
one wall with an importance cut, for both radar forward models (each supplies its own visibility). Wall patches a (out) and b (back)
are cells of length Δs and the wall's height h (area dA = Δs·h, as the LOS wall cells), the object
a scattering centre of RCS σ_o:

    P = P_t·G_tx(θ_a)·G_e(θ_a)·G_e(θ_b)·λ²·σ_o·(σ⁰_a dA)(σ⁰_b dA) / ((4π)⁵·r_a²·d_ao²·d_ob²·r_b²·L_sys)

(radar equation with each diffuse patch as a bistatic scatterer σ⁰·dA: σ⁰_a from the radar towards
the object, σ⁰_b from the object towards the radar, :func:`sims.walls.bistatic_sigma0`). Round trip
r_a + d_ao + d_ob + r_b, arrival from θ_b. Every pair (a, b) is a path (a ≠ b included: the echo
leaves the object by any patch), with phase φ_a + φ_o + φ_b from the per-cell and per-centre
random phases.

Energy: σ⁰ integrates to F over the hemisphere (∫ σ⁰/(4π cosθ_i) dΩ = F), so specular plus
diffuse never exceed the incident power: ρ_s|Γ|² + F = |Γ|² ≤ 1 (tests/unit/test_diffuse_nlos.py).

"auto" switches the path on when a relay wall with a material is mostly diffuse at the carrier,
ρ_s(θ = 0) < 1/2, i.e. σ_h > √(ln 2)·λ/(4π) ≈ 0.066 λ (2.0 mm at 10 GHz, 0.26 mm at 77 GHz):
ρ_s is smallest at normal incidence, so below that roughness the mirror path keeps most of the
power at every angle and stays the dominant NLOS echo (the diffuse path spreads its power over a
hemisphere twice and is far weaker).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from xnlos_core.signal.antenna import element_gain, transmit_gain
from xnlos_core.radar import RadarConfig
from xnlos_core.signal.chain import processing_gain

from . import roughness
from . import walls as wall_em

MOSTLY_DIFFUSE = 0.5  # ρ_s(0) below this: the wall is "mostly diffuse" ("auto" rule, module doc)


def mostly_diffuse(wall, radar: RadarConfig) -> bool:
    """True for a relay wall with a material whose normal-incidence specular factor ρ_s(0) < 1/2."""
    if not wall.relay or wall.material is None or wall.roughness == 0:
        return False
    return float(roughness.specular_factor(wall.roughness, 0.0, radar.wavelength)) < MOSTLY_DIFFUSE


def decide(switch: str, scene, radar: RadarConfig) -> str:
    """"on" or "off: why" for the diffuse NLOS path given switch "auto" / "on" / "off" (module doc)."""
    if switch == "off":
        return "off: switched off"
    if not scene.objects:
        return "off: no object"
    if switch == "on" or any(mostly_diffuse(w, radar) for w in scene.walls):
        return "on"
    return (f"off: no mostly diffuse relay wall (ρ_s(0) < {MOSTLY_DIFFUSE}, σ_h > "
            f"{math.sqrt(math.log(2)) * radar.wavelength / (4 * math.pi) * 1e3:.2g} mm at this carrier)")


def cells(spec, cell_length: float) -> tuple[np.ndarray, float]:
    """Cell centres (K, 2) [m] of ``spec`` cut into K ≈ length/cell_length cells, and the cell length [m]."""
    start, end = np.asarray(spec.start, float), np.asarray(spec.end, float)
    length = math.dist(spec.start, spec.end)
    k = max(1, int(round(length / cell_length)))
    s = (np.arange(k) + 0.5) / k
    return start + s[:, None] * (end - start), length / k


def three_bounce_power(radar: RadarConfig, r_a, az_a, r_b, az_b, d_ao, d_ob, sa_dA, sb_dA, rcs) -> np.ndarray:
    """Received power [W] of the three-bounce path (module doc), broadcast over all arrays.

    r_a, r_b: radar–patch distances [m]; az_a, az_b: their azimuths [rad]; d_ao, d_ob: patch–object
    distances [m]; sa_dA, sb_dA: the patches' bistatic σ⁰·dA [m²]; rcs: the object's σ_o [m²].
    """
    g = transmit_gain(radar, az_a) * element_gain(radar, az_a) * element_gain(radar, az_b)
    loss = 10.0 ** (radar.system_loss_db / 10.0)
    num = radar.transmit_power * g * radar.wavelength**2 * np.asarray(rcs) * sa_dA * sb_dA
    return num / ((4 * np.pi) ** 5 * r_a**2 * d_ao**2 * d_ob**2 * r_b**2 * loss)


def noise_equivalent_power(radar: RadarConfig) -> float:
    """Received power [W] whose RA-map SNR is 0 dB (:func:`sims.propagation.ra_snr_db`)."""
    return float(radar.noise_power / processing_gain(radar))


@dataclass
class WallPaths:
    """The kept three-bounce paths of one relay wall (:func:`wall_paths`), P rows each, and what the
    importance cut left out.

    length (P,) round trip [m]; azimuth (P,) arrival azimuth [rad] (cell b's); power (P,) [W];
    pos (P, 2) apparent position (arrival direction × length/2) [m]; hidden (P, 2) the object centre
    [m]; centre (P,) its index; ia, ib (P,) indices of the cells a (out) and b (back) into the cells
    given; rate (P,) d(length/2)/dt [m/s]; total: the wall's summed three-bounce power [W] before the
    cut; neglected: the power [W] of the pairs left out; pairs: the candidate pairs Σ_o K_o²; capped:
    the path cap, not the floor, set the threshold (``neglected`` may then exceed the floor's budget).
    """

    length: np.ndarray
    azimuth: np.ndarray
    power: np.ndarray
    pos: np.ndarray
    hidden: np.ndarray
    centre: np.ndarray
    ia: np.ndarray
    ib: np.ndarray
    rate: np.ndarray
    total: float
    neglected: float
    pairs: int
    capped: bool = False


def wall_paths(radar: RadarConfig, spec, normal, cells, area: float, origin, points, rcs, sees, velocity,
               budget: float, cap: int) -> WallPaths:
    """Three-bounce paths (module doc) of relay wall ``spec``: for every object centre o, every cell
    pair (a, b) that both see o, kept by an importance cut (below).

    Both radar forward models call this; each gives the visibility from its own occlusion tests.
    normal (3,): the wall's unit normal on the radar side; cells (K, 3) patch centres [m], each of
    area ``area`` [m²]; origin (3,) the radar [m]; points (O, 3) object centres [m], rcs (O,) [m²];
    sees (O, K) bool: radar ↔ cell and cell ↔ centre unobstructed and the centre facing the cell;
    velocity (O, 3) of each centre's object [m/s].

    Cost control: the pair power factorises, P(o, a, b) = c_o·u_o(a)·v_o(b) (gains, σ⁰ and distances
    of each leg), so the summed power and the kept power of any threshold follow from sorted u and v
    in O(K log K) per centre without forming the K² pairs. Pairs below t = budget / pairs are left out
    (their sum is < budget, a bound that holds in every resolution cell); when more than ``cap`` pairs
    remain, t rises (bisection in log t) until at most ``cap`` do. The exact neglected power is
    returned (``neglected``), whatever bound applied.
    """
    n3 = np.asarray(normal, dtype=np.float64)
    a = np.asarray(cells, dtype=np.float64)
    pts = np.asarray(points, dtype=np.float64)
    sees = np.asarray(sees, dtype=bool)
    rel = a - origin
    r_a = np.linalg.norm(rel, axis=1)
    az = np.arctan2(rel[:, 1], rel[:, 0])
    to_obj = pts[:, None, :] - a[None, :, :]  # (O, K, 3)
    d = np.linalg.norm(to_obj, axis=2)
    to_radar = np.broadcast_to(-rel, to_obj.shape)
    s_out = wall_em.bistatic_sigma0(spec, radar, to_radar, to_obj, n3) * area  # radar → a → o
    s_back = wall_em.bistatic_sigma0(spec, radar, to_obj, to_radar, n3) * area  # o → b → radar
    g_out = transmit_gain(radar, az) * element_gain(radar, az)
    g_back = element_gain(radar, az)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(sees, g_out * s_out / (r_a**2 * d**2), 0.0)  # (O, K)
        v = np.where(sees, g_back * s_back / (r_a**2 * d**2), 0.0)
    c = radar.transmit_power * radar.wavelength**2 * np.asarray(rcs, dtype=np.float64) / (
        (4 * np.pi) ** 5 * 10.0 ** (radar.system_loss_db / 10.0))  # (O,)
    v_sorted = np.sort(v, axis=1)  # ascending
    head = np.concatenate([np.zeros((len(pts), 1)), np.cumsum(v_sorted, axis=1)], axis=1)  # Σ of the j weakest
    total = float(np.sum(c * u.sum(axis=1) * v.sum(axis=1)))
    n_pairs = int(np.sum(sees.sum(axis=1) ** 2))
    K = a.shape[0]

    def keep(t: float) -> np.ndarray:
        """(O, K) number of b cells kept with each a cell at pair-power threshold t [W]."""
        with np.errstate(divide="ignore"):
            need = np.where(u > 0, t / (c[:, None] * u), np.inf)
        start = np.stack([np.searchsorted(v_sorted[o], need[o], side="left") for o in range(len(pts))]) \
            if len(pts) else np.zeros((0, K), dtype=np.int64)
        return np.where(u > 0, K - start, 0)

    t = budget / max(n_pairs, 1)
    counts = keep(t)
    capped = bool(counts.sum() > cap)
    if capped:
        hi = float(np.max(c[:, None] * u * v_sorted[:, -1:])) * 1.01
        lo = t
        for _ in range(60):
            mid = math.sqrt(lo * hi)
            if keep(mid).sum() > cap:
                lo = mid
            else:
                hi = mid
            if hi / lo < 1 + 1e-9:
                break
        t, counts = hi, keep(hi)
    neglected = float(np.sum(c[:, None] * u * np.take_along_axis(head, K - counts, axis=1)))
    # enumerate the kept pairs: for each (o, a) the counts[o, a] strongest b of centre o
    order = np.argsort(v, axis=1)[:, ::-1]  # descending v: the kept b of (o, a) are order[o, :count]
    o_i, a_i = np.nonzero(counts)
    n = counts[o_i, a_i]
    rep = np.repeat(np.arange(len(n)), n)
    rank = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    o_k, ia = o_i[rep], a_i[rep]
    ib = order[o_k, rank]
    power = three_bounce_power(radar, r_a[ia], az[ia], r_a[ib], az[ib], d[o_k, ia], d[o_k, ib],
                               s_out[o_k, ia], s_back[o_k, ib], np.asarray(rcs, dtype=np.float64)[o_k])
    length = r_a[ia] + d[o_k, ia] + d[o_k, ib] + r_a[ib]
    dirs = np.column_stack([np.cos(az[ib]), np.sin(az[ib])])
    vel = np.asarray(velocity, dtype=np.float64)[o_k]
    rate = (np.einsum("ij,ij->i", to_obj[o_k, ia], vel) / d[o_k, ia]
            + np.einsum("ij,ij->i", to_obj[o_k, ib], vel) / d[o_k, ib]) / 2
    return WallPaths(length=length, azimuth=az[ib], power=power, pos=dirs * (length / 2)[:, None],
                     hidden=pts[o_k, :2], centre=o_k, ia=ia, ib=ib, rate=rate, total=total,
                     neglected=neglected, pairs=n_pairs, capped=capped)


def describe_cut(kept: int, pairs: int, total: float, neglected: float, capped: bool, radar: RadarConfig) -> str:
    """meta["components"]["diffuse_nlos_cut"]: paths kept of the candidate pairs and the power left out
    (and whether the path cap, rather than the floor, set what was left out)."""
    with np.errstate(divide="ignore"):
        snr = 10 * math.log10(neglected / noise_equivalent_power(radar)) if neglected > 0 else -math.inf
    return (f"kept {kept} of {pairs} pairs; neglected {neglected:.3g} W of {total:.3g} W "
            f"(RA-map SNR of the neglected sum {snr:.1f} dB){'; path cap reached' if capped else ''}")
