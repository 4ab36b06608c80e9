"""Byte layouts of raw radar recordings: DCA1000-style ``.bin`` streams and ``.npy``/``.npz``/HDF5 cubes.

DCA1000 ``.bin`` (TI mmWave Studio / DCA1000 CLI captures) is a flat little-endian int16 stream,
frame after frame, chirp after chirp in transmission order (loop m, TDM slot i). Within one
chirp the samples arrive in the LVDS lane order of the device family:

* ``lanes = 2`` (xWR16xx/18xx/68xx): the chirp's receivers one after another, N samples each; complex
  samples come in groups of four int16, ``I(n), I(n+1), Q(n), Q(n+1)``; real samples one int16 each.
* ``lanes = 4`` (xWR12xx/14xx): sample after sample, the four lanes side by side; complex samples come
  in groups of eight int16, ``I(lane 0..3), Q(lane 0..3)``; real samples four int16 (one per lane).
  Four lanes are always present; receivers beyond ``n_rx`` are unused lanes (zeros).

:func:`decode_dca1000` turns one frame's int16 words into (n_samples, n_chirp_slots, n_rx) complex128
counts; :func:`dca1000_frame_words` is the number of int16 words per frame. :func:`encode_dca1000` is the
inverse (tests, emulators). Real-only samples are made complex by :func:`analytic_signal` (positive
frequencies only, the complex chain then sees the same beat tones; range is unambiguous up to half the
complex-sampling range). Cubes in ``.npy``/``.npz``/``.h5`` files are read by :func:`load_cube`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from xnlos_core.datafiles import hdf5_file, load_npy, load_npz_array, read_hdf5_array
from xnlos_core.errors import ConfigError, InputError


def dca1000_frame_words(n_samples: int, n_slots: int, n_rx: int, sampling: str, lanes: int) -> int:
    """int16 words of one frame: n_slots chirps × receivers (4 lanes when ``lanes`` = 4) × samples × (2 if complex)."""
    width = 4 if lanes == 4 else n_rx
    return n_samples * n_slots * width * (2 if sampling == "complex" else 1)


def decode_dca1000(words, n_samples: int, n_slots: int, n_rx: int, sampling: str, lanes: int) -> np.ndarray:
    """One frame's int16 words (1-D, :func:`dca1000_frame_words` long) → (n_samples, n_slots, n_rx)
    complex128 [ADC counts], or float64 for real sampling (see :func:`analytic_signal`).

    Raises InputError on a wrong word count, ConfigError when ``lanes`` = 4 and n_rx > 4.
    """
    if lanes == 4 and n_rx > 4:
        raise ConfigError(f"DCA1000 lanes = 4 carries at most 4 receivers, the radar has n_rx={n_rx}")
    w = np.asarray(words)
    want = dca1000_frame_words(n_samples, n_slots, n_rx, sampling, lanes)
    if w.ndim != 1 or w.size != want:
        raise InputError(f"DCA1000 frame: expected {want} int16 words (n_samples={n_samples}, chirps={n_slots}, "
                         f"n_rx={n_rx}, {sampling}, {lanes} lanes), got shape {w.shape}")
    w = w.astype(np.float64)
    if lanes == 2:
        if sampling == "complex":
            g = w.reshape(-1, 4)  # I(n), I(n+1), Q(n), Q(n+1)
            z = np.empty(w.size // 2, dtype=np.complex128)
            z[0::2] = g[:, 0] + 1j * g[:, 2]
            z[1::2] = g[:, 1] + 1j * g[:, 3]
        else:
            z = w
        return np.transpose(z.reshape(n_slots, n_rx, n_samples), (2, 0, 1))  # (sample, slot, rx)
    if sampling == "complex":
        g = w.reshape(n_slots, n_samples, 2, 4)  # per sample: I(lanes), Q(lanes)
        z = g[:, :, 0, :] + 1j * g[:, :, 1, :]
    else:
        z = w.reshape(n_slots, n_samples, 4)
    return np.transpose(z[:, :, :n_rx], (1, 0, 2))


def encode_dca1000(cube, sampling: str, lanes: int) -> np.ndarray:
    """(n_samples, n_slots, n_rx) counts (complex, or real for ``sampling`` = "real") → one frame's int16
    words in the DCA1000 order of :func:`decode_dca1000`. Values are rounded and must fit int16
    (InputError otherwise: nothing is clipped silently)."""
    c = np.asarray(cube)
    n, s, r = c.shape
    parts = (c.real, c.imag) if sampling == "complex" else (c.real,)
    for p in parts:
        if np.abs(np.rint(p)).max(initial=0) > 32767:
            raise InputError("encode_dca1000: values exceed the int16 range; lower the scale")
    if lanes == 2:
        per_chirp = np.transpose(c, (1, 2, 0)).reshape(-1)  # (slot, rx, sample)
        if sampling == "complex":
            words = np.stack([per_chirp.real[0::2], per_chirp.real[1::2], per_chirp.imag[0::2],
                              per_chirp.imag[1::2]], axis=1).reshape(-1)
        else:
            words = per_chirp.real
    else:
        if r > 4:
            raise InputError(f"encode_dca1000: lanes = 4 carries at most 4 receivers, got {r}")
        full = np.zeros((s, n, 4), dtype=c.dtype)
        full[:, :, :r] = np.transpose(c, (1, 0, 2))
        words = (np.stack([full.real, full.imag], axis=2) if sampling == "complex" else full.real).reshape(-1)
    return np.rint(words).astype("<i2")


def analytic_signal(real_cube: np.ndarray, axis: int = 0) -> np.ndarray:
    """Real samples → analytic signal (scipy.signal.hilbert) along ``axis`` (fast time), complex128.

    A real beat tone A·cos(2π f_b t + φ) becomes A·exp(j(2π f_b t + φ)) (away from the band edges), the
    complex tone the chain expects; the negative-frequency image is removed.
    """
    from scipy.signal import hilbert

    return hilbert(np.asarray(real_cube, dtype=np.float64), axis=axis)


def load_cube(path: Path, fmt: str, key: str) -> np.ndarray:
    """The array of a ``.npy`` file, of key ``key`` in a ``.npz``, or of dataset ``key`` in an HDF5 file.

    Read through :mod:`xnlos_core.datafiles`: a regular file only (a FIFO or device is refused before
    a byte is read), a self-contained HDF5 file (an external link, external storage or a virtual
    dataset is refused: it would read another file), a numeric dtype, a declared size checked
    before allocation (``.npy`` is memory-mapped and must hold what its header declares; ``.npz``
    and HDF5 arrays are read whole, at most :data:`~xnlos_core.datafiles.MAX_ARRAY_BYTES`). Raises
    InputError naming the file on a missing key, a damaged or foreign file."""
    what = f"recording {path}"
    if fmt == "npy":
        return load_npy(path, what=what)
    if fmt == "npz":
        return load_npz_array(path, key, what=what)
    with hdf5_file(path, what=what) as f:
        return read_hdf5_array(f, key, what=what, kinds="biufc",
                               expected="an ADC cube (recording.key): complex samples, or integer/float I/Q or "
                                        "real samples")
