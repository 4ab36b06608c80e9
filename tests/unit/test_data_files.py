"""Data files read without trusting their content (xnlos_core.datafiles): recordings (npy, npz, HDF5,
DCA1000), transient volumes (.mat, HDF5) and checkpoints refuse FIFOs and devices before reading,
HDF5 files that would read other files (external links, external storage, virtual datasets),
declared sizes beyond the file or memory, and damaged bytes, each with an InputError naming the
file; ``xnlos check`` opens recordings and loads checkpoints as a run does."""
from __future__ import annotations

import os
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io

from hardware.raw_formats import load_cube
from hardware.recording import Recording
from hardware.recording_checks import RecordingWarning
from sims.spad.io import read_hdf5, read_mat, write_hdf5
from xnlos_core.app.cli import check_file
from xnlos_core.datafiles import hdf5_file, load_npy, load_npz_array, open_regular, read_hdf5_array
from xnlos_core.errors import ConfigError, InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.transient import TransientVolume

RADAR = RadarConfig(n_samples=16, n_tx=1, n_rx=2, n_chirps=1, n_azimuth_bins=5, max_range=3.0)
RADAR_TABLE = {k: v for k, v in RADAR.model_dump().items() if v is not None}
SHAPE = (2, 16, 1, 2)  # frame, sample, chirp, channel


def _cube(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (rng.standard_normal(SHAPE) + 1j * rng.standard_normal(SHAPE)) * 1e-3


def _open(folder: Path, file: str, fmt: str = "hdf5", radar: dict | None = None, **recording) -> Recording:
    table = {"recording": {"file": file, "format": fmt, **recording}, "radar": {**RADAR_TABLE, **(radar or {})}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RecordingWarning)
        return Recording.from_table(table, "t.toml", folder)


@pytest.fixture
def outside(tmp_path_factory) -> Path:
    """A folder outside the test's tmp folder (and the working directory) holding a secret and an HDF5 file."""
    d = tmp_path_factory.mktemp("outside")
    (d / "secret.bin").write_bytes(os.urandom(4096))
    with h5py.File(d / "other.h5", "w") as f:
        f["adc"] = _cube(1)
    return d


# --- regular files only ----------------------------------------------------------------------------

@pytest.mark.parametrize("reader", ["open_regular", "npy", "npz", "hdf5", "spad_hdf5", "mat", "checkpoint", "frame"])
def test_a_fifo_is_refused_before_it_is_opened_for_reading(tmp_path, reader):
    from plugins.training.checkpoint import load_checkpoint
    from xnlos_core.io import load_frame

    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)  # no writer: a blocking open would hang the test
    call = {"open_regular": lambda: open_regular(fifo, what="x"), "npy": lambda: load_cube(fifo, "npy", "adc"),
            "npz": lambda: load_cube(fifo, "npz", "adc"), "hdf5": lambda: load_cube(fifo, "hdf5", "adc"),
            "spad_hdf5": lambda: read_hdf5(fifo), "mat": lambda: read_mat(fifo),
            "checkpoint": lambda: load_checkpoint(fifo), "frame": lambda: load_frame(fifo)}[reader]
    with pytest.raises(InputError, match=r"(pipe|x).* is a FIFO \(named pipe\); expected a regular file"):
        call()


def test_devices_and_directories_are_refused(tmp_path):
    from plugins.training.checkpoint import load_checkpoint

    with pytest.raises(InputError, match="'/dev/zero' is a character device; expected a regular file"):
        load_checkpoint("/dev/zero")
    with pytest.raises(InputError, match="is a directory; expected a regular file"):
        load_cube(tmp_path, "npy", "adc")
    with pytest.raises(InputError, match=r"missing\.npy: no such file"):
        load_cube(tmp_path / "missing.npy", "npy", "adc")


def test_a_recording_symlinked_out_of_the_folder_is_refused(tmp_path, outside):
    (tmp_path / "c.npy").symlink_to(outside / "secret.bin")
    with pytest.raises(ConfigError, match="outside the config roots"):
        _open(tmp_path, "c.npy", "npy")


# --- HDF5 stays inside its file ----------------------------------------------------------------------

def test_an_external_link_is_refused_naming_the_link_and_its_target(tmp_path, outside):
    with h5py.File(tmp_path / "c.h5", "w") as f:
        f["adc"] = h5py.ExternalLink(str(outside / "other.h5"), "/adc")
    with pytest.raises(InputError, match=r"c\.h5: '/adc' is an external link to '/adc' in file '.*other\.h5'"):
        _open(tmp_path, "c.h5")
    # anywhere in the file, even where the reader does not look
    with h5py.File(tmp_path / "d.h5", "w") as f:
        f["adc"] = _cube()
        f.create_group("g")["x"] = h5py.ExternalLink("/etc/passwd", "/")
    with pytest.raises(InputError, match="'/g/x' is an external link"):
        _open(tmp_path, "d.h5")


def test_external_storage_is_refused_before_any_byte_of_it_is_read(tmp_path, outside):
    with h5py.File(tmp_path / "c.h5", "w") as f:
        f.create_dataset("adc", SHAPE, "<c8", external=[(str(outside / "secret.bin"), 0, 2 * 16 * 2 * 8)])
    with pytest.raises(InputError, match=r"dataset '/adc' keeps its data in external file\(s\) .*secret\.bin"):
        _open(tmp_path, "c.h5")


def test_a_virtual_dataset_is_refused(tmp_path, outside):
    layout = h5py.VirtualLayout(SHAPE, "<c16")
    layout[:] = h5py.VirtualSource(str(outside / "other.h5"), "adc", SHAPE)
    with h5py.File(tmp_path / "c.h5", "w") as f:
        f.create_virtual_dataset("adc", layout)
    with pytest.raises(InputError, match=r"dataset '/adc' is a virtual dataset mapped from .*other\.h5:adc"):
        _open(tmp_path, "c.h5")


def test_spad_hdf5_refuses_links_into_other_files(tmp_path, outside):
    v = TransientVolume(np.ones((8, 2, 2)), 32e-12, 1.0, 1.0)
    write_hdf5(tmp_path / "v.h5", v)
    with h5py.File(tmp_path / "v.h5", "a") as f:
        del f["data"]
        f["data"] = h5py.ExternalLink(str(outside / "other.h5"), "/adc")
    with pytest.raises(InputError, match=r"v\.h5: '/data' is an external link"):
        read_hdf5(tmp_path / "v.h5")


def test_soft_links_and_hard_link_cycles_inside_the_file_are_fine(tmp_path):
    with h5py.File(tmp_path / "c.h5", "w") as f:
        g = f.create_group("g")
        g["cube"] = _cube()
        g["loop"] = g  # a hard-link cycle: walked once
        f["adc"] = h5py.SoftLink("/g/cube")
    rec = _open(tmp_path, "c.h5")
    assert rec.n_frames == 2 and rec.ra_map(1).shape == (RADAR.n_range_bins, RADAR.n_azimuth_bins)


def test_a_dataset_needing_a_filter_plugin_is_refused(tmp_path):
    with h5py.File(tmp_path / "c.h5", "w") as f:
        f.create_dataset("adc", data=_cube(), chunks=SHAPE, compression="gzip")
    with hdf5_file(tmp_path / "c.h5", what="c") as f:  # gzip is built in
        assert read_hdf5_array(f, "adc", what="c").shape == SHAPE
    with h5py.File(tmp_path / "p.h5", "w") as f:  # blosc's id: reading it would load a plugin
        f.create_dataset("adc", data=_cube(), chunks=SHAPE, compression=32001, allow_unknown_filter=True)
    with pytest.raises(InputError, match="HDF5 filter 32001, which needs a plugin"):
        _open(tmp_path, "p.h5")


# --- declared sizes and damaged bytes ----------------------------------------------------------------

def test_a_128_tib_declared_dataset_is_refused_before_allocation(tmp_path):
    with h5py.File(tmp_path / "c.h5", "w") as f:
        f.create_dataset("adc", (2**40, 16, 1, 2), "<c8")  # 128 TiB declared, no storage
    assert (tmp_path / "c.h5").stat().st_size < 10_000
    with pytest.raises(InputError, match=r"c\.h5: dataset 'adc': declares shape \(1099511627776, 16, 1, 2\).*at most 4 GiB"):
        _open(tmp_path, "c.h5")
    with h5py.File(tmp_path / "d.h5", "w") as f:
        f.create_dataset("adc", SHAPE, "<c8")  # declared, never written: fill values, not data
    with pytest.raises(InputError, match="unwritten or truncated"):
        _open(tmp_path, "d.h5")


def test_an_npy_header_larger_than_its_file_is_refused(tmp_path):
    np.save(tmp_path / "c.npy", _cube())
    data = bytearray((tmp_path / "c.npy").read_bytes())
    head = data[:128].replace(b"(2, 16, 1, 2)", b"(9, 16, 1, 2)")
    (tmp_path / "big.npy").write_bytes(bytes(head) + bytes(data[128:]))
    with pytest.raises(InputError, match=r"big\.npy: declares shape \(9, 16, 1, 2\) of complex128.*the file holds"):
        _open(tmp_path, "big.npy", "npy")
    with pytest.raises(InputError, match="declares shape"):
        load_npy(tmp_path / "big.npy", what="big", mmap=False)


def test_npz_and_object_arrays(tmp_path):
    np.savez(tmp_path / "c.npz", adc=_cube(), obj=np.array([None, 1], dtype=object))
    assert load_npz_array(tmp_path / "c.npz", "adc", what="c").shape == SHAPE
    with pytest.raises(InputError, match="holds Python objects"):
        load_npz_array(tmp_path / "c.npz", "obj", what="c")
    with pytest.raises(InputError, match=r"no array 'x'; it holds \['adc', 'obj'\]"):
        load_npz_array(tmp_path / "c.npz", "x", what="c")


def test_a_corrupt_compressed_chunk_is_an_input_error(tmp_path):
    with h5py.File(tmp_path / "c.h5", "w") as f:
        f.create_dataset("adc", data=_cube(), chunks=(1, 16, 1, 2), compression="gzip")
    with h5py.File(tmp_path / "c.h5") as f:
        info = f["adc"].id.get_chunk_info(0)
    raw = bytearray((tmp_path / "c.h5").read_bytes())
    raw[info.byte_offset + 4:info.byte_offset + info.size] = bytes(info.size - 4)
    (tmp_path / "c.h5").write_bytes(bytes(raw))
    with pytest.raises(InputError, match=r"c\.h5: dataset 'adc' cannot be read \(OSError"):
        _open(tmp_path, "c.h5")


# --- the cube a recording holds -----------------------------------------------------------------------

@pytest.mark.parametrize("fmt", ["npy", "hdf5"])
def test_a_0d_cube_is_refused_with_the_expected_shape(tmp_path, fmt):
    if fmt == "npy":
        np.save(tmp_path / "c.npy", np.complex128(1))
    else:
        with h5py.File(tmp_path / "c.h5", "w") as f:
            f["adc"] = np.complex128(1)
    with pytest.raises(InputError, match=r"has shape \(\) \(0-D\); expected shape \(frame: N ≥ 1, sample: 16, "
                                         r"chirp: N ≥ 1, channel: 2\)"):
        _open(tmp_path, "c.npy" if fmt == "npy" else "c.h5", fmt)


@pytest.mark.parametrize("fmt", ["npy", "npz", "hdf5"])
def test_an_empty_recording_is_refused(tmp_path, fmt):
    empty = np.zeros((0,) + SHAPE[1:], complex)
    name = {"npy": "c.npy", "npz": "c.npz", "hdf5": "c.h5"}[fmt]
    if fmt == "npy":
        np.save(tmp_path / name, empty)
    elif fmt == "npz":
        np.savez(tmp_path / name, adc=empty)
    else:
        with h5py.File(tmp_path / name, "w") as f:
            f["adc"] = empty
    with pytest.raises(InputError, match="has no frames: an empty recording"):
        _open(tmp_path, name, fmt)


def test_wrong_axis_lengths_and_dtypes_are_refused_on_opening(tmp_path):
    np.save(tmp_path / "n.npy", np.ones((2, 15, 1, 2), complex))
    with pytest.raises(InputError, match=r"15 entries on its 'sample' axis.*n_samples=16"):
        _open(tmp_path, "n.npy", "npy")
    np.save(tmp_path / "r.npy", np.ones(SHAPE))
    with pytest.raises(InputError, match="has dtype float64; expected complex samples"):
        _open(tmp_path, "r.npy", "npy")
    np.save(tmp_path / "iq.npy", np.ones(SHAPE + (3,), np.int16))
    with pytest.raises(InputError, match="3 entries on its trailing I/Q axis"):
        _open(tmp_path, "iq.npy", "npy", sample_format="iq")
    with pytest.raises(ConfigError, match="sampling = 'real'.*sample_format = 'iq'"):
        _open(tmp_path, "iq.npy", "npy", radar={"max_range": 1.5}, sample_format="iq", sampling="real")


@pytest.mark.parametrize("key,value", [("leakage_range", float("inf")), ("leakage_range", float("nan")),
                                       ("leakage_range", 1e6), ("scale", float("inf")), ("adc_offset", float("nan")),
                                       ("leakage_db", float("inf"))])
def test_non_finite_or_absurd_recording_numbers_are_config_errors(tmp_path, key, value):
    np.save(tmp_path / "c.npy", _cube())
    with pytest.raises(ConfigError, match=rf"\[recording\.{key}\]"):
        _open(tmp_path, "c.npy", "npy", **{key: value})


def test_dca1000_frames_are_read_through_a_checked_descriptor(tmp_path):
    from hardware.testing import make_adc_recording

    toml = make_adc_recording(tmp_path, frames=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RecordingWarning)
        rec = Recording.from_toml(toml)
    words = rec.raw_frame(1)
    assert words.dtype == np.dtype("<i2") and words.size == rec._frame_words
    rec.path.write_bytes(rec.path.read_bytes()[:10])  # shrunk after opening
    with pytest.raises(InputError, match="frame 1 holds 0 of its"):
        rec.raw_frame(1)


# --- SPAD .mat / HDF5 metadata ----------------------------------------------------------------------------

def test_mat_files_with_foreign_or_huge_content_are_input_errors(tmp_path):
    scipy.io.savemat(tmp_path / "s.mat", {"rect_data": np.ones((3, 3, 8)), "width": "wide", "bin_resolution": 4e-12})
    with pytest.raises(InputError, match=r"s\.mat: variable 'width' is a char array; expected a numeric array"):
        read_mat(tmp_path / "s.mat")
    write_hdf5(tmp_path / "v73.mat", TransientVolume(np.ones((8, 2, 2)), 32e-12, 1.0, 1.0))  # HDF5, like v7.3
    with pytest.raises(InputError, match=r"v73\.mat: not a readable MATLAB \.mat file"):
        read_mat(tmp_path / "v73.mat")
    scipy.io.savemat(tmp_path / "big.mat", {"rect_data": np.ones((3, 3, 8)), "width": 0.5})
    raw = bytearray((tmp_path / "big.mat").read_bytes())
    dims = np.array([3, 3, 8], "<i4").tobytes()
    i = raw.find(dims)
    raw[i:i + 12] = np.array([2**20, 2**20, 8], "<i4").tobytes()  # declares 64 TiB
    (tmp_path / "big.mat").write_bytes(bytes(raw))
    with pytest.raises(InputError, match=r"big\.mat: variable 'rect_data' declares shape \(1048576, 1048576, 8\)"):
        read_mat(tmp_path / "big.mat")


def test_a_damaged_mat_data_type_code_is_an_input_error_not_a_crash(tmp_path):
    # scipy's v5 reader indexes a table of dtypes with the type code read from the file, unchecked:
    # code 8 (an empty slot) in bin_resolution's data tag dereferences NULL (segmentation fault),
    # others read a wild pointer; run in a child so a regression fails this test, not the session
    import subprocess
    import sys

    scipy.io.savemat(tmp_path / "d.mat", {"rect_data": np.ones((2, 2, 8)), "width": 0.5, "bin_resolution": 4e-12})
    raw = bytearray((tmp_path / "d.mat").read_bytes())
    tag = b"\x09\x00\x00\x00\x08\x00\x00\x00" + np.float64(4e-12).tobytes()
    i = raw.rfind(tag)
    assert i > 0
    raw[i:i + 4] = np.array([8], "<u4").tobytes()
    (tmp_path / "d.mat").write_bytes(bytes(raw))
    code = ("import sys; from sims.spad.io import read_mat\n"
            "try:\n    read_mat(sys.argv[1])\nexcept Exception as e:\n    print(type(e).__name__, e)")
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "d.mat")], capture_output=True, text=True,
                         timeout=120, cwd=root, env={**os.environ, "PYTHONPATH": str(root)})
    assert out.returncode == 0, out.stderr[-2000:]
    assert "InputError" in out.stdout and "'bin_resolution': its real part has MATLAB data type 8" in out.stdout


def test_spad_hdf5_metadata_of_the_wrong_kind_is_an_input_error(tmp_path):
    write_hdf5(tmp_path / "v.h5", TransientVolume(np.ones((8, 2, 2)), 32e-12, 1.0, 1.0))
    with h5py.File(tmp_path / "v.h5", "a") as f:
        del f["deltaT"]
        f["deltaT"] = "one centimetre"
    with pytest.raises(InputError, match=r"v\.h5: dataset 'deltaT' has dtype object; expected the path length"):
        read_hdf5(tmp_path / "v.h5")
    with h5py.File(tmp_path / "v.h5", "a") as f:
        del f["deltaT"]
        f.create_group("deltaT")
    with pytest.raises(InputError, match="'deltaT' is a Group"):
        read_hdf5(tmp_path / "v.h5")


# --- xnlos check opens what run opens ---------------------------------------------------------------------

ADC_PIPELINE = """
[radar]
n_azimuth_bins = 121
[backend]
name = "adc"
params = {{ recording = "{recording}"{start} }}
[detector]
name = "cfar"
[run]
frames = 1
figure = false
"""


def test_check_refuses_a_missing_recording_and_a_start_past_its_end(tmp_path):
    p = tmp_path / "p.toml"
    p.write_text(ADC_PIPELINE.format(recording="missing.toml", start=""), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"missing\.toml: configuration file: no such file"):
        check_file(p)
    from hardware.testing import make_adc_recording

    make_adc_recording(tmp_path / "rec", frames=2)
    p.write_text(ADC_PIPELINE.format(recording="rec/capture.toml", start=""), encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RecordingWarning)
        assert check_file(p).endswith("valid (1 pipeline(s))")
        p.write_text(ADC_PIPELINE.format(recording="rec/capture.toml", start=", start = 2"), encoding="utf-8")
        with pytest.raises(InputError, match=r"params.start = 2, but the recording has 2 frame\(s\)"):
            check_file(p)


def test_check_refuses_a_missing_or_device_checkpoint(tmp_path, tiny_checkpoint):
    from xnlos_core.io import atomic_write_text

    def pipeline(checkpoint: str) -> Path:
        p = tmp_path / "p.toml"
        atomic_write_text(p, f"""
[radar]
n_samples = 256
max_range = 60.0
n_azimuth_bins = 121
[scene]
builtin = "corner"
[forward_model]
name = "image"
[detector]
name = "unet"
params = {{ checkpoint = "{checkpoint}" }}
[run]
frames = 1
figure = false
""")
        return p

    with pytest.raises(InputError, match=r"checkpoint '.*missing\.pt': no such file"):
        check_file(pipeline("missing.pt"))
    with pytest.raises(InputError, match=r"checkpoint '/dev/zero' is a character device"):
        check_file(pipeline("/dev/zero"))
    tiny_checkpoint(tmp_path / "ok.pt", "unet")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert "valid" in check_file(pipeline("ok.pt"))


def test_check_refuses_a_denormal_field_of_view_saying_radians(tmp_path):
    p = tmp_path / "p.toml"
    p.write_text(ADC_PIPELINE.replace("n_azimuth_bins = 121", "n_azimuth_bins = 121\nfield_of_view = 5e-324")
                 .format(recording="missing.toml", start=""), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"field_of_view.*HALF field of view in radians.*got 5e-324 rad"):
        check_file(p)
