import numpy as np
import pytest

from xnlos_core import (LOS, MNLOS, Detections, Frame, GroundTruth, HiddenPoints, InputError, RadarConfig,
                        RAMap, WallPosterior)
from xnlos_core.testing import small_radar


def test_ramap_rejects_nan_and_bad_shapes():
    radar = small_radar()
    good = np.zeros((radar.n_range_bins, radar.n_azimuth_bins), np.complex64)
    RAMap.from_radar(good, radar)
    bad = good.copy()
    bad[3, 4] = np.nan
    with pytest.raises(InputError, match="RAMap.data: 1 of .* NaN"):
        RAMap.from_radar(bad, radar)
    with pytest.raises(InputError, match="RAMap.range_axis: has .* entries but RAMap.data axis 0"):
        RAMap.from_radar(good[:-1], radar)
    with pytest.raises(InputError, match="expected a 2-D array"):
        RAMap.from_radar(good[0], radar)
    with pytest.raises(InputError, match="strictly ascending"):
        RAMap(good, radar.range_axis[::-1], radar.azimuth_axis, radar)


def test_ramap_is_complex64():
    radar = small_radar()
    m = RAMap.from_radar(np.ones((radar.n_range_bins, radar.n_azimuth_bins)), radar)
    assert m.data.dtype == np.complex64 and m.range_axis.dtype == np.float64


def test_detections_validate_and_position():
    d = Detections([10.0, 20.0], [0.0, np.pi / 2], [LOS, MNLOS], [0.5, 1.0])
    np.testing.assert_allclose(d.position, [[10, 0], [0, 20]], atol=1e-12)
    with pytest.raises(InputError, match="Detections.label"):
        Detections([1.0], [0.0], [7], [0.5])
    with pytest.raises(InputError, match="confidence"):
        Detections([1.0], [0.0], [0], [1.5])
    with pytest.raises(InputError, match="Detections.azimuth: expected shape"):
        Detections([1.0, 2.0], [0.0], [0, 0], [0.5, 0.5])
    assert len(Detections.empty()) == 0


def test_position_cov_is_range_azimuth_ellipse():
    d = Detections([10.0], [0.0], [LOS], [1.0], [0.1], [0.01])
    np.testing.assert_allclose(d.position_cov()[0], np.diag([0.01, 0.01]), atol=1e-12)


def test_wall_posterior_canonical_and_psd():
    w = WallPosterior.line([1.0, 0.0], -5.0)  # x = 5 written with b < 0 → flipped to b ≥ 0
    assert w.offset == pytest.approx(5.0)
    np.testing.assert_allclose(w.normal, [-1, 0], atol=1e-12)
    with pytest.raises(InputError, match="positive semi-definite"):
        WallPosterior("line", [0.0, 1.0], [[-1.0, 0], [0, 1.0]])
    with pytest.raises(InputError, match="symmetric"):
        WallPosterior("line", [0.0, 1.0], [[1.0, 0.5], [0, 1.0]])


def test_ground_truth_alignment_and_hidden_points():
    with pytest.raises(InputError, match="hidden_points"):
        GroundTruth(mnlos_points=np.zeros((2, 2)), hidden_points=np.zeros((1, 2)))
    h = HiddenPoints(np.zeros((1, 2)), np.eye(2)[None], [0], [0])
    assert len(h) == 1 and len(HiddenPoints.empty()) == 0


def test_frame_checks_types():
    with pytest.raises(InputError, match="Frame.ra_map"):
        Frame(np.zeros((3, 3)))


def test_radar_derived_quantities():
    r = RadarConfig()
    assert r.range_resolution == pytest.approx(299_792_458 / 1.2e9)
    assert r.wavelength == pytest.approx(0.02998, rel=1e-3)
    assert r.max_unambiguous_range >= 100
    assert len(r.virtual_positions) == 32
    np.testing.assert_allclose(np.diff(r.virtual_positions), r.wavelength / 2)


def test_arrays_are_read_only_after_validation():
    # RAMap.data stayed writable after its finiteness check; one cell set to inf
    # afterwards made cfar return 33 detections. Validated arrays are now read-only, and the
    # caller's own array is copied rather than locked, so editing it changes nothing validated.
    from plugins.detectors.cfar import CFARDetector

    radar = small_radar()
    user = np.random.default_rng(0).standard_normal((radar.n_range_bins, radar.n_azimuth_bins)).astype(np.complex64)
    ra = RAMap.from_radar(user, radar)
    before = len(CFARDetector().detect(Frame(ra)))
    with pytest.raises(ValueError, match="read-only"):
        ra.data[3, 4] = np.inf
    user[3, 4] = np.inf  # the caller's array stays writable and is not the map's storage
    assert np.all(np.isfinite(ra.data)) and len(CFARDetector().detect(Frame(ra))) == before
    for arr in (ra.range_axis, ra.azimuth_axis):
        assert not arr.flags.writeable
    det = Detections([10.0, 20.0], [0.0, 0.5], [LOS, MNLOS], [0.5, 1.0], [0.1, 0.1], [0.01, 0.01])
    for name in ("range", "azimuth", "label", "confidence", "range_std", "azimuth_std", "position"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(det, name)[0] = np.nan
    w = WallPosterior.line([1.0, 0.0], -5.0, cov=np.eye(2), extent=[[5, -1], [5, 1]], samples=np.zeros((3, 2)))
    for arr in (w.mean, w.cov, w.extent, w.samples):
        assert not arr.flags.writeable
    h = HiddenPoints(np.zeros((1, 2)), np.eye(2)[None], [0], [0])
    gt = GroundTruth(los_points=np.zeros((1, 2)))
    for arr in (h.mean, h.cov, h.source_index, h.wall_index, gt.los_points, gt.mnlos_points, gt.los_snr_db):
        assert not arr.flags.writeable


def test_arrays_stay_read_only_through_pickle_and_deepcopy():
    import copy
    import pickle

    radar = small_radar()
    ra = RAMap.from_radar(np.ones((radar.n_range_bins, radar.n_azimuth_bins)), radar)
    det = Detections([10.0], [0.0], [LOS], [0.5])
    w = WallPosterior.line([1.0, 0.0], -5.0)
    for obj, names in ((ra, ("data", "range_axis")), (det, ("range", "position")), (w, ("mean", "cov"))):
        for clone in (pickle.loads(pickle.dumps(obj)), copy.deepcopy(obj)):
            for name in names:
                arr = getattr(clone, name)
                np.testing.assert_array_equal(arr, getattr(obj, name))
                assert not arr.flags.writeable, name


def test_ground_truth_los_object_owner_of_each_los_point():
    los = np.array([[10.0, 0.0], [11.0, 0.0], [8.0, 6.0]])
    assert GroundTruth(los_points=los).los_object is None  # not recorded (a dataset frame)
    gt = GroundTruth(los_points=los, object_names=("car", "kiosk"), los_object=[-1, -1, 1], los_snr_db=[1, 2, 30])
    assert gt.los_object.dtype == np.int64 and gt.los_object.tolist() == [-1, -1, 1]
    assert not gt.los_object.flags.writeable
    assert gt.above_snr(10.0).los_object.tolist() == [1]  # filtered with its points
    with pytest.raises(InputError, match=r"GroundTruth\.los_object: expected shape \(3\)"):
        GroundTruth(los_points=los, object_names=("car",), los_object=[0, 0])  # one per LOS point
    with pytest.raises(InputError, match=r"GroundTruth\.los_object: .*0 … 1.*got \[-1, 2\]"):
        GroundTruth(los_points=los, object_names=("car", "kiosk"), los_object=[-1, 0, 2])
    with pytest.raises(InputError, match=r"GroundTruth\.los_object: indices must be −1"):
        GroundTruth(los_points=los, object_names=("car", "kiosk"), los_object=[-2, 0, 1])
