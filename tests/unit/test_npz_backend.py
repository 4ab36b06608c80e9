"""Frame files: save/load round trip and the npz replay backend."""
import numpy as np
import pytest

from hardware.npz import NPZBackend
from xnlos_core import ConfigError, Frame, GroundTruth, InputError, RadarConfig, RAMap, WallSegment
from xnlos_core.io import load_frame, save_frame

RADAR = RadarConfig(max_range=20.0, n_azimuth_bins=31)


def make_frame(i, with_gt=True):
    rng = np.random.default_rng(i)
    shape = (RADAR.n_range_bins, RADAR.n_azimuth_bins)
    data = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    gt = None
    if with_gt:
        gt = GroundTruth(los_points=[[10.0, 0.0]], mnlos_points=[[30.0, 5.0], [31.0, 5.0]],
                         hidden_points=[[20.0, 5.0], [19.0, 5.0]], mnlos_object=[0, 0], object_names=("car",),
                         walls=(WallSegment(np.array([15.0, 10.0]), np.array([35.0, -10.0]), "facade"),))
    return Frame(RAMap.from_radar(data, RADAR), timestamp=0.1 * i, ground_truth=gt, index=i, meta={"run": "t"})


def test_save_load_round_trip(tmp_path):
    f = make_frame(3)
    save_frame(tmp_path / "f.npz", f)
    g = load_frame(tmp_path / "f.npz")
    assert np.array_equal(g.ra_map.data, f.ra_map.data)
    assert np.array_equal(g.ra_map.range_axis, f.ra_map.range_axis)
    assert g.ra_map.radar == RADAR
    assert (g.timestamp, g.index, g.meta) == (f.timestamp, f.index, f.meta)
    for name in ("los_points", "mnlos_points", "hidden_points", "mnlos_object"):
        assert np.array_equal(getattr(g.ground_truth, name), getattr(f.ground_truth, name))
    assert g.ground_truth.object_names == ("car",)
    assert [w.name for w in g.ground_truth.walls] == ["facade"]
    assert np.array_equal(g.ground_truth.walls[0].end, [35.0, -10.0])
    save_frame(tmp_path / "n.npz", make_frame(4, with_gt=False))
    assert load_frame(tmp_path / "n.npz").ground_truth is None


def test_a_moving_frames_truth_survives_the_round_trip(tmp_path):
    # velocities, LOS owners and range rates, SNRs: what a moving scene's ground truth records
    gt = make_frame(3).ground_truth
    moving = GroundTruth(gt.los_points, gt.mnlos_points, gt.hidden_points, gt.mnlos_object, gt.object_names, gt.walls,
                         los_snr_db=[12.5], mnlos_snr_db=[20.0, 21.0], hidden_velocity=[[0.0, 5.0], [0.0, 5.0]],
                         mnlos_velocity=[[5.0, 0.0], [5.0, 0.0]], los_object=[-1], los_radial_velocity=[0.0])
    f = make_frame(3)
    save_frame(tmp_path / "m.npz", Frame(f.ra_map, f.timestamp, moving, f.index, f.meta))
    g = load_frame(tmp_path / "m.npz").ground_truth
    for name in ("los_snr_db", "mnlos_snr_db", "hidden_velocity", "mnlos_velocity", "los_object", "los_radial_velocity"):
        np.testing.assert_array_equal(getattr(g, name), getattr(moving, name), err_msg=name)
    save_frame(tmp_path / "s.npz", make_frame(5))
    s = load_frame(tmp_path / "s.npz").ground_truth
    assert s.hidden_velocity is None and s.los_object is None and s.los_radial_velocity is None


def test_backend_yields_frames_in_name_order(tmp_path):
    for i in (2, 0, 1):
        save_frame(tmp_path / f"frame_{i:06d}.npz", make_frame(i))
    (tmp_path / "notes.txt").write_text("not a frame")
    with NPZBackend({"directory": str(tmp_path)}) as backend:
        frames = list(backend.frames())
        assert [f.index for f in frames] == [0, 1, 2]
        assert [f.index for f in backend.frames(max_frames=2)] == [0, 1]
        assert list(backend.frames(max_frames=0)) == []


@pytest.mark.parametrize("content", [b"", b"garbage" * 20, "truncate"])
def test_corrupt_file_error_names_it(tmp_path, content):
    save_frame(tmp_path / "a.npz", make_frame(0))
    blob = (tmp_path / "a.npz").read_bytes()
    (tmp_path / "b_bad.npz").write_bytes(blob[: len(blob) // 2] if content == "truncate" else content)
    frames = NPZBackend({"directory": str(tmp_path)}).frames()
    assert next(frames).index == 0  # the good file before it is still delivered
    with pytest.raises(InputError, match="b_bad.npz"):
        next(frames)


def test_missing_directory_and_params(tmp_path):
    missing = tmp_path / "nope"
    with pytest.raises(InputError, match="nope"):
        list(NPZBackend({"directory": str(missing)}).frames())
    with pytest.raises(ConfigError, match="directory"):
        NPZBackend({})
    with pytest.raises(InputError, match="max_frames"):
        list(NPZBackend({"directory": str(tmp_path)}).frames(max_frames=-1))


def test_an_empty_replay_folder_is_refused_by_check_and_run(tmp_path):
    import pytest

    from hardware.npz import NPZBackend
    from xnlos_core.errors import InputError

    backend = NPZBackend(NPZBackend.Params(directory=str(tmp_path)))
    with pytest.raises(InputError, match="holds no"):
        backend.check_source()
    with pytest.raises(InputError, match="holds no"):
        list(backend.frames())
