"""Every registered plugin passes the conformance kit a third-party author would run."""
import numpy as np
import pytest

from xnlos_core import Detector, Detections
from xnlos_core.io import save_frame
from xnlos_core.registry import get_registry
from xnlos_core.testing import check_component, check_detector, synthetic_frame

REG = get_registry()
CASES = [(c.kind, c.name) for c in REG.components() if c.provider.startswith("xnlos ")]


@pytest.mark.parametrize("kind,name", CASES, ids=[f"{k}:{n}" for k, n in CASES])
def test_builtin_conforms(kind, name, tmp_path):
    params = {}
    if (kind, name) == ("backend", "npz"):
        for k in range(3):
            save_frame(tmp_path / f"{k:02d}.npz", synthetic_frame(seed=k))
        params = {"directory": str(tmp_path)}
    if (kind, name) == ("backend", "replay"):
        from hardware.testing import make_recording

        params = {"file": str(make_recording(tmp_path / "rec.blf"))}
    if (kind, name) == ("backend", "dataset"):
        from sims.dataset import parse_dataset_config, simulate_dataset
        from tests.test_dataset import table
        from tests.tiny_scenes import tiny_registry

        simulate_dataset(parse_dataset_config(table(n_maps=4), "tiny.toml"), tmp_path, workers=1, progress=False,
                         registry=tiny_registry())
        params = {"path": str(tmp_path), "split": "all"}
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
