"""Seeded fuzz of the f-k and LCT solvers (every registered nlos_solver) on generated transient volumes.

The inputs are valid TransientVolumes a careless or hostile caller can build: tiny and odd shapes
(1–40 bins, 1–6 scan points a side, non-square grids), counts that are zero, a single spike, Poisson,
constant, only at round trip t = 0, or spread over 1e-300 … 1e300 (up to float64's largest value);
bin widths, wall sizes and t0 over 1e-300 … 1e300 (t0 of either sign, whole or fractional numbers of
bins, near the 66.7 µs bound and padding towards MAX_BINS), and solver parameters (float32/float64,
LCT's snr over 1e-300 … 1e300, diffuse or not, f-k's Stolt chunk).

Every case must end in a finite, non-negative NLOSVolume of the prepared shape whose depths are
k·c·bin_width/2, or a *typed* project error from the short list of the solvers' boundary checks
(estimators/nlos/prep.py, LCT's snr bounds); 0 tracebacks, 0 hangs, no RuntimeWarning (an overflow on
the way is a bug even when the result comes out finite).

Case counts come from the ``fuzz_cases`` fixture (50 in ``make test``, 10,000 in ``make fuzz``).
Each test prints its tally (``pytest -s``).
"""
from __future__ import annotations

import collections
import warnings

import numpy as np
import pytest

from estimators.nlos.prep import MAX_BINS, MAX_T0
from xnlos_core.errors import ConfigError, InputError, InsufficientDataError, XnlosError
from xnlos_core.nlos_volume import NLOSVolume
from xnlos_core.registry import get_registry
from xnlos_core.transient import SPEED_OF_LIGHT, TransientVolume

pytestmark = pytest.mark.fuzz

SOLVERS = get_registry().names("nlos_solver")
# The typed errors a solver may raise on a valid TransientVolume (prep.py) or parameters (LCTParams).
EXPECTED = {
    "non-square scan grid": "H ≠ W",
    "scan grid; expected at least 2 × 2": "grid < 2 × 2",
    "volume.bin_width =": "bin width out of range",
    "volume.wall_width =": "wall width out of range",
    "volume.wall_height =": "wall height out of range",
    "volume.t0 = ": "t0 out of range",
    "is not a whole number of bins": "t0 not whole bins",
    "time bins from t = 0": "< 8 bins",
    "holds no counts": "no counts",
    "albedo is zero everywhere": "zero albedo",
    "overflows float64": "albedo overflows",
}


def log_uniform(rng: np.random.Generator, lo: float, hi: float, size=None):
    return 10.0 ** rng.uniform(lo, hi, size)


def random_counts(rng: np.random.Generator) -> np.ndarray:
    """A (T, H, W) array of finite counts ≥ 0 of one of several adversarial kinds."""
    t = int(rng.choice([1, 4, 7, 8, 9, 12, 16, 17, 24, 32, 40]))
    n = int(rng.integers(2, 7)) if rng.random() < 0.9 else 1
    h, w = (n, n) if rng.random() < 0.9 else (n, int(rng.integers(1, 7)))
    kind = rng.integers(8)
    if kind == 0:
        d = np.zeros((t, h, w))
    elif kind == 1:  # one spike
        d = np.zeros((t, h, w))
        d[rng.integers(t), rng.integers(h), rng.integers(w)] = log_uniform(rng, -300, 300)
    elif kind == 2:  # Poisson, scaled by any decade
        d = rng.poisson(rng.uniform(0.1, 20), (t, h, w)) * log_uniform(rng, -300, 300)
    elif kind == 3:  # a constant
        d = np.full((t, h, w), log_uniform(rng, -300, 300))
    elif kind == 4:  # counts only at t = 0
        d = np.zeros((t, h, w))
        d[0] = rng.poisson(5.0, (h, w))
    elif kind == 5:  # log-uniform over 600 decades
        d = log_uniform(rng, -300, 300, (t, h, w))
    elif kind == 6:  # at float64's largest values (a sum of several overflows)
        d = np.zeros((t, h, w))
        d[rng.integers(t), rng.integers(h), rng.integers(w)] = np.finfo(np.float64).max * rng.uniform(0.1, 1)
    else:  # a return on a faint floor
        d = 1e-12 * rng.random((t, h, w))
        d[min(t - 1, 5 + int(rng.integers(3)))] += 10.0
    return d


def random_volume(rng: np.random.Generator) -> TransientVolume:
    """Counts of :func:`random_counts` in a geometry that is sane (about half the cases: the solvers
    run) or adversarial (any decade, either side of each bound)."""
    d = random_counts(rng)
    if rng.random() < 0.5:
        bw, ww = float(rng.choice([1e-11, 4e-12, 1e-9, 3e-11])), float(rng.choice([1.0, 2.0, 0.5]))
        return TransientVolume(d, bw, ww, ww, float(rng.choice([0.0, 0.0, int(rng.integers(-2, 9)) * bw])))
    bw = float(rng.choice([1e-11, log_uniform(rng, -300, 300), log_uniform(rng, -16, -5)]))
    ww = float(rng.choice([1.0, log_uniform(rng, -300, 300), log_uniform(rng, -7, 5)]))
    wh = ww if rng.random() < 0.8 else float(log_uniform(rng, -8, 5))
    kind = rng.integers(7)
    if kind == 0:
        t0 = 0.0
    elif kind == 1:  # whole bins, either sign
        t0 = int(rng.integers(-len(d), 3 * len(d) + 1)) * bw
    elif kind == 2:  # not a whole number of bins
        t0 = (int(rng.integers(-5, 20)) + rng.uniform(0.01, 0.99)) * bw
    elif kind == 3:  # any decade, either sign
        t0 = float(rng.choice([-1.0, 1.0]) * log_uniform(rng, -300, 300))
    elif kind == 4:  # at and beyond the bound
        t0 = float(rng.choice([-1.0, 1.0]) * MAX_T0 * rng.choice([1.0, 1 + 1e-9, 2.0]))
    elif kind == 5:  # padding to about MAX_BINS
        t0 = int(MAX_BINS - len(d) + rng.integers(-2, 3)) * bw
    else:
        t0 = 0.0
    return TransientVolume(d, bw, ww, wh, t0)


def random_params(rng: np.random.Generator, name: str) -> dict:
    p = {"dtype": str(rng.choice(["float32", "float64"])), "workers": 1}
    if name == "lct":
        p["snr"] = float(rng.choice([0.8, log_uniform(rng, -300, 300), log_uniform(rng, -13, 13), 1e-12, 1e12]))
        p["diffuse"] = bool(rng.random() < 0.7)
    if name == "fk":
        p["chunk"] = int(rng.choice([1, 2, 64]))
    return p


def check_result(out: NLOSVolume, vol: TransientVolume) -> None:
    """Finite, non-negative, the scan grid of the volume, depths k·c·bin_width/2 from t = 0."""
    assert isinstance(out, NLOSVolume)
    t, h, w = vol.shape
    m = t + int(round(vol.t0 / vol.bin_width))
    assert out.albedo.shape == (m, h, w)
    assert np.all(np.isfinite(out.albedo)) and out.albedo.min() >= 0 and out.albedo.max() > 0
    z = np.arange(m) * (SPEED_OF_LIGHT * vol.bin_width / 2)
    assert np.allclose(out.z, z, rtol=1e-12, atol=0)
    out.peak()


def report(name: str, tally: collections.Counter) -> None:
    print(f"\n[fuzz] {name}: {sum(tally.values())} cases, " + ", ".join(f"{k}: {v}" for k, v in sorted(tally.items())))


@pytest.mark.parametrize("name", SOLVERS)
def test_solvers_on_random_volumes(name, fuzz_cases):
    rng = np.random.default_rng(280 + SOLVERS.index(name))
    reg = get_registry()
    tally = collections.Counter()
    for _ in range(fuzz_cases):
        vol = random_volume(rng)
        params = random_params(rng, name)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error", RuntimeWarning)
                solver = reg.create("nlos_solver", name, params)
                out = solver.reconstruct(vol)
        except ConfigError as exc:
            assert name == "lct" and "snr" in str(exc) and not 1e-12 <= params["snr"] <= 1e12, exc
            tally["ConfigError (snr out of range)"] += 1
            continue
        except (InputError, InsufficientDataError) as exc:
            key = next((v for k, v in EXPECTED.items() if k in str(exc)), None)
            assert key is not None, f"unexpected {type(exc).__name__}: {exc}"
            tally[f"{type(exc).__name__} ({key})"] += 1
            continue
        except XnlosError as exc:
            pytest.fail(f"{type(exc).__name__}: {exc}")
        check_result(out, vol)
        tally["ok"] += 1
    report(name, tally)


def test_non_finite_volumes_are_refused_and_cannot_be_corrupted(fuzz_cases):
    """NaN and inf cannot reach a solver: TransientVolume refuses them (counts, bin width, wall size,
    t0), and its counts are read-only afterwards."""
    rng = np.random.default_rng(285)
    bad_values = [np.nan, np.inf, -np.inf]
    for _ in range(fuzz_cases):
        d = random_counts(rng)
        field = int(rng.integers(5))
        args = [d, 1e-11, 1.0, 1.0, 0.0]
        if field == 0:
            d = d.copy()
            d[rng.integers(d.shape[0]), rng.integers(d.shape[1]), rng.integers(d.shape[2])] = rng.choice(bad_values)
            args[0] = d
            match = r"TransientVolume\.data: .* NaN or infinite"
        else:
            args[field] = float(rng.choice(bad_values))
            match = r"TransientVolume\.(bin_width|wall_width|wall_height|t0): expected a (positive )?finite"
        with pytest.raises(InputError, match=match):
            TransientVolume(*args)
        vol = TransientVolume(random_counts(rng), 1e-11, 1.0, 1.0)
        with pytest.raises(ValueError, match="read-only"):
            vol.data[0, 0, 0] = np.nan
