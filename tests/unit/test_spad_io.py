"""Transient files (sims.spad.io): round trips and bad input."""
import h5py
import numpy as np
import pytest
import scipy.io

from sims.spad.io import read_hdf5, read_mat, write_hdf5, write_mat
from xnlos_core.errors import InputError
from xnlos_core.transient import SPEED_OF_LIGHT, TransientVolume


def vol(h=4, w=4, t=16):
    d = np.random.default_rng(0).poisson(3.0, (t, h, w)).astype(float)
    return TransientVolume(d, 32e-12, 1.0, 1.0 if h == w else 0.5, 2e-10)


def test_mat_round_trip(tmp_path):
    v = vol()
    write_mat(tmp_path / "a.mat", v)
    m = scipy.io.loadmat(tmp_path / "a.mat")
    assert m["rect_data"].shape == (4, 4, 16) and m["width"].item() == 0.5  # N × N × T, half width
    r = read_mat(tmp_path / "a.mat")
    assert np.array_equal(r.data, v.data)
    assert (r.bin_width, r.wall_width, r.wall_height, r.t0) == (v.bin_width, 1.0, 1.0, v.t0)


def test_mat_layouts_detected(tmp_path):
    d = np.arange(1, 4 * 3 * 3 + 1, dtype=float).reshape(4, 3, 3)  # (t, y, x)
    scipy.io.savemat(tmp_path / "tfirst.mat", {"meas": d, "width": 0.4, "bin_resolution": 4e-12})
    scipy.io.savemat(tmp_path / "tlast.mat", {"rect_data": d.transpose(2, 1, 0), "width": 0.4})
    a = read_mat(tmp_path / "tfirst.mat")
    b = read_mat(tmp_path / "tlast.mat", bin_width=4e-12)
    assert np.array_equal(a.data, d) and np.array_equal(b.data, d)
    assert a.wall_width == pytest.approx(0.8) and b.bin_width == 4e-12
    scipy.io.savemat(tmp_path / "cube.mat", {"rect_data": np.ones((3, 3, 3)), "width": 0.4, "bin_resolution": 4e-12})
    with pytest.raises(InputError, match="ambiguous"):
        read_mat(tmp_path / "cube.mat")
    assert read_mat(tmp_path / "cube.mat", time_axis="first").shape == (3, 3, 3)


def test_hdf5_round_trip(tmp_path):
    v = vol(2, 4)  # non-square is fine in HDF5
    write_hdf5(tmp_path / "a.h5", v)
    with h5py.File(tmp_path / "a.h5") as f:
        assert float(f["deltaT"][()]) == pytest.approx(SPEED_OF_LIGHT * 32e-12)  # metres per bin
    r = read_hdf5(tmp_path / "a.h5")
    assert np.array_equal(r.data, v.data)
    assert r.bin_width == pytest.approx(v.bin_width, rel=1e-12) and r.t0 == pytest.approx(v.t0, rel=1e-12)
    assert (r.wall_width, r.wall_height) == (1.0, 0.5)


def test_bad_input_named(tmp_path):
    d = np.ones((3, 3, 8))
    nan = d.copy()
    nan[0, 0, 0] = np.nan
    scipy.io.savemat(tmp_path / "nan.mat", {"rect_data": nan, "width": 0.5, "bin_resolution": 4e-12})
    with pytest.raises(InputError, match=r"nan\.mat: rect_data holds 1 NaN"):
        read_mat(tmp_path / "nan.mat")
    scipy.io.savemat(tmp_path / "zero.mat", {"rect_data": 0 * d, "width": 0.5, "bin_resolution": 4e-12})
    with pytest.raises(InputError, match="all zeros"):
        read_mat(tmp_path / "zero.mat")
    scipy.io.savemat(tmp_path / "rect.mat", {"rect_data": np.ones((3, 4, 8)), "width": 0.5, "bin_resolution": 4e-12})
    with pytest.raises(InputError, match="no square scan grid"):
        read_mat(tmp_path / "rect.mat")
    scipy.io.savemat(tmp_path / "bw.mat", {"rect_data": d, "width": 0.5, "bin_resolution": 4e-12})
    with pytest.raises(InputError, match="bin_width = 8e-12 s disagrees with the file's bin_resolution"):
        read_mat(tmp_path / "bw.mat", bin_width=8e-12)
    scipy.io.savemat(tmp_path / "nobw.mat", {"rect_data": d, "width": 0.5})
    with pytest.raises(InputError, match="no bin_resolution"):
        read_mat(tmp_path / "nobw.mat")
    with pytest.raises(InputError, match="square grid"):
        write_mat(tmp_path / "x.mat", vol(2, 4))
    write_hdf5(tmp_path / "a.h5", vol())
    with pytest.raises(InputError, match="disagrees with the file's deltaT"):
        read_hdf5(tmp_path / "a.h5", bin_width=16e-12)
    with h5py.File(tmp_path / "z.h5", "w") as f:
        f["data"] = np.zeros((8, 2, 2))
        f["deltaT"] = 0.01
        f["cameraGridSize"] = [1.0, 1.0]
    with pytest.raises(InputError, match=r"z\.h5: data is all zeros"):
        read_hdf5(tmp_path / "z.h5")
    with h5py.File(tmp_path / "n.h5", "w") as f:
        f["data"] = np.full((8, 2, 2), np.nan)
        f["deltaT"] = 0.01
        f["cameraGridSize"] = [1.0, 1.0]
        f["cameraGridPoints"] = [2, 2]
    with pytest.raises(InputError, match=r"n\.h5: data holds 32 NaN"):
        read_hdf5(tmp_path / "n.h5")
