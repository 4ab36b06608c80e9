"""Seeded fuzz of the data-file readers: raw recordings (``[recording]`` descriptions with ``.npy``,
``.npz``, HDF5 and DCA1000 ``.bin`` files, :mod:`hardware.recording`) and the SPAD transient files
(confocal ``.mat`` and HDF5, :mod:`sims.spad.io`).

The inputs are what a careless or hostile file can hold: wrong ranks (0-d cubes included), axis
lengths and dtypes (bool, float16, strings, compound, object), empty recordings, NaN/inf and
1e300 samples, non-finite or absurd description numbers (``leakage_range = inf``), truncated files,
flipped bytes (HDF5 metadata and compressed chunks, MATLAB headers and zlib streams), headers that
declare terabytes, and files that try to read others: HDF5 external links, external storage and
virtual datasets, symlinks and ``../`` paths out of the folder, FIFOs (which would block a reader
forever) and ``/dev/zero``.

Every case must end in success (an RA map or a volume, finite) or a *typed* project error
(:class:`~xnlos_core.errors.XnlosError`); a library traceback fails the test, and so does a case
that runs longer than ``CASE_SECONDS`` (a hang). Files outside the allowed folder (``outside/``, not
under the config's folder nor the working directory) hold *valid* data, so a reader that followed
a link there would succeed: every case that points outside must be refused.

Case counts come from the ``fuzz_cases`` fixture (50 in ``make test``, 10,000 in ``make fuzz``).
Each test prints its tally (``pytest -s``). Files are tiny (a 16-sample, 2-channel radar) and the
same few names are rewritten case after case.
"""
from __future__ import annotations

import collections
import contextlib
import os
import signal
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io

from hardware.raw_formats import dca1000_frame_words, load_cube
from hardware.recording import Recording
from sims.spad.io import read_hdf5, read_mat
from xnlos_core.errors import XnlosError
from xnlos_core.radar import RadarConfig
from xnlos_core.transient import SPEED_OF_LIGHT, TransientVolume

pytestmark = pytest.mark.fuzz

CASE_SECONDS = 20  # one case: a hang (a FIFO opened for reading) fails the test instead of blocking it
# Small radars: 16 samples, 2 receivers, 1 or 2 transmitters and chirp loops; max_range fits real sampling.
RADARS = [RadarConfig(n_samples=16, n_tx=t, n_rx=2, n_chirps=c, n_azimuth_bins=5, max_range=1.5)
          for t in (1, 2) for c in (1, 2)]
AXES_ORDERS = [("frame", "sample", "chirp", "channel"), ("sample", "chirp", "channel"),
               ("channel", "frame", "chirp", "sample"), ("frame", "sample", "channel"), ("sample", "channel"),
               ("chirp", "frame", "channel", "sample")]
BAD_AXES = [("frame", "sample", "chirp"), ("sample", "sample", "channel"), ("frame", "frame", "sample", "channel"), ()]


class Hung(BaseException):
    """A case ran past CASE_SECONDS (BaseException: no reader's ``except Exception`` swallows it)."""


@contextlib.contextmanager
def watchdog(seconds: float = CASE_SECONDS):
    """Raise :class:`Hung` in the main thread when the block runs longer than ``seconds``."""
    def fire(signum, frame):
        raise Hung(f"case ran longer than {seconds} s")

    old = signal.signal(signal.SIGALRM, fire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def report(name: str, tally: collections.Counter) -> None:
    print(f"\n[fuzz] {name}: {sum(tally.values())} cases, " + ", ".join(f"{k}: {v}" for k, v in sorted(tally.items())))


def outcome(fn) -> str:
    """'ok' or the XnlosError subclass name ``fn()`` ended in; anything else propagates (a test failure)."""
    try:
        with watchdog():
            fn()
    except XnlosError as exc:
        return type(exc).__name__
    return "ok"


# --- the folders: inside (the config's), outside (must never be read) ---------------------------------

def _radar_table(radar: RadarConfig) -> dict:
    return {k: v for k, v in radar.model_dump().items() if v is not None}


@pytest.fixture
def arena(tmp_path_factory, monkeypatch) -> dict[str, Path]:
    """``inside``: the config's folder, also the working directory (so the config roots are exactly
    it); ``outside``: valid recordings and volumes a followed link would read; FIFOs in both."""
    inside, outside = tmp_path_factory.mktemp("inside"), tmp_path_factory.mktemp("outside")
    monkeypatch.chdir(inside)
    radar = RADARS[0]
    cube = np.full((2, radar.n_samples, 1, radar.n_channels), 1e-3 + 1e-3j)
    with h5py.File(outside / "valid.h5", "w") as f:
        f["adc"] = cube
        f["data"] = np.ones((8, 2, 2))
        f["deltaT"] = 0.01
        f["cameraGridSize"] = [1.0, 1.0]
    np.save(outside / "valid.npy", cube)
    cube.astype("<c16").tofile(outside / "valid.raw")  # external storage would read these bytes as the cube
    np.ones(4096, "<i2").tofile(outside / "valid.bin")
    scipy.io.savemat(outside / "valid.mat", {"rect_data": np.ones((2, 2, 8)), "width": 0.5, "bin_resolution": 4e-12})
    for folder in (inside, outside):
        os.mkfifo(folder / "fifo")
    for suffix in (".h5", ".npy", ".npz", ".bin", ".mat"):
        os.mkfifo(inside / f"fifo{suffix}")
        (inside / f"out{suffix}").symlink_to(outside / f"valid{suffix if suffix not in ('.npz',) else '.npy'}")
    (inside / "zero.bin").symlink_to("/dev/zero")
    for suffix in (".h5", ".mat"):
        (inside / f"outfifo{suffix}").symlink_to(outside / "fifo")
    return {"inside": inside, "outside": outside}


# --- raw recordings ---------------------------------------------------------------------------------------

def _pick(rng, options, p=None):
    return options[int(rng.choice(len(options), p=p))]


def _spec_numbers(rng) -> dict:
    """The description's numbers: mostly sane, some non-finite, negative, zero or absurd."""
    out = {}
    if rng.random() < 0.15:
        out["scale"] = _pick(rng, [1.0, 1e-6, float(10.0 ** rng.uniform(-40, 10)), float("inf"), float("nan"), -1.0, 0.0])
    if rng.random() < 0.1:
        out["adc_offset"] = _pick(rng, [0.0, 32768.0, float("nan"), float("inf"), float(rng.uniform(-1e6, 1e6)), 1e300])
    if rng.random() < 0.15:
        out["leakage_range"] = _pick(rng, [1.0, 0.0, float("inf"), float("nan"), 1e6, -1.0, 5e-324,
                                          float(rng.uniform(0, 50)), 999.0])
    if rng.random() < 0.08:
        out["leakage_db"] = _pick(rng, [30.0, float("inf"), 0.0, float(rng.uniform(0, 400)), float("nan")])
    if rng.random() < 0.2:
        out["remove_dc"] = bool(rng.random() < 0.5)
    return out


def _cube_values(rng, shape, kind: str) -> np.ndarray:
    """Samples of ``shape``: complex, real float or integer I/Q, with adversarial magnitudes sometimes."""
    mode = rng.random()
    if mode < 0.7:
        x = rng.standard_normal(shape) * 1000
    elif mode < 0.8:
        x = np.zeros(shape)
    elif mode < 0.9:
        x = 10.0 ** rng.uniform(-300, 300, shape) * np.sign(rng.standard_normal(shape))
    else:
        x = rng.standard_normal(shape)
        if x.size:
            x.flat[rng.integers(x.size)] = _pick(rng, [np.nan, np.inf, -np.inf])
    if kind == "c":
        y = rng.standard_normal(shape) * 1000
        return (x + 1j * y).astype(_pick(rng, [np.complex128, np.complex64]))
    if kind == "i":
        with np.errstate(invalid="ignore", over="ignore"):
            return np.nan_to_num(x, nan=0.0, posinf=32767, neginf=-32768).clip(-32768, 32767).astype(
                _pick(rng, [np.int16, np.int32, np.uint16, np.int8]))
    return x.astype(_pick(rng, [np.float64, np.float32]))


def _bad_dtype(rng, shape) -> np.ndarray:
    """An array of ``shape`` whose dtype no layout accepts (or that a file format cannot hold plainly)."""
    kind = rng.integers(5)
    if kind == 0:
        return np.zeros(shape, bool)
    if kind == 1:
        return np.zeros(shape, np.float16)
    if kind == 2:
        return np.full(shape, "ab", dtype="U2")
    if kind == 3:
        return np.zeros(shape, dtype=[("re", "<f4"), ("im", "<f4"), ("x", "<i2")])
    return np.zeros(shape, np.uint64)


def _cube_for(rng, radar: RadarConfig, spec: dict) -> np.ndarray:
    """A cube in the layout ``spec`` describes for ``radar``, then perhaps made wrong."""
    axes = spec.get("axes", ("frame", "sample", "chirp", "channel"))
    iq = spec.get("sample_format") == "iq"
    real = spec.get("sampling") == "real"
    frames = int(_pick(rng, [1, 2, 3, 0], p=[0.45, 0.35, 0.15, 0.05]))
    size = {"frame": frames, "sample": radar.n_samples, "chirp": radar.n_chirps, "channel": radar.n_channels}
    shape = [size.get(a, 1) for a in axes] + ([2] if iq else [])
    mode = rng.random()
    if mode < 0.06:
        shape = []  # a 0-d cube
    elif mode < 0.12:
        shape = shape[:-1] if len(shape) > 1 else shape + [3]  # an axis missing
    elif mode < 0.16:
        shape = shape + [int(rng.integers(1, 3))]  # an axis too many
    elif mode < 0.24 and shape:
        k = int(rng.integers(len(shape)))
        shape[k] = int(rng.integers(0, 20))  # one axis of a wrong (or zero) length
    if rng.random() < 0.06:
        return _bad_dtype(rng, tuple(shape))
    kind = "i" if iq and rng.random() < 0.7 else "f" if iq or real else "c"
    if rng.random() < 0.05:
        kind = _pick(rng, ["c", "f", "i"])  # the dtype the other layout wants
    return _cube_values(rng, tuple(shape), kind)


def _write_cube(rng, path: Path, fmt: str, cube: np.ndarray, key: str) -> None:
    if fmt == "npy":
        np.save(path, cube, allow_pickle=False)
    elif fmt == "npz":
        (np.savez_compressed if rng.random() < 0.5 else np.savez)(path, **{key: cube})
    else:
        with h5py.File(path, "w") as f:
            if cube.dtype.kind == "U":
                f[key] = cube.astype("S2")
            elif cube.ndim and cube.size and rng.random() < 0.5:
                f.create_dataset(key, data=cube, chunks=True, compression=_pick(rng, ["gzip", "lzf"]),
                                 shuffle=bool(rng.random() < 0.5))
            elif rng.random() < 0.03:
                f.create_dataset(key, shape=(2**int(rng.integers(30, 45)),) + cube.shape[1:], dtype=cube.dtype
                                 if cube.dtype.kind in "biufc" else "<c8")  # declared, never stored
            else:
                f[key] = cube
            if rng.random() < 0.2:
                f.create_group("meta").attrs["note"] = "radar capture"


def _corrupt(rng, path: Path) -> str:
    """Damage the file at ``path`` (truncate, flip bytes, replace); returns what was done."""
    data = bytearray(path.read_bytes())
    mode = rng.random()
    if mode < 0.35 and data:
        path.write_bytes(bytes(data[:int(rng.integers(0, len(data)))]))
        return "truncated"
    if mode < 0.8 and data:
        for _ in range(int(rng.integers(1, 8))):
            data[int(rng.integers(len(data)))] = int(rng.integers(256))
        path.write_bytes(bytes(data))
        return "flipped"
    if mode < 0.9:
        path.write_bytes(rng.bytes(int(rng.integers(0, 4096))))
        return "random bytes"
    path.write_bytes(b"")
    return "empty"


def _hostile_recording(rng, arena, fmt: str, key: str) -> str:
    """A recording file name that points outside the folder (or at a FIFO / device); ``rec.h5`` is
    written when the link lives inside an HDF5 file. Every one of them must be refused."""
    inside, outside = arena["inside"], arena["outside"]
    suffix = {"npy": ".npy", "npz": ".npz", "hdf5": ".h5", "dca1000": ".bin"}[fmt]
    kinds = ["fifo", "symlink", "dotdot", "absolute"] + (["zero"] if fmt == "dca1000" else []) + \
            (HDF5_LINKS if fmt == "hdf5" else [])
    kind = _pick(rng, kinds)
    if kind == "fifo":
        return f"fifo{suffix}"
    if kind == "symlink":
        return f"out{suffix}"
    if kind == "dotdot":
        return os.path.relpath(outside / f"valid{'.npy' if suffix == '.npz' else suffix}", inside)
    if kind == "absolute":
        return str(outside / f"valid{'.npy' if suffix == '.npz' else suffix}")
    if kind == "zero":
        return "zero.bin"
    _hostile_hdf5(rng, arena, kind, key)
    return "rec.h5"


HDF5_LINKS = ["external_link", "external_link_fifo", "external_storage", "external_storage_fifo", "virtual"]


def _hostile_hdf5(rng, arena, kind: str, key: str) -> None:
    """Write ``rec.h5`` whose dataset ``key`` (or another one, in a group) reads outside the file:
    ``kind`` is one of HDF5_LINKS."""
    inside, outside = arena["inside"], arena["outside"]
    radar = RADARS[0]
    shape = (2, radar.n_samples, 1, radar.n_channels)
    with h5py.File(inside / "rec.h5", "w") as f:
        where = f.create_group("g") if rng.random() < 0.3 else f
        name = key if where is f else "hidden"
        if kind == "external_link":
            where[name] = h5py.ExternalLink(str(outside / "valid.h5"), "/adc")
        elif kind == "external_link_fifo":
            where[name] = h5py.ExternalLink(str(outside / "fifo"), "/adc")
        elif kind.startswith("external_storage"):
            target = outside / ("fifo" if kind.endswith("fifo") else "valid.raw")
            where.create_dataset(name, shape, "<c16", external=[(str(target), 0, int(np.prod(shape)) * 16)])
        else:
            layout = h5py.VirtualLayout(shape, "<c16")
            layout[:] = h5py.VirtualSource(str(outside / "valid.h5"), "adc", shape)
            where.create_virtual_dataset(name, layout)
        if where is not f:
            f[key] = np.full(shape, 1e-3 + 0j)  # the recording itself is fine: the link elsewhere is refused


def recording_case(rng, arena) -> tuple[dict, bool, str]:
    """(description table, points outside, label) of one generated recording."""
    radar = _pick(rng, RADARS)
    fmt = _pick(rng, ["npy", "npz", "hdf5", "dca1000"])
    spec: dict = {"format": fmt, **_spec_numbers(rng)}
    if rng.random() < 0.25:
        spec["sampling"] = "real"
    if fmt != "dca1000":
        if rng.random() < (0.4 if spec.get("sampling") != "real" else 0.03):
            spec["sample_format"] = "iq"
        if rng.random() < 0.5:
            spec["axes"] = list(_pick(rng, AXES_ORDERS if rng.random() < 0.95 else BAD_AXES))
        if rng.random() < 0.3:
            spec["channel_order"] = "rx_major"
    else:
        spec["lanes"] = int(_pick(rng, [2, 4]))
    key = "adc" if rng.random() < 0.9 else _pick(rng, ["frames", "x/y", "data"])
    spec["key"] = key
    if rng.random() < 0.02:
        spec["gain"] = 3  # an unknown key
    table = {"recording": spec, "radar": _radar_table(radar)}
    if rng.random() < 0.1:
        spec["file"] = _hostile_recording(rng, arena, fmt, key)
        return table, True, "outside"
    inside = arena["inside"]
    if fmt == "dca1000":
        path = inside / "rec.bin"
        n_rx = radar.n_channels // radar.n_tdm
        words = dca1000_frame_words(radar.n_samples, radar.n_chirps * radar.n_tdm, n_rx,
                                    spec.get("sampling", "complex"), spec["lanes"])
        n = int(_pick(rng, [words, 2 * words, 3 * words + int(rng.integers(1, words)), int(rng.integers(0, words)), 0],
                      p=[0.4, 0.3, 0.15, 0.1, 0.05]))
        (rng.integers(-32768, 32768, n).astype("<i2") if rng.random() < 0.9
         else np.zeros(n, "<i2")).tofile(path)
    else:
        path = inside / {"npy": "rec.npy", "npz": "rec.npz", "hdf5": "rec.h5"}[fmt]
        _write_cube(rng, path, fmt, _cube_for(rng, radar, spec), "adc" if rng.random() < 0.97 else "other")
    label = "file"
    if rng.random() < 0.15:
        label = _corrupt(rng, path)
    spec["file"] = path.name
    return table, False, label


def _open_and_read(table: dict, folder: Path) -> None:
    rec = Recording.from_table(table, "fuzz.toml", folder)
    assert rec.n_frames >= 1
    ra = rec.check(0)
    assert np.all(np.isfinite(ra.data))
    last = rec.ra_map(rec.n_frames - 1)
    assert np.all(np.isfinite(last.data))


def test_raw_recordings(arena, fuzz_cases):
    """Generated descriptions and files: an RA map of every frame read, or an XnlosError; every file
    outside the folder (or a FIFO, /dev/zero, an HDF5 link or external storage) refused."""
    rng = np.random.default_rng(270)
    tally = collections.Counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # RecordingWarnings and numpy's: the outcome is what is checked
        for _ in range(fuzz_cases):
            table, hostile, label = recording_case(rng, arena)
            result = outcome(lambda: _open_and_read(table, arena["inside"]))
            if hostile:
                assert result != "ok", f"read a file outside the folder: {table['recording']}"
            tally[f"{label}: {result}"] += 1
    report("raw recordings", tally)


def test_cube_loaders_refuse_fifos_and_links_directly(arena, fuzz_cases):
    """load_cube itself (no description, no path rule): a FIFO or /dev/zero is refused before it is
    opened for reading, and an HDF5 file that points outside is refused, whatever the order."""
    rng = np.random.default_rng(271)
    inside = arena["inside"]
    tally = collections.Counter()
    for _ in range(max(fuzz_cases // 10, 10)):
        fmt = _pick(rng, ["npy", "npz", "hdf5"])
        target = _pick(rng, ["fifo", "zero"] + (HDF5_LINKS if fmt == "hdf5" else []))
        if target == "fifo":
            path = inside / "fifo"
        elif target == "zero":
            path = Path("/dev/zero")
        else:
            _hostile_hdf5(rng, arena, target, "adc")
            path = inside / "rec.h5"
        result = outcome(lambda: load_cube(path, fmt, "adc"))
        assert result == "InputError", (fmt, target, result)
        tally[f"{fmt} {target}: {result}"] += 1
    report("load_cube on FIFOs, devices, links", tally)


# --- SPAD transient files ---------------------------------------------------------------------------------

def _volume_fields(rng) -> dict:
    """Valid Zaragoza-subset HDF5 fields of a small confocal volume."""
    t, n = int(rng.integers(4, 12)), int(rng.integers(1, 4))
    data = rng.poisson(3.0, (t, n, n)).astype(float) + 1
    return {"data": data, "deltaT": 32e-12 * SPEED_OF_LIGHT, "cameraGridSize": np.array([1.0, 1.0]),
            "cameraGridPoints": np.array([n, n], np.int64), "t0": 0.1, "isConfocal": np.int64(1)}


def _bad_value(rng, value):
    """A wrong version of ``value``: another rank, dtype, non-finite, negative, zero or a string."""
    v = np.asarray(value)
    kind = rng.integers(11)
    if kind == 0:
        return "not a number"
    if kind == 1:
        return np.full(v.shape, np.nan)
    if kind == 2:
        return -np.abs(v) - 1
    if kind == 3:
        return np.zeros(v.shape)
    if kind == 4:
        return np.float64(1.0)  # 0-d
    if kind == 5:
        return np.ones((2,) * int(rng.integers(1, 6)))
    if kind == 6:
        return v.astype(np.complex128)
    if kind == 7:
        return v.astype(bool)
    if kind == 8:
        return np.zeros(v.shape, dtype=[("a", "<f8"), ("b", "<i4")])
    if kind == 9:
        return v[None, None]  # leading axes of length 1
    return np.ones((0,) + v.shape[1:])


def _write_volume_hdf5(rng, path: Path, fields: dict) -> None:
    with h5py.File(path, "w") as f:
        for k, v in fields.items():
            if v is None:
                continue
            if isinstance(v, str):
                f[k] = v
            elif k == "data" and rng.random() < 0.05:
                f.create_group(k)
            elif k == "data" and rng.random() < 0.04:
                f.create_dataset(k, shape=(2**int(rng.integers(30, 46)), 2, 2), dtype="<f8")  # declared only
            elif np.ndim(v) and np.size(v) > 1 and rng.random() < 0.5:
                f.create_dataset(k, data=v, chunks=True, compression=_pick(rng, ["gzip", "lzf"]))
            else:
                f[k] = v


def _mat_fields(rng) -> dict:
    t, n = int(rng.integers(4, 12)), int(rng.integers(1, 4))
    counts = rng.poisson(3.0, (n, n, t)).astype(float) + 1
    if rng.random() < 0.3:
        counts = np.transpose(counts, (2, 1, 0))  # T × N × N
    return {_pick(rng, ["rect_data", "meas", "data"]): counts, "width": 0.5, "bin_resolution": 32e-12, "t0": 1e-9}


def _bad_mat_value(rng, value):
    kind = rng.integers(8)
    if kind == 0:
        return "wide"
    if kind == 1:
        return np.array([np.nan])
    if kind == 2:
        return {"a": 1.0, "b": np.ones(3)}  # a struct
    if kind == 3:
        cell = np.empty((2,), dtype=object)
        cell[0], cell[1] = np.ones(2), "x"
        return cell  # a cell array
    if kind == 4:
        return np.asarray(value) * (1 + 1j)
    if kind == 5:
        import scipy.sparse

        return scipy.sparse.csr_matrix(np.eye(3))
    if kind == 6:
        return np.ones((3, 3, 3))  # a cube: ambiguous time axis
    return np.ones((2, 3))


def _patch_mat_dims(rng, path: Path) -> bool:
    """Make a v5 .mat's first 3-D array header declare huge dims (uncompressed files only)."""
    raw = bytearray(path.read_bytes())
    i = raw.find(b"\x05\x00\x00\x00\x0c\x00\x00\x00")  # miINT32 dims tag of 12 bytes
    if i < 0:
        return False
    raw[i + 8:i + 20] = np.array([2**20, 2**20, int(rng.integers(1, 2**20))], "<i4").tobytes()
    path.write_bytes(bytes(raw))
    return True


def _hostile_volume(rng, arena) -> tuple[Path, str]:
    inside, outside = arena["inside"], arena["outside"]
    kind = _pick(rng, ["fifo", "symlink", "external_link", "external_storage", "virtual", "zero"])
    if kind == "fifo":
        return inside / _pick(rng, ["fifo.h5", "fifo.mat"]), kind
    if kind == "symlink":  # to a FIFO outside (the readers take any path a caller gives; none may block)
        return inside / _pick(rng, ["outfifo.h5", "outfifo.mat"]), kind
    if kind == "zero":
        return Path("/dev/zero"), kind
    fields = _volume_fields(rng)
    path = inside / "vol.h5"
    with h5py.File(path, "w") as f:
        for k, v in fields.items():
            if k != "data":
                f[k] = v
        if kind == "external_link":
            f["data"] = h5py.ExternalLink(str(outside / _pick(rng, ["valid.h5", "fifo"])), "/data")
        elif kind == "external_storage":
            f.create_dataset("data", (8, 2, 2), "<f8",
                             external=[(str(outside / _pick(rng, ["valid.raw", "fifo"])), 0, 8 * 2 * 2 * 8)])
        else:
            layout = h5py.VirtualLayout((8, 2, 2), "<f8")
            layout[:] = h5py.VirtualSource(str(outside / "valid.h5"), "data", (8, 2, 2))
            f.create_virtual_dataset("data", layout)
    return path, kind


def _read_volume(path: Path, reader: str, kwargs: dict) -> None:
    vol = (read_mat if reader == "mat" else read_hdf5)(path, **kwargs)
    assert isinstance(vol, TransientVolume) and np.all(np.isfinite(vol.data))


def test_spad_hdf5_and_mat_files(arena, fuzz_cases):
    """Generated confocal .mat and HDF5 files: a finite TransientVolume or an XnlosError; files that
    point outside the folder, FIFOs and devices always refused."""
    rng = np.random.default_rng(272)
    inside = arena["inside"]
    tally = collections.Counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(fuzz_cases):
            reader = _pick(rng, ["hdf5", "mat"])
            kwargs = {}
            if rng.random() < 0.3:
                kwargs["bin_width"] = _pick(rng, [32e-12, 64e-12, float(10.0 ** rng.uniform(-15, -9))])
            hostile = rng.random() < 0.1
            label = "file"
            if hostile:
                path, label = _hostile_volume(rng, arena)
                reader = "mat" if path.suffix == ".mat" else "hdf5"
            elif reader == "hdf5":
                fields = _volume_fields(rng)
                for k in list(fields):
                    if rng.random() < 0.12:
                        fields[k] = None if rng.random() < 0.3 else _bad_value(rng, fields[k])
                path = inside / "vol.h5"
                _write_volume_hdf5(rng, path, fields)
            else:
                fields = _mat_fields(rng)
                for k in list(fields):
                    if rng.random() < 0.1:
                        fields[k] = _bad_mat_value(rng, fields[k])
                if rng.random() < 0.05:
                    fields.pop(next(iter(fields)))
                path = inside / "vol.mat"
                if rng.random() < 0.05:
                    _write_volume_hdf5(rng, path, _volume_fields(rng))  # an HDF5 file, as MATLAB v7.3 writes
                    label = "v7.3"
                else:
                    fmt = "4" if rng.random() < 0.1 else "5"
                    try:
                        scipy.io.savemat(path, fields, format=fmt, do_compression=fmt == "5" and rng.random() < 0.5)
                    except (ValueError, TypeError):  # v4 holds no structs or cells: write v5
                        scipy.io.savemat(path, fields)
                    if rng.random() < 0.04 and _patch_mat_dims(rng, path):
                        label = "huge dims"
                if reader == "mat" and rng.random() < 0.3:
                    kwargs["time_axis"] = _pick(rng, ["first", "last", "auto", "sideways"])
            if not hostile and rng.random() < 0.15:
                label = _corrupt(rng, path)
            result = outcome(lambda: _read_volume(path, reader, kwargs))
            if hostile:
                assert result != "ok", f"{label}: read {path} ({reader})"
            tally[f"{reader} {label}: {result}"] += 1
    report("SPAD .mat / HDF5", tally)
