"""Light-cone transform (LCT) reconstruction of confocal NLOS transients (O'Toole, Lindell, Wetzstein,
Nature 2018), the "lct" nlos_solver of the cross-modality comparison (Sec. 5.1.2, Fig. 5).

With the round trip t = 2·√(Δx² + Δy² + z²)/c, the substitutions v = (c·t/2)² and u = z² turn the
confocal measurement into a 3-D convolution τ(x′, y′, v) = Σ ρ(x, y, u)·K(x′ − x, y′ − y, v − u)
with the shell kernel K = δ(Δx² + Δy² − (v − u)). The solver: compensate the 1/r⁴ (diffuse) or
1/r² fall-off, resample t → v with the LCT resampling matrix, Wiener-deconvolve K in the Fourier
domain (scipy.fft, padded to 2× in every axis), resample u → z with the transposed matrix.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import scipy.fft as sfft
import scipy.sparse as sp
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.interfaces import NLOSSolver
from xnlos_core.nlos_volume import NLOSVolume
from xnlos_core.transient import TransientVolume

from .prep import prepare
from .torch_backend import device_field, lct_torch, torch_device


class LCTParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    snr: float = Field(0.8, ge=1e-12, le=1e12, description="Wiener filter signal-to-noise ratio (O'Toole's default "
                       "0.8); larger sharpens and amplifies noise. Within 1e-12 … 1e12: 1/snr is added to the "
                       "kernel's |K̂|² ≤ 1 in float32, where 1/snr beyond 3.4e38 is inf (an all-zero albedo)")
    diffuse: bool = Field(True, description="compensate a 1/r⁴ (diffuse) fall-off; False: 1/r² (retroreflective)")
    dtype: str = Field("float32", pattern="^(float32|float64)$",
                       description="working precision of the FFTs: float32 (complex64) or float64")
    workers: int = Field(-1, description="scipy.fft worker threads (-1: all cores)")
    device: str = device_field()


ZETA_HALF = -1.4603545088095868  # ζ(1/2)
_EXACT_BELOW = 64  # partial sums of 1/√x up to here by direct summation, above by Euler–Maclaurin


def inv_sqrt_partial_sums(n: np.ndarray) -> np.ndarray:
    """S(N) = Σ_{x=1}^{N} x^(−1/2) for integer N ≥ 0 (array, any shape), float64.

    N < 64: direct cumulative sum. N ≥ 64: the Euler–Maclaurin expansion
    S(N) = ζ(½) + 2√N + ½N^(−½) − (1/24)·N^(−3/2) + (1/384)·N^(−7/2) − …, whose next term
    (≈ 2.4·10⁻³·N^(−11/2)) is below 10⁻¹² there: O(1) per N instead of a sum over N terms."""
    n = np.asarray(n, dtype=np.int64)
    table = np.concatenate([[0.0], np.cumsum(1.0 / np.sqrt(np.arange(1, _EXACT_BELOW, dtype=np.float64)))])
    big = n >= _EXACT_BELOW
    nf = np.where(big, n, 1).astype(np.float64)
    r = np.sqrt(nf)
    asym = ZETA_HALF + 2 * r + 0.5 / r - 1.0 / (24 * nf * r) + 1.0 / (384 * nf ** 3 * r)
    return np.where(big, asym, table[np.where(big, 0, n)])


@lru_cache(maxsize=4)
def resampling_matrix(m: int) -> sp.csr_matrix:
    """The (m, m) LCT resampling matrix t → v (O'Toole 2018, ``resamplingOperator``): fine bins
    x = 1 … m² of v, each taken from t bin ⌈√x⌉ with weight 1/√x, averaged over blocks of m. Its
    transpose maps back v → t (u → z). t and v both in units of the last bin (normalised to [0, 1]).

    Built in O(m): the block edges k·m and the bin edges c² cut 1 … m² into ≤ 2m runs (p, q], each
    inside one block (row p // m) and one t bin (column ⌊√p⌋); a run's entry is
    (S(q) − S(p))/m with S the partial sums of 1/√x (:func:`inv_sqrt_partial_sums`), equal to the
    direct sum over the m² fine bins to ≈ 10⁻¹² relative (tests/unit/test_nlos_solvers.py)."""
    k = np.arange(m + 1, dtype=np.int64)
    edges = np.union1d(k * m, k * k)  # 0 … m², sorted, unique
    p, q = edges[:-1], edges[1:]
    row = p // m
    col = np.sqrt(p.astype(np.float64)).astype(np.int64)
    col -= col * col > p  # exact integer square root (floating √ may round up near squares)
    col += (col + 1) * (col + 1) <= p
    vals = (inv_sqrt_partial_sums(q) - inv_sqrt_partial_sums(p)) / m
    return sp.csr_matrix((vals, (row, col)), shape=(m, m))


KERNEL_CHUNK_BYTES = 4 << 20  # v-frequency rows per kernel chunk: about this much complex data


def lct_kernel_fft(m: int, n: int, dx: float, dy: float, bin_length: float, snr: float, dtype,
                   workers: int) -> np.ndarray:
    """Wiener inverse conj(K̂)/(|K̂|² + 1/snr) of the shell kernel on the (2m, 2n, 2n) padded grid,
    as rfft along v (axis 0, m + 1 bins) and fft along y, x — returned as its half ky = 0 … n,
    shape (m + 1, n + 1, 2n); the full grid is even in ky (K̂[f, 2n − ky, kx] = K̂[f, ky, kx]),
    see :func:`apply_kernel`.

    K(Δy, Δx, Δv) = 1 where Δv = m·(Δx² + Δy²)/(m·bin_length/2)² (in v bins, nearest) — the shell
    of O'Toole's ``definePsf`` written with the physical scan spacing dx, dy [m] — normalised to unit
    norm. Offsets are circular (index i ↔ Δy = i·dy for i < n, (i − 2n)·dy above), so K is even
    in Δy and Δx and its 2n-point DFT along y, x is the (n + 1)-point DCT-I of its quadrant
    Δy, Δx ≥ 0 (scipy.fft.dctn type 1, unnormalised): a quarter of the scatter, transform and
    division work of the full grid. Built in chunks of v-frequency rows (≈ KERNEL_CHUNK_BYTES
    each) so that scatter, transform and Wiener division stay in cache.
    """
    off = np.arange(n + 1, dtype=np.float64)  # quadrant offsets 0 … n (n ↔ −n on the circle)
    depth = m * bin_length / 2  # [m] the last bin's depth
    dv = m * ((off[:, None] * dy) ** 2 + (off[None, :] * dx) ** 2) / depth ** 2
    r = np.rint(np.minimum(dv, 2 * m)).astype(np.int64)  # beyond 2m: outside the kernel (and int64-safe)
    keep = r < 2 * m
    flat = np.flatnonzero(keep.ravel())
    # points of the full circular grid each quadrant cell stands for (1, 2 or 4): the unit norm
    inner = (off > 0) & (off < n)
    mult = (1 + inner)[:, None] * (1 + inner)[None, :]
    norm = 1.0 / np.sqrt(float(mult.ravel()[flat].sum()))
    # rfft along v of a unit impulse at bin r is exp(−iπ·f·r/m), f = 0 … m: one phase column per
    # distinct r (few, by the shell's symmetry) instead of an FFT of the (2m, 2n, 2n) impulse volume
    shells, which = np.unique(r.ravel()[flat], return_inverse=True)
    cdtype = np.result_type(dtype, np.complex64)
    rdtype = np.finfo(cdtype).dtype
    q = n + 1
    out = np.empty((m + 1, q, 2 * n), dtype=cdtype)
    step = max(1, KERNEL_CHUNK_BYTES // (q * q * np.dtype(cdtype).itemsize))
    buf = np.zeros((step, q * q), dtype=cdtype)
    for f0 in range(0, m + 1, step):
        f1 = min(f0 + step, m + 1)
        c = f1 - f0
        phase = (np.exp((-1j * np.pi / m) * np.outer(np.arange(f0, f1), shells)) * norm).astype(cdtype)
        kc = buf[:c]
        kc[:, flat] = phase[:, which]
        k = sfft.dctn(kc.reshape(c, q, q), type=1, axes=(1, 2), workers=workers)
        den = np.square(k.real, dtype=rdtype)
        den += np.square(k.imag)
        den += rdtype.type(1.0 / snr)
        np.conjugate(k, out=k)
        np.divide(k, den, out=out[f0:f1, :, :q])
        out[f0:f1, :, q:] = out[f0:f1, :, n - 1:0:-1]  # kx = 2n − k ↔ k (even in kx)
    return out


def apply_kernel(f: np.ndarray, half: np.ndarray) -> None:
    """f (F, 2n, 2n) *= the full even kernel whose half ky = 0 … n (F, n + 1, 2n) is ``half``, in
    place (rows 2n − k, k = 1 … n − 1, reuse half's rows k)."""
    q = half.shape[1]
    f[:, :q] *= half
    f[:, q:] *= half[:, q - 2:0:-1]


class LCTSolver(NLOSSolver):
    """Light-cone transform (O'Toole 2018) on a (T, N, N) confocal volume; depth z = c·t/2.

    Cost: FFTs of a (2T, 2N, 2N) volume; the kernel's Wiener inverse (its even half,
    (T + 1, N + 1, 2N)) is cached for the last geometry (so a second volume of the same shape
    reuses it)."""

    Params = LCTParams

    def __init__(self, params=None):
        super().__init__(params)
        self._torch = None if self.params.device == "numpy" else torch_device(self.params.device, "lct")
        self._torch_cache: dict = {}

    def reconstruct(self, volume: TransientVolume) -> NLOSVolume:
        p = self.params
        dtype = np.dtype(p.dtype)
        prep = prepare(volume, "lct", dtype)
        m, n, _ = prep.data.shape
        w = p.workers
        t = (np.arange(m, dtype=dtype) / m)[:, None, None]
        data = prep.data * (t ** 4 if p.diffuse else t ** 2)  # undo the 1/r⁴ (1/r²) fall-off, r ∝ t
        a = resampling_matrix(m).astype(dtype)
        inv = self._kernel(m, n, prep.dx, prep.dy, prep.bin_length, p.snr, dtype, w)
        if self._torch is not None:
            return prep.result(lct_torch(data, a, inv, self._torch, self._torch_cache))
        data = (a @ data.reshape(m, n * n)).reshape(m, n, n)
        f = sfft.rfft(data, n=2 * m, axis=0, workers=w)
        del data
        f = sfft.fft(f, n=2 * n, axis=1, workers=w, overwrite_x=True)
        f = sfft.fft(f, n=2 * n, axis=2, workers=w, overwrite_x=True)
        apply_kernel(f, inv)
        f = sfft.ifft(f, axis=2, workers=w, overwrite_x=True)[:, :, :n]
        f = sfft.ifft(f, axis=1, workers=w)[:, :n, :]
        vol = sfft.irfft(f, n=2 * m, axis=0, workers=w)[:m]
        del f
        vol = (a.T @ np.ascontiguousarray(vol).reshape(m, n * n)).reshape(m, n, n)
        return prep.result(vol)

    def _kernel(self, m, n, dx, dy, bin_length, snr, dtype, workers) -> np.ndarray:
        key = (m, n, dx, dy, bin_length, snr, np.dtype(dtype).str)
        cached = getattr(self, "_kernel_cache", None)
        if cached is None or cached[0] != key:
            cached = (key, lct_kernel_fft(m, n, dx, dy, bin_length, snr, dtype, workers))
            self._kernel_cache = cached
        return cached[1]
