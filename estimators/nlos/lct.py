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


class LCTParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    snr: float = Field(0.8, gt=0, description="Wiener filter signal-to-noise ratio (O'Toole's default 0.8); "
                                              "larger sharpens and amplifies noise")
    diffuse: bool = Field(True, description="compensate a 1/r⁴ (diffuse) fall-off; False: 1/r² (retroreflective)")
    dtype: str = Field("float32", pattern="^(float32|float64)$",
                       description="working precision of the FFTs: float32 (complex64) or float64")
    workers: int = Field(-1, description="scipy.fft worker threads (-1: all cores)")


@lru_cache(maxsize=4)
def resampling_matrix(m: int) -> sp.csr_matrix:
    """The (m, m) LCT resampling matrix t → v (O'Toole 2018, ``resamplingOperator``): fine bins
    x = 1 … m² of v, each taken from t bin ⌈√x⌉ with weight 1/√x, averaged over blocks of m. Its
    transpose maps back v → t (u → z). t and v both in units of the last bin (normalised to [0, 1])."""
    x = np.arange(1, m * m + 1, dtype=np.int64)
    col = np.ceil(np.sqrt(x)).astype(np.int64) - 1
    row = (x - 1) // m
    key = row * m + col  # nondecreasing in x: runs of equal (row, col) are contiguous
    starts = np.flatnonzero(np.r_[True, np.diff(key) != 0])
    vals = np.add.reduceat(1.0 / np.sqrt(x), starts) / m
    return sp.csr_matrix((vals, (row[starts], col[starts])), shape=(m, m))


def lct_kernel_fft(m: int, n: int, dx: float, dy: float, bin_length: float, snr: float, dtype,
                   workers: int) -> np.ndarray:
    """Wiener inverse conj(K̂)/(|K̂|² + 1/snr) of the shell kernel on the (2m, 2n, 2n) padded grid,
    as rfft along v (axis 0, m + 1 bins) and fft along y, x: shape (m + 1, 2n, 2n).

    K(Δy, Δx, Δv) = 1 where Δv = m·(Δx² + Δy²)/(m·bin_length/2)² (in v bins, nearest) — the shell
    of O'Toole's ``definePsf`` written with the physical scan spacing dx, dy [m] — normalised to unit
    norm. Offsets are circular (index i ↔ Δy = i·dy for i < n, (i − 2n)·dy above).
    """
    off = np.fft.fftfreq(2 * n, 1.0 / (2 * n))  # 0, 1, …, n − 1, −n, …, −1
    depth = m * bin_length / 2  # [m] the last bin's depth
    dv = m * ((off[:, None] * dy) ** 2 + (off[None, :] * dx) ** 2) / depth ** 2
    r = np.rint(dv).astype(np.int64)
    keep = r < 2 * m
    iy, ix = np.nonzero(keep)
    # rfft along v of a unit impulse at bin r is exp(−iπ·f·r/m), f = 0 … m: one phase column per
    # distinct r (few, by the shell's symmetry) instead of an FFT of the (2m, 2n, 2n) impulse volume
    shells, which = np.unique(r[keep], return_inverse=True)
    cdtype = np.result_type(dtype, np.complex64)
    phase = (np.exp((-1j * np.pi / m) * np.outer(np.arange(m + 1), shells)) / np.sqrt(keep.sum())).astype(cdtype)
    k = np.zeros((m + 1, 2 * n, 2 * n), dtype=cdtype)
    k.reshape(m + 1, -1)[:, iy * (2 * n) + ix] = phase[:, which]
    k = sfft.fftn(k, axes=(1, 2), workers=workers, overwrite_x=True)
    inv = np.conj(k)
    inv /= (k.real ** 2 + k.imag ** 2 + 1.0 / snr)
    return inv


class LCTSolver(NLOSSolver):
    """Light-cone transform (O'Toole 2018) on a (T, N, N) confocal volume; depth z = c·t/2.

    Cost: FFTs of a (2T, 2N, 2N) volume; the kernel's Wiener inverse is cached for the last
    geometry (so a second volume of the same shape reuses it)."""

    Params = LCTParams

    def reconstruct(self, volume: TransientVolume) -> NLOSVolume:
        p = self.params
        dtype = np.dtype(p.dtype)
        prep = prepare(volume, "lct", dtype)
        m, n, _ = prep.data.shape
        w = p.workers
        t = (np.arange(m, dtype=dtype) / m)[:, None, None]
        data = prep.data * (t ** 4 if p.diffuse else t ** 2)  # undo the 1/r⁴ (1/r²) fall-off, r ∝ t
        a = resampling_matrix(m).astype(dtype)
        data = (a @ data.reshape(m, n * n)).reshape(m, n, n)
        inv = self._kernel(m, n, prep.dx, prep.dy, prep.bin_length, p.snr, dtype, w)
        f = sfft.rfft(data, n=2 * m, axis=0, workers=w)
        del data
        f = sfft.fft(f, n=2 * n, axis=1, workers=w, overwrite_x=True)
        f = sfft.fft(f, n=2 * n, axis=2, workers=w, overwrite_x=True)
        f *= inv
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
