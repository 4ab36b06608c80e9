"""Three-bounce Lambertian transport of a confocal SPAD scan (expected photon counts, no noise).

Wall coordinates: the relay wall is the plane z = 0, x along it, y up, z the distance in front of
it toward the hidden side; the laser and the SPAD both aim at scan point s = (x_s, y_s, 0).
A hidden Lambertian patch at p (area A [m²], unit normal n_p, albedo ρ) returns, per laser pulse,

    N = N_γ · (ρ_w cosθ_s/π) · (A cosθ_p/r²) · (ρ cosθ_p/π) · (A_spot cosθ_s/r²) · (ρ_w cosθ_v/π) · (A_ap/D²) · η

photons (r = |p − s|, cosθ_s = z/r at the wall, cosθ_p = n_p·(s − p)/r ≥ 0 at the patch): the laser
spot scatters Lambertian (ρ_w) toward the patch, the patch scatters Lambertian (ρ) back onto the
SPAD's spot of area A_spot, and that spot scatters Lambertian into the aperture A_ap at collection
distance D, seen at the sensor's view angle θ_v from the wall normal (``Optics.view_cosine`` =
cosθ_v; 1 for a sensor on the wall normal). The two wall–patch legs give the 1/r⁴ falloff. N_γ = P/(f_rep·hc/λ)
photons per pulse (average power P, repetition rate f_rep, wavelength λ); η the detection
efficiency. Round trip (confocal convention, the sensor–wall legs removed): τ = 2r/c.

Histogram (the project's one depth-bin convention, shared with the NLOS solvers,
:mod:`estimators.nlos.prep`): bin k is CENTRED at round trip t_k = t0 + kΔ, i.e. it covers
[t0 + (k − ½)Δ, t0 + (k + ½)Δ), and the solvers put it at depth z_k = c·(t_k)/2. Each return is
split linearly between the two nearest bin centres (a return at exactly t_k lands wholly in bin k),
then convolved along time with the bin-integrated Gaussian of the system response,
σ = √(FWHM_pulse² + FWHM_jitter²)/(2√(2 ln 2)) (pulse width ⊕ SPAD timing jitter).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import convolve1d
from scipy.special import erf

from xnlos_core.errors import InputError
from xnlos_core.transient import SPEED_OF_LIGHT
from xnlos_core.validation import as_array

PLANCK = 6.626_070_15e-34  # [J s]
FWHM_TO_SIGMA = 1.0 / (2.0 * np.sqrt(2.0 * np.log(2.0)))


@dataclass(frozen=True)
class Patches:
    """Hidden Lambertian patches in wall coordinates: centres (P, 3) [m], unit normals (P, 3),
    areas (P,) [m²], albedos (P,) in [0, 1]."""

    centers: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    albedo: np.ndarray

    def __post_init__(self):
        c = as_array("Patches.centers", self.centers, shape=(None, 3))
        n = as_array("Patches.normals", self.normals, shape=(len(c), 3))
        a = as_array("Patches.areas", self.areas, shape=(len(c),))
        r = as_array("Patches.albedo", self.albedo, shape=(len(c),))
        if len(a) and a.min() < 0:
            raise InputError(f"Patches.areas: expected areas ≥ 0 [m²], got min {a.min():g}")
        if len(r) and (r.min() < 0 or r.max() > 1):
            raise InputError(f"Patches.albedo: expected albedos in [0, 1], got [{r.min():g}, {r.max():g}]")
        norm = np.linalg.norm(n, axis=1)
        if len(n) and np.any(np.abs(norm - 1) > 1e-6):
            raise InputError("Patches.normals: expected unit vectors, got norms in "
                             f"[{norm.min():g}, {norm.max():g}]")
        for name, v in (("centers", c), ("normals", n), ("areas", a), ("albedo", r)):
            object.__setattr__(self, name, v)


@dataclass(frozen=True)
class Optics:
    """Laser and collection optics: average power [W], wavelength [m], repetition rate [Hz],
    detection efficiency η, aperture area [m²], collection distance D [m], SPAD spot area on the
    wall [m²], relay-wall albedo ρ_w, cosθ_v of the collection direction from the wall normal
    (module docstring)."""

    power: float = 1.6e-3
    wavelength: float = 850e-9
    rep_rate: float = 5e6
    efficiency: float = 0.3
    aperture_area: float = 4.9e-4
    collection_distance: float = 2.0
    spot_area: float = 7.85e-5
    wall_albedo: float = 0.8
    view_cosine: float = 1.0

    def __post_init__(self):
        if not 0.0 <= self.view_cosine <= 1.0:
            raise InputError(f"Optics.view_cosine: expected cosθ_v in [0, 1], got {self.view_cosine}")

    @property
    def photons_per_pulse(self) -> float:
        """N_γ = P / f_rep / (h c / λ) [photons]."""
        return self.power / self.rep_rate / (PLANCK * SPEED_OF_LIGHT / self.wavelength)


def return_per_pulse(scan_x: np.ndarray, scan_y: np.ndarray, patches: Patches, optics: Optics
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Expected detected photons per pulse (P, H, W) and round-trip times (P, H, W) [s] of every
    patch at every scan point (x_j, y_i) (scan_x (W,), scan_y (H,) [m]); the module docstring's N, τ."""
    d = patches.centers[:, None, None, :] - np.stack(np.broadcast_arrays(
        scan_x[None, :], scan_y[:, None], np.zeros((len(scan_y), len(scan_x)))), axis=-1)[None]
    r = np.linalg.norm(d, axis=-1)
    r = np.maximum(r, 1e-9)
    cos_wall = np.clip(d[..., 2] / r, 0.0, None)  # the hidden side is z > 0
    cos_patch = np.clip(-np.einsum("phwk,pk->phw", d, patches.normals) / r, 0.0, None)
    geom = (cos_wall * cos_patch / r**2) ** 2
    k = (optics.photons_per_pulse * optics.wall_albedo**2 / np.pi**3 * optics.spot_area
         * optics.aperture_area / optics.collection_distance**2 * optics.efficiency * optics.view_cosine)
    n = k * (patches.areas * patches.albedo)[:, None, None] * geom
    return n, 2.0 * r / SPEED_OF_LIGHT


def gaussian_kernel(sigma: float, bin_width: float) -> np.ndarray:
    """Bin-integrated unit Gaussian of std ``sigma`` [s] on bins of ``bin_width`` [s], centred, odd
    length, summing to 1 ([1.] when sigma is 0)."""
    if sigma <= 0:
        return np.ones(1)
    m = int(np.ceil(6 * sigma / bin_width))
    edges = (np.arange(-m, m + 2) - 0.5) * bin_width / (np.sqrt(2) * sigma)
    g = np.diff(0.5 * erf(edges))
    return g / g.sum()


def histogram(weights: np.ndarray, tau: np.ndarray, n_bins: int, bin_width: float, t0: float = 0.0,
              sigma: float = 0.0) -> np.ndarray:
    """Transient (T, H, W) of returns ``weights`` (P, H, W) [photons] at round trips ``tau``
    (P, H, W) [s]: linear split between the bin centres t0 + kΔ (module docstring: bin k is centred
    at t0 + kΔ), then the Gaussian system response of std ``sigma`` [s]. A share that falls on a bin
    outside 0 … T − 1 is dropped."""
    p, h, w = weights.shape
    u = (tau - t0) / bin_width
    k = np.floor(u).astype(np.int64)
    f = u - k
    pix = np.broadcast_to(np.arange(h * w).reshape(h, w), (p, h, w))
    out = np.zeros(n_bins * h * w)
    for kk, ww in ((k, weights * (1 - f)), (k + 1, weights * f)):
        ok = (kk >= 0) & (kk < n_bins)
        out += np.bincount((kk[ok] * h * w + pix[ok]), weights=ww[ok], minlength=n_bins * h * w)
    vol = out.reshape(n_bins, h, w)
    g = gaussian_kernel(sigma, bin_width)
    if len(g) > 1:
        vol = convolve1d(vol, g, axis=0, mode="constant")
    return vol


def system_sigma(pulse_fwhm: float, jitter_fwhm: float) -> float:
    """σ [s] of the system response: pulse width ⊕ timing jitter (both FWHM [s], Gaussian)."""
    return float(np.hypot(pulse_fwhm, jitter_fwhm) * FWHM_TO_SIGMA)


def expected_transient(scan_x: np.ndarray, scan_y: np.ndarray, patches: Patches, optics: Optics, *,
                       n_bins: int, bin_width: float, n_pulses: float, sigma: float = 0.0, t0: float = 0.0,
                       chunk: int = 256) -> np.ndarray:
    """Expected signal photons (T, H, W) over ``n_pulses`` pulses per scan point (no background,
    no pile-up): :func:`return_per_pulse` histogrammed by :func:`histogram`; patches in chunks."""
    scan_x = as_array("scan_x", scan_x, ndim=1)
    scan_y = as_array("scan_y", scan_y, ndim=1)
    vol = np.zeros((n_bins, len(scan_y), len(scan_x)))
    for i in range(0, len(patches.areas), chunk):
        part = Patches(patches.centers[i:i + chunk], patches.normals[i:i + chunk], patches.areas[i:i + chunk],
                       patches.albedo[i:i + chunk])
        n, tau = return_per_pulse(scan_x, scan_y, part, optics)
        vol += histogram(n, tau, n_bins, bin_width, t0, 0.0)
    g = gaussian_kernel(sigma, bin_width)
    if len(g) > 1:
        vol = convolve1d(vol, g, axis=0, mode="constant")
    return vol * n_pulses
