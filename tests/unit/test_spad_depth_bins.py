"""One depth-bin convention from the SPAD forward model to the NLOS solvers: bin k is centred at
round trip t_k = t0 + kΔ (sims/spad/transport.py) and the solvers put it at depth z_k = c·t_k/2
(estimators/nlos/prep.py). A single point return at a known depth, rendered by the forward model
and reconstructed by each solver, comes back at that depth: exactly (to rounding) on a bin centre,
and in the NEAREST bin (error ≤ ¼ bin) a quarter bin either side of it. A half-bin slip between the
two conventions (edge vs centre) moves every error by ½ bin and fails both."""
import numpy as np
import pytest

from sims.spad.transport import Optics, Patches, expected_transient, histogram
from xnlos_core.registry import get_registry
from xnlos_core.transient import SPEED_OF_LIGHT as C
from xnlos_core.transient import TransientVolume

N, WALL, BINS, K = 16, 1.0, 256, 100
BW = 2 * 1.2 / C / BINS  # 1.2 m of depth over 256 bins (4.7 mm per bin)


def _point_volume(frac: float, t0_bins: int = 0) -> tuple[TransientVolume, float]:
    """Forward-model counts of one facing patch under scan point (8, 8) at depth (K + frac) bins."""
    x = (np.arange(N) - (N - 1) / 2) * (WALL / N)
    z = (K + frac) * BW * C / 2
    p = Patches(np.array([[x[8], x[8], z]]), np.array([[0.0, 0.0, -1.0]]), np.array([1e-4]), np.array([0.5]))
    t0 = t0_bins * BW
    vol = expected_transient(x, x, p, Optics(), n_bins=BINS - t0_bins, bin_width=BW, n_pulses=1, t0=t0)
    return TransientVolume(vol, BW, WALL, WALL, t0), z


def test_a_return_on_a_bin_centre_lands_wholly_in_that_bin():
    v = histogram(np.ones((1, 1, 1)), np.full((1, 1, 1), 7 * BW + 2e-9), 16, BW, t0=2e-9)
    assert v[7, 0, 0] == pytest.approx(1.0) and v.sum() == pytest.approx(1.0)


@pytest.mark.parametrize("name", ["lct", "fk"])
@pytest.mark.parametrize("frac, t0_bins", [(0.0, 0), (0.25, 0), (0.75, 0), (0.0, 40)])
def test_point_return_reconstructs_at_its_depth(name, frac, t0_bins):
    vol, z = _point_volume(frac, t0_bins)
    nv = get_registry().create("nlos_solver", name, {"dtype": "float64"}).reconstruct(vol)
    k, i, j = nv.peak_index()
    assert (i, j) == (8, 8)
    dz = BW * C / 2
    err = (nv.z[k] - z) / dz  # [bins]
    # closed form: the nearest bin centre round(K + frac) is the peak; its depth error is −frac or 1 − frac
    assert k == int(np.rint(K + frac))
    assert abs(err) <= (1e-6 if frac == 0 else 0.25 + 1e-6), (name, frac, err)
