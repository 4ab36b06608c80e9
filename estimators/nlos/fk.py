"""f-k migration of confocal NLOS transients (Lindell, Wetzstein, O'Toole, SIGGRAPH 2019), the "fk"
nlos_solver of the cross-modality comparison (Sec. 5.1.2, Fig. 5).

The confocal measurement is a wave field recorded on the wall from "exploding reflectors" with
speed c/2. In the Fourier domain a field sampled at temporal frequency f_t on the wall comes from
depth frequency f_z with f_t = √(f_z² + (b_x·f_x)² + (b_y·f_y)²) (Stolt 1978), b = (c·Δt/2)/Δx in
sample units. The solver: amplitude ψ = √τ·t (undoing the 1/r⁴ intensity fall-off to the 1/r of a
wave), FFT padded to 2× (scipy.fft, rfft along t), Stolt interpolation along f_t (linear) with the
Jacobian f_z/f_t, inverse FFT, albedo |ψ|².
"""
from __future__ import annotations

import numpy as np
import scipy.fft as sfft
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.interfaces import NLOSSolver
from xnlos_core.nlos_volume import NLOSVolume
from xnlos_core.transient import TransientVolume

from .prep import prepare
from .torch_backend import device_field, fk_torch, torch_device


class FKParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    dtype: str = Field("float32", pattern="^(float32|float64)$",
                       description="working precision of the FFTs: float32 (complex64) or float64")
    workers: int = Field(-1, description="scipy.fft worker threads (-1: all cores)")
    chunk: int = Field(64, ge=1, description="depth-frequency rows per Stolt interpolation chunk "
                                             "(bounds the temporary memory)")
    device: str = device_field()


def stolt(f: np.ndarray, bx: float, by: float, chunk: int = 64) -> np.ndarray:
    """Stolt interpolation of ``f`` (m + 1, 2n, 2n): rfft bins 0 … m along t (axis 0), fft bins
    along y, x. out[k, i, j] = (k/q)·f(q, i, j) with q = √(k² + (b_y·ν_i)² + (b_x·ν_j)²) [bins],
    ν the signed fft bin index, f(q) linear between bins, 0 where q > m − 1 and at k = 0 and m."""
    m = f.shape[0] - 1
    ny, nx = f.shape[1:]
    nu_y = np.fft.fftfreq(ny, 1.0 / ny)
    nu_x = np.fft.fftfreq(nx, 1.0 / nx)
    real = f.real.dtype
    rho2 = ((by * nu_y[:, None]) ** 2 + (bx * nu_x[None, :]) ** 2).astype(real)
    plane = ny * nx
    pix = np.arange(plane, dtype=np.int64).reshape(ny, nx)
    flat = f.reshape(-1)
    out = np.zeros_like(f)
    for k0 in range(1, m, chunk):
        k = np.arange(k0, min(k0 + chunk, m), dtype=real)[:, None, None]
        q = np.sqrt(k * k + rho2)
        ok = q <= m - 1
        if not ok.any():
            break  # q grows with k: every later chunk is out of range too
        q0 = np.minimum(q, m - 1).astype(np.int64)
        frac = np.where(ok, q - q0, 0).astype(real)
        idx = q0 * plane + pix
        val = flat[idx]
        val *= 1 - frac
        val += flat[np.minimum(idx + plane, flat.size - 1)] * frac
        val *= np.where(ok, k / q, 0).astype(real)
        out[k0:k0 + k.shape[0]] = val
    return out


class FKSolver(NLOSSolver):
    """f-k migration (Lindell 2019) on a (T, N, N) confocal volume; depth z = c·t/2.

    Memory: two (T + 1, 2N, 2N) complex arrays (complex64 by default: 0.27 GB each at
    T = 2048, N = 64) and chunked interpolation temporaries."""

    Params = FKParams

    def __init__(self, params=None):
        super().__init__(params)
        self._torch = None if self.params.device == "numpy" else torch_device(self.params.device, "fk")

    def reconstruct(self, volume: TransientVolume) -> NLOSVolume:
        p = self.params
        dtype = np.dtype(p.dtype)
        prep = prepare(volume, "fk", dtype)
        m, n, _ = prep.data.shape
        w = p.workers
        t = (np.arange(m, dtype=dtype) / m)[:, None, None]
        psi = np.sqrt(prep.data) * t  # wave amplitude: √(1/r⁴) · r = 1/r
        # b = (c·Δt/2)/Δx in bins of the padded grids: 2m along t, 2n along x, y
        bx = m * prep.bin_length / (2 * n * prep.dx)
        by = m * prep.bin_length / (2 * n * prep.dy)
        if self._torch is not None:
            return prep.result(fk_torch(psi, bx, by, p.chunk, self._torch))
        f = sfft.rfft(psi, n=2 * m, axis=0, workers=w)
        del psi
        f = sfft.fft(f, n=2 * n, axis=1, workers=w, overwrite_x=True)
        f = sfft.fft(f, n=2 * n, axis=2, workers=w, overwrite_x=True)
        g = stolt(f, bx, by, p.chunk)
        del f
        g = sfft.ifft(g, axis=2, workers=w, overwrite_x=True)[:, :, :n]
        g = sfft.ifft(g, axis=1, workers=w)[:, :n, :]
        g = sfft.ifft(g, n=2 * m, axis=0, workers=w)[:m]  # one-sided in f_t: complex field
        return prep.result(g.real ** 2 + g.imag ** 2)
