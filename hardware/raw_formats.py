"""Byte layouts of raw radar recordings: DCA1000-style ``.bin`` streams and ``.npy``/``.npz``/HDF5 cubes.

DCA1000 ``.bin`` (TI mmWave Studio / DCA1000 CLI captures) is a flat little-endian int16 stream,
frame after frame, chirp after chirp in transmission order (loop m, TDM slot i). Within one
chirp the samples arrive in the LVDS lane order of the device family:

* ``lanes = 2`` (xWR16xx/18xx/68xx): the chirp's receivers one after another, N samples each; complex
  samples come in groups of four int16, ``I(n), I(n+1), Q(n), Q(n+1)``; real samples one int16 each.
* ``lanes = 4`` (xWR12xx/14xx): sample after sample, the four lanes side by side; complex samples come
  in groups of eight int16, ``I(lane 0..3), Q(lane 0..3)``; real samples four int16 (one per lane).
  Four lanes are always present; receivers beyond ``n_rx`` are unused lanes (zeros).

Two settings change the order of the complex words inside a group (``[recording]``):
``iq_interleave = "samples"`` pairs each I with its own Q (2 lanes ``I(n), Q(n), I(n+1), Q(n+1)``; 4
lanes ``I(lane 0), Q(lane 0), I(lane 1) …``), as readers that save complex samples as int16 pairs
write them; ``iq_order = "qi"`` puts Q where the order has I and I where it has Q. A word's code is
``encoding``: ``"twos_complement"`` (signed int16, the DCA1000's) or ``"offset_binary"`` (0 … 65535
with 32768 meaning 0, as TSW1400-style capture cards store it; :func:`signed_words` converts).
Offset-binary words read as signed int16 wrap: a code u ≥ 32768 (a value u − 32768 ≥ 0) reads as
u − 65536, so subtracting 32768 from the signed words (``adc_offset``) is wrong by 65536 for every
non-negative sample; the conversion flips the top bit instead.

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


def signed_words(words, encoding: str = "twos_complement") -> np.ndarray:
    """16-bit codes → signed values [ADC counts]: unchanged for ``"twos_complement"``; for
    ``"offset_binary"`` the unsigned code u (int16 or uint16 storage, read bit for bit) gives u − 32768.

    Raises InputError when ``encoding`` is offset binary and the words are not 16-bit integers."""
    w = np.asarray(words)
    if encoding == "twos_complement":
        return w
    if encoding != "offset_binary":
        raise ConfigError(f"recording.encoding must be 'twos_complement' or 'offset_binary', got {encoding!r}")
    if w.dtype not in (np.dtype("<i2"), np.dtype(">i2"), np.dtype("<u2"), np.dtype(">u2")):
        raise InputError(f"recording.encoding = 'offset_binary' reads 16-bit codes; the samples are {w.dtype}")
    v = w.astype(np.int32)
    return v - 32768 if w.dtype.kind == "u" else v ^ -32768  # flipping bit 15 of a signed word: u − 32768


def offset_binary_words(signed) -> np.ndarray:
    """Signed int16 values → their offset-binary codes stored as int16 words (the inverse of
    :func:`signed_words` for ``"offset_binary"``; tests, emulators)."""
    return (np.asarray(signed).astype(np.int16).view(np.uint16) ^ np.uint16(0x8000)).view("<i2")


def _iq_columns(n_lanes: int, iq_order: str, iq_interleave: str) -> tuple[np.ndarray, np.ndarray]:
    """Positions of I and Q of each lane inside one group of 2·n_lanes words."""
    lane = np.arange(n_lanes)
    first, second = (lane, lane + n_lanes) if iq_interleave == "lanes" else (2 * lane, 2 * lane + 1)
    if iq_interleave not in ("lanes", "samples"):
        raise ConfigError(f"recording.iq_interleave must be 'lanes' or 'samples', got {iq_interleave!r}")
    if iq_order not in ("iq", "qi"):
        raise ConfigError(f"recording.iq_order must be 'iq' or 'qi', got {iq_order!r}")
    return (first, second) if iq_order == "iq" else (second, first)


def decode_dca1000(words, n_samples: int, n_slots: int, n_rx: int, sampling: str, lanes: int,
                   iq_order: str = "iq", iq_interleave: str = "lanes") -> np.ndarray:
    """One frame's int16 words (1-D, :func:`dca1000_frame_words` long) → (n_samples, n_slots, n_rx)
    complex128 [ADC counts], or float64 for real sampling (see :func:`analytic_signal`).

    ``iq_order`` ("iq" | "qi") and ``iq_interleave`` ("lanes" | "samples") order the complex words
    (module doc). Raises InputError on a wrong word count, ConfigError when ``lanes`` = 4 and n_rx > 4.
    """
    if lanes == 4 and n_rx > 4:
        raise ConfigError(f"DCA1000 lanes = 4 carries at most 4 receivers, the radar has n_rx={n_rx}")
    w = np.asarray(words)
    want = dca1000_frame_words(n_samples, n_slots, n_rx, sampling, lanes)
    if w.ndim != 1 or w.size != want:
        raise InputError(f"DCA1000 frame: expected {want} int16 words (n_samples={n_samples}, chirps={n_slots}, "
                         f"n_rx={n_rx}, {sampling}, {lanes} lanes), got shape {w.shape}")
    w = w.astype(np.float64)
    if sampling == "complex":
        width = 2 if lanes == 2 else 4  # samples (2 lanes) or receivers (4 lanes) per group
        i_col, q_col = _iq_columns(width, iq_order, iq_interleave)
        g = w.reshape(-1, 2 * width)
        z = (g[:, i_col] + 1j * g[:, q_col]).reshape(-1)
    else:
        z = w
    if lanes == 2:
        return np.transpose(z.reshape(n_slots, n_rx, n_samples), (2, 0, 1))  # (sample, slot, rx)
    return np.transpose(z.reshape(n_slots, n_samples, 4)[:, :, :n_rx], (1, 0, 2))


def encode_dca1000(cube, sampling: str, lanes: int, iq_order: str = "iq", iq_interleave: str = "lanes") -> np.ndarray:
    """(n_samples, n_slots, n_rx) counts (complex, or real for ``sampling`` = "real") → one frame's int16
    words in the DCA1000 order of :func:`decode_dca1000` (same ``iq_order``, ``iq_interleave``). Values
    are rounded and must fit int16 (InputError otherwise: nothing is clipped silently)."""
    c = np.asarray(cube)
    n, s, r = c.shape
    parts = (c.real, c.imag) if sampling == "complex" else (c.real,)
    for p in parts:
        if np.abs(np.rint(p)).max(initial=0) > 32767:
            raise InputError("encode_dca1000: values exceed the int16 range; lower the scale")
    if lanes == 2:
        z = np.transpose(c, (1, 2, 0)).reshape(-1)  # (slot, rx, sample)
    else:
        if r > 4:
            raise InputError(f"encode_dca1000: lanes = 4 carries at most 4 receivers, got {r}")
        full = np.zeros((s, n, 4), dtype=c.dtype)
        full[:, :, :r] = np.transpose(c, (1, 0, 2))
        z = full.reshape(-1)
    if sampling != "complex":
        return np.rint(z.real).astype("<i2")
    width = 2 if lanes == 2 else 4
    i_col, q_col = _iq_columns(width, iq_order, iq_interleave)
    zg = z.reshape(-1, width)
    g = np.empty((zg.shape[0], 2 * width))
    g[:, i_col] = zg.real
    g[:, q_col] = zg.imag
    return np.rint(g.reshape(-1)).astype("<i2")


def swap_iq(x: np.ndarray, sample_format: str) -> np.ndarray:
    """Samples stored Q first (``iq_order = "qi"``) → I first: the trailing I/Q axis reversed
    (``sample_format = "iq"``), or real and imaginary parts exchanged (complex dtype, Q + jI → I + jQ)."""
    if sample_format == "iq":
        return x[..., ::-1]
    return x.imag + 1j * x.real


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
