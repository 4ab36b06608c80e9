"""1-D FDTD reflection/transmission of a material slab (paper Sec. 5.1.1: reflection coefficients
from an FDTD solver), cached in-process and on disk, and :func:`wall_reflection` for the simulator.

Solver (Yee, 1-D, e^{+jωt} phasors as in :mod:`sims.materials`):

* Fields E (tangential, E_y) on integer nodes z = kΔz and H̃ = η0·H on half nodes; normalised
  updates  H̃ ← H̃ − S_h·ΔE,   E ← c_a·E − c_b·ΔH̃  with  S_h = cΔt/Δz,
  x = σΔt/(2ε0ε_e),  c_a = (1 − x)/(1 + x),  c_b = (S_h/ε_e)/(1 + x)  (standard lossy update).
* Oblique TE incidence by the exact 1-D mapping: with k_x = k0·sinθ fixed, E_y obeys the 1-D
  equations with ε_e = ε' − sin²θ (slab, same σ) and ε_e = cos²θ (vacuum), non-dispersive.
  TM has no such non-dispersive mapping (μ_e = 1 − sin²θ/η is frequency dependent in a lossy
  medium), so TM is available at normal incidence only (where TM ≡ TE up to the sign convention).
* Δt = cosθ·Δz/c puts the vacuum at the "magic" Courant number 1: free-space propagation is
  dispersion-free, the total-field/scattered-field source is leak-free and the first-order Mur
  boundary E_0^{n+1} = E_1^n is exact (zero reflection at every frequency) — so the vacuum gaps
  need only a few cells. Inside the slab the Courant number is cosθ/√ε_e < 1 (stable).
* Resolution: Δz ≤ λ0 / (ppw · min(|√(ε_e − jσ/ωε0)|, n_cap)) at the highest frequency; the
  slab spans an integer number of cells exactly (Δz = d/N) and its two face nodes take the
  average of the materials on either side, so the faces sit at their true positions. A lossy
  slab deeper than 20 one-way field decay lengths is simulated to that depth only (back-face
  echo below e^{−40}); T is then continued analytically through the rest. A slab thinner than
  half a cell becomes one node with thickness-weighted ε_e and σ (thin-sheet model). n_cap caps
  the resolution of good conductors (metal, |√η| ~ 4000): their skin depth is not resolved and
  they act as the near-PEC they are (FDTD |R| = 1.000 vs 0.9997 at 10 GHz, 0.9991 at 77 GHz).
* Source: a Gaussian-modulated sine centred on the requested band, injected at a TF/SF node;
  the reflected wave is recorded in the scattered-field region, the transmitted one behind the
  slab; the run stops once the field energy left in the grid is below ``tol`` × its peak.
  DFTs at the requested frequencies divided by the incident spectrum give R (referred to the
  front face) and T (P.2040 reference of :func:`sims.fresnel.slab`).
"""
from __future__ import annotations

import functools
import hashlib
import json
import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.constants import epsilon_0, speed_of_light

from sims.fresnel import polarisation, as_theta, fresnel, slab
from sims.materials import Material, get_material
from sims.roughness import specular_field_factor
from xnlos_core.errors import InputError
from xnlos_core.io import atomic_write_text

SOLVER_VERSION = "xnlos-fdtd1d-1"
MAX_FDTD_ANGLE = math.radians(85.0)  # time step shrinks as cosθ; beyond this use the analytic slab
_GAP = 4  # vacuum cells between source, observers and slab (exact ABC: a few suffice)


@dataclass(frozen=True)
class SlabFDTDResult:
    """Output of :func:`simulate_slab`: f_hz (F,), R and T (F,) complex, grid and run facts."""

    f_hz: np.ndarray
    R: np.ndarray
    T: np.ndarray
    dz_m: float
    dt_s: float
    n_cells: int
    n_steps: int
    converged: bool


def _pulse(dt: float, f_c: float, half_band: float) -> np.ndarray:
    """g(m), m = 0…L−1: exp(−((m−m0)Δt/τ)²)·sin(2πf_c(m−m0)Δt), τ = 2/(πB), m0 = ⌈5τ/Δt⌉."""
    tau = 2.0 / (np.pi * half_band)
    m0 = int(math.ceil(5.0 * tau / dt))
    t = (np.arange(2 * m0 + 1) - m0) * dt
    return np.exp(-((t / tau) ** 2)) * np.sin(2.0 * np.pi * f_c * t)


def simulate_slab(eps_real: float, sigma_s_m: float, thickness_m: float, f_hz, theta_i: float = 0.0, *,
                  ppw: float = 40.0, tol: float = 1e-12, n_cap: float = 10.0,
                  max_steps: int = 5_000_000) -> SlabFDTDResult:
    """Run the 1-D FDTD for a slab (ε' = eps_real ≥ 1, σ = sigma_s_m [S/m], thickness_m [m] ≥ 0,
    constant over the band) lit from vacuum at theta_i [rad] (TE), and return R, T at f_hz [Hz]
    (scalar or 1-D). ppw: cells per wavelength in the densest medium at max(f_hz); tol: stop
    when the grid's field energy is below tol × peak; n_cap: cap on the index used for
    resolution (conductors). Lossy slabs deeper than 20 decay lengths are simulated to that
    depth only (see below). Typical cost 0.01–0.4 s (benchmarks/fdtd_check.py): concrete or glass
    300 mm at 77 GHz ≈ 0.1–0.4 s; cost grows ∝ 1/cosθ for oblique TE.
    """
    f = np.atleast_1d(np.asarray(f_hz, dtype=np.float64))
    if f.ndim != 1 or f.size == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise InputError(f"f_hz must be one or more finite frequencies > 0 (Hz), got {f_hz!r}")
    for name, v, lo in (("eps_real", eps_real, 1.0), ("sigma_s_m", sigma_s_m, 0.0), ("thickness_m", thickness_m, 0.0)):
        if not (isinstance(v, (int, float, np.floating, np.integer)) and math.isfinite(v) and v >= lo):
            raise InputError(f"{name} must be a finite number ≥ {lo:g}, got {v!r}")
    if not (ppw >= 10 and n_cap >= 1 and 0 < tol < 1e-3):
        raise InputError(f"need ppw ≥ 10, n_cap ≥ 1, 0 < tol < 1e-3; got ppw={ppw}, n_cap={n_cap}, tol={tol}")
    th = float(as_theta(theta_i))
    if th > MAX_FDTD_ANGLE:
        raise InputError(f"theta_i = {math.degrees(th):.2f}° exceeds the FDTD limit of 85°; use the analytic slab")
    cos_t, sin2 = math.cos(th), math.sin(th) ** 2
    eps_v, eps_s = cos_t**2, float(eps_real) - sin2
    sigma = float(sigma_s_m)
    f_max = float(f.max())
    n_med = abs(np.sqrt(eps_s - 1j * sigma / (2 * np.pi * f_max * epsilon_0)))
    n_res = max(min(n_med, n_cap), cos_t)
    dz_max = speed_of_light / f_max / (ppw * n_res)
    d = float(thickness_m)
    # a slab deeper than 20 one-way decay lengths is cut there (back-face echo < e^{-40}; it also
    # keeps the deep field out of the subnormal range, which would slow numpy ~20×); T is then
    # carried through the removed depth analytically, T ← T·e^{−jk0·a·(d − d_sim)}
    a_f = np.sqrt(eps_s - 1j * sigma / (2 * np.pi * f * epsilon_0))
    decay = float(np.min(np.abs(a_f.imag) * 2 * np.pi * f / speed_of_light))
    d_sim = min(d, max(20.0 / decay, 8.0 * dz_max)) if decay > 0 else d
    sheet = 0 < d_sim < 0.5 * dz_max  # thinner than half a cell: one thickness-weighted node
    n_slab = 0 if (d == 0 or sheet) else max(int(math.ceil(d_sim / dz_max - 1e-9)), 1)
    dz = d_sim / n_slab if n_slab else dz_max
    dt = cos_t * dz / speed_of_light
    sh = cos_t  # S_h = cΔt/Δz

    k_o, k_s = 2, 2 + _GAP // 2
    k_f = k_s + _GAP
    k_b = k_f + n_slab
    k_t = k_b + _GAP
    n_nodes = k_t + 3
    eps_e = np.full(n_nodes, eps_v)
    sig = np.zeros(n_nodes)
    if n_slab:
        eps_e[k_f + 1:k_b] = eps_s
        sig[k_f + 1:k_b] = sigma
        eps_e[[k_f, k_b]] = 0.5 * (eps_v + eps_s)
        sig[[k_f, k_b]] = 0.5 * sigma
    elif sheet:  # sub-cell sheet centred on node k_f: volume-weighted ε_e and σ
        eps_e[k_f] = eps_v + (eps_s - eps_v) * d_sim / dz
        sig[k_f] = sigma * d_sim / dz
    x = sig * dt / (2.0 * epsilon_0 * eps_e)
    ca = ((1.0 - x) / (1.0 + x))[1:-1]
    cb = ((sh / eps_e) / (1.0 + x))[1:-1]
    cb_s = float(cb[k_s - 1])

    f_lo = float(f.min())
    f_c = 0.5 * (f_lo + f_max)
    g = _pulse(dt, f_c, max(0.5 * (f_max - f_lo), 0.25 * f_c))
    n_g = g.size

    def g_at(m: int) -> float:
        return float(g[m]) if 0 <= m < n_g else 0.0

    E = np.zeros(n_nodes)
    H = np.zeros(n_nodes - 1)
    dH = np.empty(n_nodes - 2)
    rec_r: list[float] = []
    rec_t: list[float] = []
    w_peak, converged, n = 0.0, False, 0
    n_src_done = n_g + k_s + 1
    while n < max_steps:
        H -= sh * (E[1:] - E[:-1])
        H[k_s - 1] += sh * g_at(n - k_s)
        e_left, e_right = E[1], E[-2]
        np.subtract(H[1:], H[:-1], out=dH)
        E[1:-1] = ca * E[1:-1] - cb * dH
        E[k_s] += cb_s * sh * g_at(n - k_s + 1)
        E[0], E[-1] = e_left, e_right
        rec_r.append(E[k_o])
        rec_t.append(E[k_t])
        n += 1
        if n % 32 == 0:
            w = float(np.dot(eps_e * E, E) + np.dot(H, H))
            w_peak = max(w_peak, w)
            if n > n_src_done and w <= tol * w_peak:
                converged = True
                break
    if not converged:
        warnings.warn(f"simulate_slab: stopped at max_steps={max_steps} before the field decayed "
                      f"below tol={tol:g}; R and T are truncated", RuntimeWarning, stacklevel=2)

    w_dt = 2.0 * np.pi * f * dt  # ωΔt = k_z·Δz in the vacuum (exact at Courant 1)
    steps = np.arange(1, n + 1)
    kern = np.exp(-1j * np.outer(w_dt, steps))
    x_r = kern @ np.asarray(rec_r)
    x_t = kern @ np.asarray(rec_t)
    G = np.exp(-1j * np.outer(w_dt, np.arange(n_g))) @ g
    n_thick = d_sim / dz  # slab thickness in cells (fractional for a sheet)
    z_front = k_f - 0.5 * n_thick if sheet else k_f  # front face in cells
    R = x_r / G * np.exp(1j * w_dt * k_o) * np.exp(2j * w_dt * (z_front - k_o))
    T = x_t / G * np.exp(1j * w_dt * k_t) * np.exp(-1j * w_dt * n_thick)
    if d_sim < d:
        T = T * np.exp(-1j * 2 * np.pi * f / speed_of_light * a_f * (d - d_sim))
    return SlabFDTDResult(f, R, T, dz, dt, n_nodes, n, converged)


# -- cached per-material front end ---------------------------------------------------------------
def cache_dir() -> Path:
    """On-disk FDTD cache folder: $XNLOS_CACHE_DIR/fdtd, default ~/.cache/xnlos/fdtd."""
    root = os.environ.get("XNLOS_CACHE_DIR") or "~/.cache/xnlos"
    return Path(root).expanduser() / "fdtd"


def _cache_key(name, eps_real, sigma, d, f, theta, ppw, tol, n_cap) -> dict:
    return {"solver": SOLVER_VERSION, "material": name, "eps_real": eps_real, "sigma_s_m": sigma,
            "thickness_m": d, "f_hz": f, "theta_i": theta, "ppw": ppw, "tol": tol, "n_cap": n_cap}


def _read_entry(path: Path, key: dict):
    """(R, T) stored at path for key, or None (absent); a corrupt file warns and reads as None."""
    if not path.exists():
        return None
    try:
        rec = json.loads(path.read_text(encoding="utf-8"))
        if rec["key"] != key:
            raise ValueError("key mismatch")
        R, T = complex(*rec["R"]), complex(*rec["T"])
        if not (np.isfinite(R) and np.isfinite(T)):
            raise ValueError("non-finite value")
        return R, T
    except (OSError, ValueError, KeyError, TypeError) as exc:
        warnings.warn(f"ignoring corrupt FDTD cache file {path} ({exc}); recomputing and rewriting it",
                      RuntimeWarning, stacklevel=4)
        return None


@functools.lru_cache(maxsize=4096)
def _cached(name, eps_real, sigma, d, f, theta, ppw, tol, n_cap, folder) -> tuple[complex, complex]:
    key = _cache_key(name, eps_real, sigma, d, f, theta, ppw, tol, n_cap)
    digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:32]
    path = Path(folder) / f"{digest}.json"
    hit = _read_entry(path, key)
    if hit is not None:
        return hit
    res = simulate_slab(eps_real, sigma, d, f, theta, ppw=ppw, tol=tol, n_cap=n_cap)
    R, T = complex(res.R[0]), complex(res.T[0])
    rec = {"key": key, "R": [R.real, R.imag], "T": [T.real, T.imag], "dz_m": res.dz_m,
           "n_steps": res.n_steps, "converged": res.converged}
    try:
        atomic_write_text(path, json.dumps(rec, sort_keys=True))
    except OSError as exc:
        warnings.warn(f"could not write FDTD cache file {path} ({exc})", RuntimeWarning, stacklevel=3)
    return R, T


def clear_cache() -> None:
    """Forget the in-process (lru) FDTD results; the on-disk cache is left alone."""
    _cached.cache_clear()


def _half_space_depth(eps: complex, f: float, theta: float, ppw: float) -> float:
    """Slab thickness [m] whose round trip attenuates the back-face echo by e^{−14} (≈ 1e-6)."""
    im = abs((np.sqrt(eps - 1.0 + math.cos(theta) ** 2)).imag) * 2 * np.pi * f / speed_of_light
    if im == 0:
        raise InputError("a lossless half-space (thickness None/inf) cannot be simulated by FDTD: "
                         "give a finite thickness or use method='analytic'")
    return max(7.0 / im, speed_of_light / f / ppw)


def fdtd_coefficients(material: str | Material, thickness_m: float | None, f_hz: float, theta_i: float = 0.0, *,
                      ppw: float = 40.0, tol: float = 1e-12, n_cap: float = 10.0, extrapolate: bool = False,
                      cache: bool = True) -> tuple[complex, complex]:
    """FDTD (R, T) of a slab of ``material`` [Table 3 name or Material], thickness_m [m] (None/inf:
    a half-space, simulated as a lossy slab deep enough that its back face is invisible, T ≈ 0),
    at one frequency f_hz [Hz], TE incidence theta_i [rad] ≤ 85°. ε' and σ are those of
    material at f_hz (P.2040 range enforced unless extrapolate=True). Conventions as in
    :func:`sims.fresnel.slab`. Results are memoised in-process and, with cache=True, on disk
    (:func:`cache_dir`, one JSON file per key: material parameters, thickness, frequency, angle,
    solver settings and SOLVER_VERSION; written atomically; a corrupt file warns and is rewritten).
    """
    m = get_material(material)
    f = float(f_hz)
    eps = complex(m.permittivity(f, extrapolate=extrapolate))
    th = float(as_theta(theta_i))
    if thickness_m is None or (isinstance(thickness_m, (int, float)) and math.isinf(thickness_m)):
        d = _half_space_depth(eps, f, th, ppw)
    else:
        d = float(thickness_m)
    eps1 = float(m.real_permittivity(f, extrapolate=extrapolate))
    sigma = float(m.conductivity(f, extrapolate=extrapolate))
    if not cache:
        res = simulate_slab(eps1, sigma, d, f, th, ppw=ppw, tol=tol, n_cap=n_cap)
        return complex(res.R[0]), complex(res.T[0])
    return _cached(m.name, eps1, sigma, d, f, th, float(ppw), float(tol), float(n_cap), str(cache_dir()))


def fdtd_reflection(material: str | Material, thickness_m: float | None, f_hz: float, theta_i: float = 0.0,
                    **kw) -> complex:
    """FDTD amplitude reflection coefficient R (front-face reference); see :func:`fdtd_coefficients`."""
    return fdtd_coefficients(material, thickness_m, f_hz, theta_i, **kw)[0]


def wall_reflection(material: str | Material, thickness_m, theta_i, f_hz, *, method: str = "analytic",
                    pol: str = "s", roughness_m=0.0, extrapolate: bool = False, **fdtd_kw) -> np.ndarray:
    """Specular amplitude reflectivity α of a wall (complex, e^{jωt}) for the simulator's mirror paths.

    material: Table 3 name or Material; thickness_m [m] (None or inf: half-space); theta_i [rad]
    from the wall normal and f_hz [Hz] broadcast (any shape); pol 's'/'TE' (vertical polarisation
    on a vertical wall) or 'p'/'TM'; roughness_m: rms height σ_h [m] — α is multiplied by the
    coherent FIELD factor exp(−8π²σ_h²cos²θ/λ²) (:func:`sims.roughness.specular_field_factor`), the
    power taken out of the mirror path goes to the diffuse lobe (:mod:`sims.roughness`).

    method='analytic': :func:`sims.fresnel.slab` (or :func:`sims.fresnel.fresnel` for a half-space).
    method='fdtd': one cached FDTD run per distinct (θ, f). TE uses the exact oblique 1-D mapping
    (θ ≤ 85°); TM only at normal incidence (θ = 0), since the TM mapping is dispersive — other
    TM angles raise InputError (use 'analytic'). At θ = 0 the TM value is −R_TE (P.2040 sign).
    """
    p = polarisation(pol)
    m = get_material(material)
    th = as_theta(theta_i)
    f = np.asarray(f_hz, dtype=np.float64)
    th, f = np.broadcast_arrays(th, f)
    eps = m.permittivity(f, extrapolate=extrapolate)
    half = thickness_m is None or np.isinf(np.asarray(thickness_m, dtype=np.float64)).all()
    if method == "analytic":
        alpha = fresnel(eps, th, p)[0] if half else slab(eps, thickness_m, th, f, p)[0]
    elif method == "fdtd":
        if p == "p" and np.any(th > 1e-12):
            raise InputError("method='fdtd' gives TM ('p') reflection at normal incidence only "
                             "(no non-dispersive 1-D TM mapping); use method='analytic' for oblique TM")
        if not np.ndim(thickness_m) == 0:
            raise InputError("method='fdtd' needs a scalar thickness_m (or None)")
        d = None if half else float(thickness_m)
        alpha = np.empty(th.shape, dtype=np.complex128)
        for idx in np.ndindex(th.shape):
            alpha[idx] = fdtd_reflection(m, d, float(f[idx]), float(th[idx]), extrapolate=extrapolate, **fdtd_kw)
        if p == "p":
            alpha = -alpha
    else:
        raise InputError(f"method must be 'analytic' or 'fdtd', got {method!r}")
    if np.any(np.asarray(roughness_m) != 0):
        alpha = alpha * specular_field_factor(roughness_m, th, speed_of_light / f)
    return alpha
