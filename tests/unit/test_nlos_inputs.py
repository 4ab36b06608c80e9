"""The f-k and LCT solvers refuse absurd volumes with an InputError naming the input
(estimators/nlos/prep.py), reconstruct counts over float64's whole range instead of returning a
silent all-zero albedo, and refuse an albedo that is zero everywhere with a named cause."""
import numpy as np
import pytest

from estimators.nlos.prep import MAX_BINS, MAX_T0
from xnlos_core.errors import ConfigError, InputError, InsufficientDataError
from xnlos_core.registry import get_registry
from xnlos_core.transient import TransientVolume

SOLVERS = ("fk", "lct")


def solver(name, **params):
    return get_registry().create("nlos_solver", name, params)


def volume(scale=1.0, t=16, n=4, **kw):
    d = np.zeros((t, n, n))
    d[8, 1, 2] = 3.0
    d[11, 2, 2] = 1.0
    return TransientVolume(d * scale, **({"bin_width": 1e-11, "wall_width": 1.0, "wall_height": 1.0} | kw))


@pytest.mark.parametrize("name", SOLVERS)
def test_absurd_t0_is_refused(name):
    """t0 = 1e300 s made int(round(t0 / bin_width)) raise OverflowError."""
    for t0 in (1e300, -1e300, 2 * MAX_T0):
        with pytest.raises(InputError, match=r"volume\.t0 = .* s; expected within ±6\.671e-05 s"):
            solver(name).reconstruct(volume(t0=t0))
    # a t0 that would pad beyond MAX_BINS (1e-5 s of 1e-11 s bins: a million empty bins)
    with pytest.raises(InputError, match=rf"would pad the 16 bins to 1000016 from t = 0; expected at most {MAX_BINS}"):
        solver(name).reconstruct(volume(t0=1e-5))


@pytest.mark.parametrize("name", SOLVERS)
def test_absurd_bin_widths_and_walls_are_refused(name):
    for bw in (1e-300, 1e-16, 1.0, 1e300):
        with pytest.raises(InputError, match=r"volume\.bin_width = .* s; expected 1e-15 … 1e-06 s"):
            solver(name).reconstruct(volume(bin_width=bw))
    for key in ("wall_width", "wall_height"):
        for v in (1e-300, 1e-7, 3e4, 1e300):
            with pytest.raises(InputError, match=rf"volume\.{key} = .* m; expected 1e-06 … 20000 m"):
                solver(name).reconstruct(volume(**{key: v}))


@pytest.mark.parametrize("name", SOLVERS)
@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_tiny_and_huge_counts_scale_the_albedo(name, dtype):
    """Counts ×1e-300 gave an all-zero albedo (float32 underflow) and ×1e39 a NaN one (overflow):
    the albedo is linear in the counts over float64's range, exactly so for powers of four."""
    s = solver(name, dtype=dtype)
    ref = s.reconstruct(volume()).albedo
    assert ref.max() > 0
    for k in (-400, -3, 5, 60):  # 4**-400 ≈ 1e-241 … 4**60 ≈ 1e36
        out = s.reconstruct(volume(4.0 ** k)).albedo
        assert np.array_equal(out, ref * 4.0 ** k), k
    for scale in (1e-300, 1e39, 1e300):
        out = s.reconstruct(volume(scale)).albedo
        assert np.all(np.isfinite(out)) and out.max() > 0, scale
        assert np.allclose(out / scale, ref, rtol=1e-5, atol=1e-6 * ref.max()), scale


def test_albedo_beyond_float64_is_a_typed_error():
    """Counts near float64's largest value (divided by s = 2**1022 for the solve) whose albedo
    exceeds 4 per unit count would overflow once scaled back: refused, naming the counts."""
    from estimators.nlos.prep import prepare

    prep = prepare(volume(5e307), "fk")
    assert prep.scale == 2.0 ** 1022 and prep.data.max() == pytest.approx(3 * 5e307 / 2.0 ** 1022)
    with pytest.raises(InputError, match=r"fk\.reconstruct\(volume\): volume\.data holds counts up to 1\.5e\+308, "
                                         r"and the albedo they give overflows float64"):
        prep.result(np.full(prep.data.shape, 10.0))
    assert prep.result(np.full(prep.data.shape, 1.0)).albedo.max() == 2.0 ** 1022


def test_absurd_snr_is_refused_and_the_bounds_work():
    """snr = 1e-300 made 1/snr inf in float32: an all-zero albedo, silently."""
    for snr in (1e-300, 1e-13, 1e13, 1e300):
        with pytest.raises(ConfigError, match="snr"):
            solver("lct", snr=snr)
    for snr in (1e-12, 1e12):
        out = solver("lct", snr=snr).reconstruct(volume()).albedo
        assert np.all(np.isfinite(out)) and out.max() > 0, snr


@pytest.mark.parametrize("name", SOLVERS)
def test_an_all_zero_albedo_is_refused_naming_the_cause(name):
    """Counts only at round trip t = 0, which the fall-off compensation weights by 0."""
    d = np.zeros((16, 4, 4))
    d[0, 1, 1] = 5.0
    with pytest.raises(InsufficientDataError, match=r"albedo is zero everywhere although volume\.data holds counts"):
        solver(name).reconstruct(TransientVolume(d, 1e-11, 1.0, 1.0))
