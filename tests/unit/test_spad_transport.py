"""SPAD three-bounce transport (sims.spad.transport) against closed forms."""
import numpy as np
import pytest

from sims.spad.transport import (Optics, Patches, expected_transient, gaussian_kernel, histogram,
                                 return_per_pulse, system_sigma)
from xnlos_core.errors import InputError
from xnlos_core.transient import SPEED_OF_LIGHT

C = SPEED_OF_LIGHT
BW = 32e-12


def facing(z, x=0.0, y=0.0, area=1e-4, albedo=0.5):
    return Patches(np.array([[x, y, z]]), np.array([[0.0, 0.0, -1.0]]), np.array([area]), np.array([albedo]))


def test_photons_per_pulse_closed_form():
    o = Optics(power=1.6e-3, wavelength=850e-9, rep_rate=5e6)
    assert o.photons_per_pulse == pytest.approx(1.6e-3 / 5e6 / (6.62607015e-34 * C / 850e-9), rel=1e-12)
    assert o.photons_per_pulse == pytest.approx(1.369e9, rel=1e-3)


def test_on_axis_count_closed_form_and_inverse_fourth_power():
    o = Optics()
    n1, t1 = return_per_pulse(np.zeros(1), np.zeros(1), facing(1.0), o)
    n2, t2 = return_per_pulse(np.zeros(1), np.zeros(1), facing(2.0), o)
    want = (o.photons_per_pulse * o.wall_albedo**2 * 0.5 * 1e-4 * o.spot_area * o.aperture_area * o.efficiency
            / (np.pi**3 * o.collection_distance**2))
    assert n1[0, 0, 0] == pytest.approx(want, rel=1e-12)
    assert n1[0, 0, 0] / n2[0, 0, 0] == pytest.approx(16.0, rel=1e-12)  # 1/z⁴
    assert t1[0, 0, 0] == pytest.approx(2.0 / C) and t2[0, 0, 0] == pytest.approx(4.0 / C)


def test_off_axis_cosine_falloff():
    z, x = 1.0, 0.75
    n, _ = return_per_pulse(np.array([0.0, x]), np.zeros(1), facing(z), Optics())
    r = np.hypot(x, z)
    # cosθ_wall = cosθ_patch = z/r, each twice, and 1/r⁴: ratio (z/r)⁴ (z/r)⁴
    assert n[0, 0, 1] / n[0, 0, 0] == pytest.approx((z / r) ** 8, rel=1e-12)


def test_patch_facing_away_or_behind_wall_returns_nothing():
    p = Patches(np.array([[0, 0, 1.0], [0, 0, -1.0]]), np.array([[0, 0, 1.0], [0, 0, 1.0]]),
                np.array([1e-4, 1e-4]), np.array([0.5, 0.5]))
    n, _ = return_per_pulse(np.zeros(1), np.zeros(1), p, Optics())
    assert np.all(n == 0)


@pytest.mark.parametrize("z", [0.8, 1.3])
def test_peak_bin_at_round_trip(z):
    t0 = 1e-9
    vol = expected_transient(np.zeros(1), np.zeros(1), facing(z), Optics(), n_bins=256, bin_width=BW,
                             n_pulses=1, sigma=system_sigma(50e-12, 60e-12), t0=t0)
    assert int(np.argmax(vol[:, 0, 0])) == int(np.rint((2 * z / C - t0) / BW))  # bin k centred at t0 + kΔ


def test_histogram_conserves_counts_and_places_a_bin_centre_exactly():
    tau = np.full((1, 1, 1), 30 * BW)  # bin k is centred at kΔ: all of it in bin 30
    v = histogram(np.ones((1, 1, 1)), tau, 64, BW)
    assert v[30, 0, 0] == pytest.approx(1.0) and v.sum() == pytest.approx(1.0)
    tau = np.full((1, 1, 1), (30 + 0.3) * BW)  # 0.3 of a bin past centre 30: split 0.7 / 0.3
    v = histogram(np.ones((1, 1, 1)), tau, 64, BW)
    assert v[30:32, 0, 0] == pytest.approx([0.7, 0.3])
    v = histogram(np.ones((1, 1, 1)), tau, 64, BW, sigma=100e-12)
    assert v.sum() == pytest.approx(1.0, rel=1e-9)
    # mean arrival of the split + blurred histogram stays at τ (the kernel is symmetric)
    assert np.sum(np.arange(64) * v[:, 0, 0]) == pytest.approx(30.3, abs=1e-6)


def test_gaussian_kernel_width():
    g = gaussian_kernel(3 * BW, BW)
    k = np.arange(len(g)) - len(g) // 2
    assert g.sum() == pytest.approx(1.0)
    # bin-integrated Gaussian: variance σ² + Δ²/12 (Sheppard)
    assert np.sum(k**2 * g) * BW**2 == pytest.approx((3 * BW) ** 2 + BW**2 / 12, rel=1e-3)


def test_bad_patches_named():
    with pytest.raises(InputError, match="Patches.normals"):
        Patches(np.zeros((1, 3)), np.array([[0, 0, 2.0]]), np.ones(1), np.ones(1))
    with pytest.raises(InputError, match="Patches.centers"):
        Patches(np.full((1, 3), np.nan), np.array([[0, 0, 1.0]]), np.ones(1), np.ones(1))
