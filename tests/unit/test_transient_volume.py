"""TransientVolume (xnlos_core/transient.py): validation, grid and time axes."""
import numpy as np
import pytest

from xnlos_core.errors import InputError
from xnlos_core.transient import SPEED_OF_LIGHT, TransientVolume


def test_grid_and_times():
    v = TransientVolume(np.zeros((8, 2, 4)), 1e-11, 1.0, 0.5, t0=2e-9)
    x, y = v.grid()
    np.testing.assert_allclose(x, [-0.375, -0.125, 0.125, 0.375])
    np.testing.assert_allclose(y, [-0.125, 0.125])
    np.testing.assert_allclose(v.times()[[0, -1]], [2e-9, 2e-9 + 7e-11])
    assert v.bin_length == pytest.approx(SPEED_OF_LIGHT * 1e-11) and v.shape == (8, 2, 4)
    with pytest.raises(ValueError):
        v.data[0, 0, 0] = 1.0  # read-only once validated


@pytest.mark.parametrize("bad, match", [
    ({"data": np.full((2, 2, 2), np.nan)}, "finite"), ({"data": -np.ones((2, 2, 2))}, "≥ 0"),
    ({"data": np.zeros((2, 2))}, "TransientVolume.data"), ({"data": np.zeros((0, 2, 2))}, "non-empty"),
    ({"bin_width": 0.0}, "bin_width"), ({"wall_width": -1.0}, "wall_width"), ({"t0": np.inf}, "t0")])
def test_bad_input_names_the_field(bad, match):
    kw = {"data": np.zeros((2, 2, 2)), "bin_width": 1e-11, "wall_width": 1.0, "wall_height": 1.0, **bad}
    with pytest.raises(InputError, match=match):
        TransientVolume(**kw)
