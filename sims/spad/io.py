"""Transient files: the Stanford confocal ``.mat`` layout and a subset of the Zaragoza NLOS HDF5 layout.

Confocal ``.mat`` (O'Toole et al. 2018, LCT; Lindell et al. 2019, f-k migration datasets):

* ``rect_data`` (or ``meas``, or ``data``): the counts, either N × N × T — MATLAB's (x, y, t), the
  released datasets' order — or T × N × N, read as (t, y, x). The time axis is the one whose
  length differs from the two equal spatial ones; a cube (T = N) is ambiguous and needs
  ``time_axis`` = "first" or "last". The grid must be square (the layout holds one width).
* ``width``: HALF the scanned wall's width [m] (the scan spans [−width, width] in x and y).
* ``bin_resolution``: bin width [s] (absent in some releases: pass ``bin_width``).
We write ``rect_data`` as N × N × T (x, y, t), ``width``, ``bin_resolution``, and ``t0`` [s].

HDF5 (subset of the Zaragoza NLOS dataset format, Galindo et al. 2019; confocal only):

* ``data`` (T, H, W) counts (C order; the full format's bounce and illumination axes are not
  written, and a leading axis of length 1 is squeezed on reading);
* ``deltaT``: path length per bin [m] (c·Δt, as in that format);
* ``cameraGridSize``: (wall_width, wall_height) [m]; ``cameraGridPoints``: (W, H);
* ``t0``: path length of bin 0 [m] (c·t0; 0 when absent); ``isConfocal``: 1.

Readers refuse NaN/inf, negative and all-zero counts, missing metadata, and a ``bin_width`` that
disagrees with the file (relative tolerance 1e-6) with :class:`~xnlos_core.errors.InputError`
naming the file and the variable. Files are read as :mod:`xnlos_core.datafiles` reads data: regular
files only (a FIFO or device is refused before a byte is read), HDF5 files self-contained (an
external link, external storage or a virtual dataset is refused: they would read other files),
declared sizes checked before allocation (at most :data:`xnlos_core.datafiles.MAX_ARRAY_BYTES` per
variable), and damaged files (a corrupt compressed chunk, a truncated header) refused with an
InputError naming the file, never a library traceback.
"""
from __future__ import annotations

from pathlib import Path
from typing import Literal

import h5py
import numpy as np
import scipy.io

from xnlos_core.datafiles import hdf5_file, load_mat, read_hdf5_array
from xnlos_core.errors import InputError
from xnlos_core.transient import SPEED_OF_LIGHT, TransientVolume

MAT_NAMES = ("rect_data", "meas", "data")
RTOL = 1e-6


def _volume(src: str, var: str, data: np.ndarray, bin_width: float, wall_width: float, wall_height: float,
            t0: float) -> TransientVolume:
    if data.dtype.kind not in "fiub":
        raise InputError(f"{src}: {var} expected numeric counts, got dtype {data.dtype}")
    data = np.asarray(data, np.float64)
    if not np.all(np.isfinite(data)):
        bad = int(data.size - np.count_nonzero(np.isfinite(data)))
        raise InputError(f"{src}: {var} holds {bad} NaN or infinite values; counts must be finite")
    if data.size and not np.any(data):
        raise InputError(f"{src}: {var} is all zeros; expected a measurement with photon counts")
    try:
        return TransientVolume(data, bin_width, wall_width, wall_height, t0)
    except InputError as exc:
        raise InputError(f"{src}: {exc}") from None


def _bin_width(src: str, var: str, in_file: float | None, given: float | None) -> float:
    if in_file is None and given is None:
        raise InputError(f"{src}: no {var} in the file; pass bin_width [s]")
    if in_file is not None and given is not None and not np.isclose(in_file, given, rtol=RTOL, atol=0):
        raise InputError(f"{src}: bin_width = {given:g} s disagrees with the file's {var} "
                         f"(= {in_file:g} s); expected the file's value or none")
    return float(in_file if in_file is not None else given)


def _scalar(src: str, name: str, value) -> float:
    try:
        a = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError, OverflowError):
        a = np.array([np.nan, np.nan])  # a string, a struct, a cell: not one number
    if a.size != 1 or not np.isfinite(a[0]):
        raise InputError(f"{src}: {name} expected one finite number, got {_short(value)}")
    return float(a[0])


def _short(value) -> str:
    """``value`` for an error message, at most 120 characters (a file can hold a large array)."""
    text = repr(value) if np.size(value) <= 16 else f"an array of shape {np.shape(value)}"
    return text if len(text) <= 120 else text[:117] + "..."


def read_mat(path: str | Path, *, bin_width: float | None = None,
             time_axis: Literal["auto", "first", "last"] = "auto") -> TransientVolume:
    """A confocal ``.mat`` file (module docstring) as a TransientVolume (T, N, N)."""
    src = str(path)
    m = load_mat(path, MAT_NAMES + ("width", "bin_resolution", "t0"), what=src)
    var = next((v for v in MAT_NAMES if v in m), None)
    if var is None:
        raise InputError(f"{src}: no measurement variable; expected one of {', '.join(MAT_NAMES)}")
    d = np.asarray(m[var])
    if d.ndim != 3:
        raise InputError(f"{src}: {var} expected a 3-D volume (N × N × T or T × N × N), got shape {d.shape}")
    a, b, c = d.shape
    if time_axis == "auto":
        if a == b == c:
            raise InputError(f"{src}: {var} of shape {d.shape} is a cube: which axis is time is ambiguous; "
                             "pass time_axis='first' or 'last'")
        time_axis = "last" if a == b else "first" if b == c else None
        if time_axis is None:
            raise InputError(f"{src}: {var} of shape {d.shape} has no square scan grid; expected N × N × T or T × N × N")
    if time_axis == "last":
        if a != b:
            raise InputError(f"{src}: {var} of shape {d.shape}: expected a square N × N × T grid")
        vol = np.transpose(d, (2, 1, 0))  # (x, y, t) → (t, y, x)
    elif time_axis == "first":
        if b != c:
            raise InputError(f"{src}: {var} of shape {d.shape}: expected a square T × N × N grid")
        vol = d
    else:
        raise InputError(f"time_axis: expected 'auto', 'first' or 'last', got {time_axis!r}")
    if "width" not in m:
        raise InputError(f"{src}: no width (half the scanned wall width [m])")
    half = _scalar(src, "width", m["width"])
    in_file = _scalar(src, "bin_resolution", m["bin_resolution"]) if "bin_resolution" in m else None
    bw = _bin_width(src, "bin_resolution", in_file, bin_width)
    t0 = _scalar(src, "t0", m["t0"]) if "t0" in m else 0.0
    return _volume(src, var, vol, bw, 2 * half, 2 * half, t0)


def write_mat(path: str | Path, volume: TransientVolume) -> None:
    """Write ``volume`` as a confocal ``.mat`` (rect_data N × N × T, width, bin_resolution, t0);
    the grid must be square in points and extent (the layout holds one width)."""
    _, h, w = volume.shape
    if h != w or not np.isclose(volume.wall_width, volume.wall_height, rtol=RTOL):
        raise InputError(f"volume: the confocal .mat layout holds a square grid; got {h} × {w} points over "
                         f"{volume.wall_height:g} × {volume.wall_width:g} m")
    scipy.io.savemat(str(path), {"rect_data": np.transpose(volume.data, (2, 1, 0)),
                                 "width": volume.wall_width / 2, "bin_resolution": volume.bin_width,
                                 "t0": volume.t0}, do_compression=True)


def read_hdf5(path: str | Path, *, bin_width: float | None = None) -> TransientVolume:
    """An HDF5 file of the module docstring's subset as a TransientVolume."""
    src = str(path)
    small = 2**16  # a metadata dataset: a few numbers

    def meta(f, key: str, expected: str) -> np.ndarray:
        return read_hdf5_array(f, key, what=src, kinds="biuf", max_bytes=small, expected=expected).ravel()

    with hdf5_file(path, what=src) as f:
        for key in ("data", "deltaT", "cameraGridSize"):
            if key not in f:
                raise InputError(f"{src}: no {key}; expected data, deltaT [m], cameraGridSize [m]")
        d = read_hdf5_array(f, "data", what=src, kinds="biuf", expected="confocal counts (T, H, W), real numbers")
        while d.ndim > 3 and d.shape[0] == 1:
            d = d[0]
        if d.ndim != 3:
            raise InputError(f"{src}: data expected a confocal (T, H, W) volume, got shape {d.shape}")
        size = meta(f, "cameraGridSize", "(width, height) [m]").astype(np.float64)
        if size.size != 2:
            raise InputError(f"{src}: cameraGridSize expected (width, height) [m], got {_short(size)}")
        if "cameraGridPoints" in f:
            pts = meta(f, "cameraGridPoints", "(W, H) grid points")
            if pts.size != 2 or not np.all(np.isfinite(pts)) or tuple(pts.tolist()) != (d.shape[2], d.shape[1]):
                raise InputError(f"{src}: cameraGridPoints {_short(pts)} disagrees with data's (W, H) = "
                                 f"({d.shape[2]}, {d.shape[1]})")
        if "isConfocal" in f:
            flag = meta(f, "isConfocal", "1 (a confocal capture)")
            if flag.size != 1 or not flag[0]:
                raise InputError(f"{src}: isConfocal is {_short(flag)}; only confocal captures (1) are read")
        delta = _scalar(src, "deltaT", meta(f, "deltaT", "the path length per bin [m]"))
        t0 = _scalar(src, "t0", meta(f, "t0", "the path length of bin 0 [m]")) / SPEED_OF_LIGHT if "t0" in f else 0.0
    bw = _bin_width(src, "deltaT", delta / SPEED_OF_LIGHT, bin_width)
    return _volume(src, "data", d, bw, float(size[0]), float(size[1]), t0)


def write_hdf5(path: str | Path, volume: TransientVolume) -> None:
    """Write ``volume`` in the module docstring's HDF5 subset (atomically: temporary file, then rename)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    _, h, w = volume.shape
    with h5py.File(tmp, "w") as f:
        f.create_dataset("data", data=volume.data, compression="gzip")
        f["deltaT"] = volume.bin_length
        f["t0"] = volume.t0 * SPEED_OF_LIGHT
        f["cameraGridSize"] = np.array([volume.wall_width, volume.wall_height])
        f["cameraGridPoints"] = np.array([w, h], dtype=np.int64)
        f["isConfocal"] = np.int64(1)
    tmp.replace(path)
