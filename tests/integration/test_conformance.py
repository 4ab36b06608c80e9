"""Every registered plugin passes the conformance kit a third-party author would run."""
import numpy as np
import pytest

from xnlos_core import Backend, Detector, Detections, InputError
from xnlos_core.io import save_frame
from xnlos_core.registry import get_registry
from xnlos_core.testing import check_backend, check_component, check_detector, small_radar, synthetic_frame
from xnlos_core.types import Frame, RAMap

pytestmark = pytest.mark.filterwarnings("ignore::xnlos_core.errors.GridMismatchWarning")  # toy maps, not the models' grid

REG = get_registry()
CASES = [(c.kind, c.name) for c in REG.components() if c.provider.startswith("xnlos ")]


@pytest.mark.parametrize("kind,name", CASES, ids=[f"{k}:{n}" for k, n in CASES])
def test_builtin_conforms(kind, name, tmp_path, request):
    params = {}
    if (kind, name) == ("backend", "npz"):
        for k in range(3):
            save_frame(tmp_path / f"{k:02d}.npz", synthetic_frame(seed=k))
        params = {"directory": str(tmp_path)}
    if (kind, name) == ("backend", "replay"):
        from hardware.testing import make_recording

        params = {"file": str(make_recording(tmp_path / "rec.blf"))}
    if (kind, name) == ("backend", "adc"):
        from hardware.testing import make_adc_recording

        params = {"recording": str(make_adc_recording(tmp_path / "adc"))}
    if (kind, name) == ("backend", "dataset"):
        params = {"path": str(request.getfixturevalue("small_dataset")), "split": "all"}
    check_component(kind, name, params)


def test_kit_catches_a_broken_detector():
    class Mutating(Detector):
        def detect(self, frame):
            frame.ra_map.data[:] = 0
            return Detections.empty()

    # RAMap.data is read-only after validation: a plain in-place write fails at once …
    with pytest.raises(ValueError, match="read-only"):
        check_detector(Mutating())

    class Unlocking(Detector):
        def detect(self, frame):
            frame.ra_map.data.flags.writeable = True  # … so only a deliberate unlock can mutate it
            frame.ra_map.data[:] = 0
            return Detections.empty()

    with pytest.raises(AssertionError, match="modified the RA map in place"):
        check_detector(Unlocking())

    class Blind(Detector):
        def detect(self, frame):
            return Detections.empty()

    with pytest.raises(AssertionError, match="no detection within 2 m"):
        check_detector(Blind())


def test_synthetic_frame_is_seeded():
    a, b = synthetic_frame(seed=4), synthetic_frame(seed=4)
    assert np.array_equal(a.ra_map.data, b.ra_map.data)


class _ListBackend(Backend):
    """Yields the frames it was given (after the base class's max_frames check)."""

    def __init__(self, frames):
        super().__init__()
        self._frames = frames

    def frames(self, max_frames=None):
        self.check_max_frames(max_frames)
        yield from self._frames[:max_frames]


def test_kit_demands_a_frame_of_the_radars_grid_from_a_backend():
    check_backend(_ListBackend([synthetic_frame(seed=0), synthetic_frame(seed=1)]))
    with pytest.raises(AssertionError, match="yielded no frame"):
        check_backend(_ListBackend([]))
    radar = small_radar()  # 241 × 61 grid
    wrong = RAMap(np.zeros((radar.n_range_bins, 3), np.complex64), radar.range_axis, np.linspace(-0.1, 0.1, 3), radar)
    with pytest.raises(AssertionError, match=r"RA map shape \(241, 3\) ≠ its radar's grid \(241, 61\)"):
        check_backend(_ListBackend([Frame(wrong)]))


def test_kit_demands_the_max_frames_check():
    class Unchecked(_ListBackend):
        def frames(self, max_frames=None):
            yield from self._frames[:1]

    with pytest.raises(AssertionError, match=r"frames\(-1\) did not raise InputError"):
        check_backend(Unchecked([synthetic_frame()]))
    with pytest.raises(InputError, match=r"_ListBackend.frames: max_frames must be None or an integer ≥ 0, got 1.5"):
        list(_ListBackend([]).frames(1.5))
