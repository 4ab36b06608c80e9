"""Optional torch backend of the NLOS solvers ("optionally torch on a GPU").

The solvers' ``device`` parameter: "numpy" (default: scipy.fft, this package's reference path),
"cpu" or "cuda" (torch.fft on that torch device). The torch path runs the same algorithm step for
step — same radiometric weights, the same LCT resampling matrix (as a torch sparse CSR matrix) and
Wiener kernel (built once by scipy, :func:`estimators.nlos.lct.lct_kernel_fft`, then moved to the
device and cached), the same f-k Stolt interpolation — so its output equals the numpy path's to
rounding (tests/unit/test_nlos_solvers.py: 1e-5 of the peak on torch-cpu).

torch is imported inside the functions here, never at registration (start-up stays cheap,
tests/unit/test_startup_imports.py).
"""
from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from pydantic import Field

from xnlos_core.errors import ConfigError

DEVICE_PATTERN = "^(numpy|cpu|cuda)$"


def device_field() -> Any:
    """The ``device`` Field shared by the solvers' Params."""
    return Field("numpy", pattern=DEVICE_PATTERN,
                 description='"numpy" (scipy.fft, default) | "cpu" | "cuda" (torch.fft on that torch device; '
                             'cuda only where torch sees a GPU)')


def torch_device(name: str, solver: str):
    """The torch.device for ``name`` ("cpu" | "cuda"); ConfigError naming the device where torch
    cannot use it (no CUDA build or no GPU visible)."""
    import torch

    if name == "cuda" and not torch.cuda.is_available():
        raise ConfigError(f"{solver}: params.device = 'cuda' but torch {torch.__version__} sees no CUDA GPU "
                          f"(torch.cuda.is_available() is False); use device = 'cpu' or 'numpy'")
    if name not in ("cpu", "cuda"):
        raise ConfigError(f"{solver}: params.device = {name!r}; expected 'numpy', 'cpu' or 'cuda'")
    return torch.device(name)


def _to_numpy(x) -> np.ndarray:
    return x.detach().to("cpu").numpy()


def lct_torch(data: np.ndarray, a, inv_half: np.ndarray, dev, cache: dict) -> np.ndarray:
    """LCT of ``data`` (m, n, n), already radiometrically compensated, on torch device ``dev``:
    resample t → v with ``a`` (scipy CSR (m, m)), Wiener-deconvolve with the kernel half
    ``inv_half`` ((m + 1, n + 1, 2n) complex, :func:`estimators.nlos.lct.lct_kernel_fft`), resample
    u → z with aᵀ. Returns the (m, n, n) albedo (before clipping at 0) as numpy, ``data``'s dtype.

    ``cache`` holds the device copies of a, aᵀ and the kernel for the key stored with them."""
    import torch

    m, n, _ = data.shape
    key = (id(inv_half), str(dev), m)
    if cache.get("key") != key:
        def csr(s):
            s = s.tocsr()
            with warnings.catch_warnings():  # "Sparse CSR tensor support is in beta state"
                warnings.filterwarnings("ignore", message="Sparse CSR tensor support", category=UserWarning)
                return torch.sparse_csr_tensor(torch.from_numpy(s.indptr.astype(np.int64)),
                                               torch.from_numpy(s.indices.astype(np.int64)),
                                               torch.from_numpy(s.data), size=s.shape, device=dev,
                                               check_invariants=True)
        cache.clear()
        cache.update(key=key, a=csr(a), at=csr(a.T), inv=torch.from_numpy(inv_half).to(dev))
    a_t, at_t, inv = cache["a"], cache["at"], cache["inv"]
    x = torch.from_numpy(data).to(dev)
    x = (a_t @ x.reshape(m, n * n)).reshape(m, n, n)
    f = torch.fft.rfft(x, n=2 * m, dim=0)
    del x
    f = torch.fft.fft(f, n=2 * n, dim=1)
    f = torch.fft.fft(f, n=2 * n, dim=2)
    q = inv.shape[1]
    f[:, :q] *= inv
    f[:, q:] *= torch.flip(inv[:, 1:q - 1], dims=(1,))  # rows 2n − k ↔ k, k = n − 1 … 1
    f = torch.fft.ifft(f, dim=2)[:, :, :n]
    f = torch.fft.ifft(f, dim=1)[:, :n, :]
    v = torch.fft.irfft(f, n=2 * m, dim=0)[:m].contiguous()
    del f
    out = (at_t @ v.reshape(m, n * n)).reshape(m, n, n)
    return _to_numpy(out)


def stolt_torch(f, bx: float, by: float, chunk: int):
    """:func:`estimators.nlos.fk.stolt` in torch (same rows, same linear interpolation, same zeros)."""
    import torch

    m = f.shape[0] - 1
    ny, nx = f.shape[1:]
    dev = f.device
    real = f.real.dtype
    nu_y = torch.fft.fftfreq(ny, 1.0 / ny, dtype=torch.float64, device=dev)
    nu_x = torch.fft.fftfreq(nx, 1.0 / nx, dtype=torch.float64, device=dev)
    rho2 = ((by * nu_y[:, None]) ** 2 + (bx * nu_x[None, :]) ** 2).to(real)
    plane = ny * nx
    pix = torch.arange(plane, dtype=torch.int64, device=dev).reshape(ny, nx)
    flat = f.reshape(-1)
    out = torch.zeros_like(f)
    for k0 in range(1, m, chunk):
        k = torch.arange(k0, min(k0 + chunk, m), dtype=real, device=dev)[:, None, None]
        q = torch.sqrt(k * k + rho2)
        ok = q <= m - 1
        if not bool(ok.any()):
            break  # q grows with k: every later chunk is out of range too
        q0 = torch.clamp(q, max=m - 1).to(torch.int64)
        frac = torch.where(ok, q - q0, torch.zeros((), dtype=real, device=dev))
        idx = (q0 * plane + pix).reshape(-1)
        shape = q.shape
        # index_select on the flat view: several times faster than advanced indexing on torch-cpu
        val = torch.index_select(flat, 0, idx).reshape(shape) * (1 - frac)
        val += torch.index_select(flat, 0, torch.clamp(idx + plane, max=flat.numel() - 1)).reshape(shape) * frac
        val *= torch.where(ok, k / q, torch.zeros((), dtype=real, device=dev))
        out[k0:k0 + k.shape[0]] = val
    return out


def fk_torch(psi: np.ndarray, bx: float, by: float, chunk: int, dev) -> np.ndarray:
    """f-k migration of the wave amplitude ``psi`` (m, n, n) on torch device ``dev`` (the numpy
    path of :class:`estimators.nlos.fk.FKSolver` step for step); returns |ψ_out|² (m, n, n) numpy."""
    import torch

    m, n, _ = psi.shape
    x = torch.from_numpy(psi).to(dev)
    f = torch.fft.rfft(x, n=2 * m, dim=0)
    del x
    f = torch.fft.fft(f, n=2 * n, dim=1)
    f = torch.fft.fft(f, n=2 * n, dim=2)
    g = stolt_torch(f, bx, by, chunk)
    del f
    g = torch.fft.ifft(g, dim=2)[:, :, :n]
    g = torch.fft.ifft(g, dim=1)[:, :n, :]
    g = torch.fft.ifft(g, n=2 * m, dim=0)[:m]
    return _to_numpy(g.real ** 2 + g.imag ** 2)
