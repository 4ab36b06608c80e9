"""SPAD detection (sims.spad.detector): Poisson statistics and Coates pile-up against closed forms."""
import numpy as np
import pytest

from sims.spad.detector import background_per_bin, coates_correction, detect, first_photon_probabilities
from xnlos_core.errors import InputError

BW = 32e-12


def test_background_closed_form():
    assert background_per_bin(1e3, 9e3, BW, 1e6) == pytest.approx(1e4 * BW * 1e6)


def test_poisson_mean_and_variance():
    rng = np.random.default_rng(7)
    signal = np.zeros((4, 50, 50))
    signal[1] = 3.0
    signal[2] = 20.0
    n = 1_000_000
    bg = background_per_bin(2e3, 3e4, BW, n)  # ≈ 1.02 counts per bin
    c = detect(signal, n_pulses=n, bin_width=BW, dark_rate=2e3, ambient_rate=3e4, rng=rng)
    for k, s in enumerate((0.0, 3.0, 20.0, 0.0)):
        m = s + bg
        se = np.sqrt(m / 2500)  # standard error of the mean over 2500 pixels
        assert c[k].mean() == pytest.approx(m, abs=5 * se)
        assert c[k].var() == pytest.approx(m, rel=0.1)


def test_seeded_is_deterministic():
    s = np.full((3, 4, 4), 2.0)
    a = detect(s, n_pulses=100, bin_width=BW, rng=np.random.default_rng(1))
    b = detect(s, n_pulses=100, bin_width=BW, rng=np.random.default_rng(1))
    assert np.array_equal(a, b)


def test_coates_probabilities_closed_form_constant_flux():
    mu = np.full((10, 1, 1), 0.2)
    p = first_photon_probabilities(mu)[:, 0, 0]
    assert p == pytest.approx((1 - np.exp(-0.2)) * np.exp(-0.2 * np.arange(10)), rel=1e-12)
    assert p.sum() == pytest.approx(1 - np.exp(-2.0), rel=1e-12)


def test_pile_up_shifts_histogram_early_as_coates_says():
    t, n = 40, 20000
    signal = np.full((t, 3, 3), 0.05 * n)  # 0.05 detections per pulse per bin: strong pile-up
    rng = np.random.default_rng(3)
    c = detect(signal, n_pulses=n, bin_width=BW, pile_up=True, rng=rng)
    k = np.arange(t)
    mean_time = (k[:, None, None] * c).sum(0) / c.sum(0)
    want = (1 - np.exp(-0.05)) * np.exp(-0.05 * k) * n
    expected_mean = (k * want).sum() / want.sum()
    assert expected_mean < (t - 1) / 2  # the flat histogram's mean bin: pile-up moves it early
    assert mean_time.mean() == pytest.approx(expected_mean, abs=0.3)
    assert c[:, 0, 0].sum() <= n
    # Coates inversion recovers the flat flux within counting noise
    mu = coates_correction(c.sum((1, 2)), 9 * n)
    assert mu[: t // 2] == pytest.approx(np.full(t // 2, 0.05), rel=0.1)


def test_no_pile_up_matches_coates_at_low_flux():
    mu = np.full((5, 1, 1), 1e-6)
    assert first_photon_probabilities(mu)[:, 0, 0] == pytest.approx(mu[:, 0, 0], rel=1e-5)


def test_bad_input_named():
    with pytest.raises(InputError, match="signal"):
        detect(np.full((2, 2, 2), np.nan), n_pulses=1, bin_width=BW, rng=np.random.default_rng(0))
    with pytest.raises(InputError, match="rng"):
        detect(np.ones((2, 2, 2)), n_pulses=1, bin_width=BW, rng=0)
