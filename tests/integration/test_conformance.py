"""Every registered plugin passes the conformance kit a third-party author would run; the kit takes a
registered name, a class or a plugin module, reports each check, and runs as parametrised pytest tests."""
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core import UNCLASSIFIED, Backend, Detector, Detections, InputError, PluginError, Tracker, Tracks, hookimpl
from xnlos_core.io import save_frame
from xnlos_core.registry import get_registry
from xnlos_core.testing import (check_backend, check_component, check_detector, parametrize_with_checks, small_radar,
                                synthetic_frame)
from xnlos_core.types import Frame, RAMap

pytestmark = pytest.mark.filterwarnings("ignore::xnlos_core.errors.GridMismatchWarning")  # toy maps, not the models' grid

REG = get_registry()
CASES = [(c.kind, c.name) for c in REG.components() if c.provider.startswith("xnlos ")]

ROOT = Path(__file__).resolve().parents[2]


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
    if (kind, name) == ("scene_generator", "osm"):
        params = {"map": str(ROOT / "configs" / "maps" / "intersection.osm"),
                  "radar": {"lat": 41.393, "lon": 2.161, "heading": 44.0}}
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


class _Peaks(Detector):
    """The strongest cell of the map, class-agnostic (a minimal detector for the kit's own tests)."""

    classifies = False

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid")
        min_power: float = Field(1.0, gt=0, description="weakest peak power reported [-]")

    def detect(self, frame):
        self.check_frame(frame)
        power = frame.ra_map.power
        i, j = np.unravel_index(np.argmax(power), power.shape)
        if power[i, j] < self.params.min_power:
            return Detections.empty()
        ra = frame.ra_map
        return Detections([ra.range_axis[i]], [ra.azimuth_axis[j]], [UNCLASSIFIED], [1.0])


def _plugin_module(*components):
    """A plugin module registering (kind, name, class) components through the hook."""
    module = types.ModuleType("kit_test_plugin")

    @hookimpl
    def xnlos_register_components(registry):
        for kind, name, cls in components:
            registry.add(kind, name, cls)

    module.xnlos_register_components = xnlos_register_components
    return module


def test_check_component_takes_a_class_or_a_plugin_module_and_reports_each_check(capsys):
    by_class = check_component("detector", _Peaks, {"min_power": 2.0})
    assert by_class.passed == ["detector:_Peaks(min_power=2.0)::is a Detector", "detector:_Peaks(min_power=2.0)::params",
                               "detector:_Peaks(min_power=2.0)::detector contract"]
    assert check_component(_Peaks, {"min_power": 2.0}).passed == by_class.passed  # the kind from the class
    contract = by_class.results[2]
    assert "finds a 35 dB target within 2 m" in contract.steps and "the same detections twice" in contract.steps
    text = str(by_class).splitlines()
    assert text[0] == "detector:_Peaks(min_power=2.0): 3 checks passed"
    assert text[2].startswith("  PASSED params: a strict Params model")
    assert capsys.readouterr().out == ""  # quiet unless asked

    report = check_component(_plugin_module(("detector", "peaks", _Peaks)), verbose=True)
    assert [r.component for r in report] == ["detector:peaks"] * 3
    printed = capsys.readouterr().out.splitlines()
    assert printed[0] == f"detector:peaks ({__name__}._Peaks)" and printed[1:] == [f"  {r}" for r in report]


def test_check_component_names_what_is_broken():
    class NotADetector(Tracker):
        def update(self, points, timestamp):
            raise AssertionError("never called")

    with pytest.raises(AssertionError, match="NotADetector: is not a xnlos_core.Detector subclass"):
        check_component("detector", NotADetector)

    class Loose(_Peaks):
        class Params(BaseModel):
            min_power: float = 1.0

    with pytest.raises(AssertionError, match="Loose: Params must set model_config = ConfigDict"):
        check_component(Loose)

    class Listy(_Peaks):
        def detect(self, frame):
            return []

    with pytest.raises(AssertionError, match="Listy: detect\\(\\) returned list, not Detections"):
        check_component(Listy)
    with pytest.raises(AssertionError, match="kit_test_plugin: xnlos_register_components registered no component"):
        check_component(_plugin_module())
    with pytest.raises(TypeError, match="a plugin module"):
        check_component(42)
    with pytest.raises(PluginError, match="did you mean 'cfar'"):
        check_component("detector", "cfra")


def test_parametrize_with_checks_makes_one_test_per_component_and_check():
    mark = parametrize_with_checks([("detector", _Peaks), ("detector", "cfar", {"pfa": 1e-4}),
                                    _plugin_module(("detector", "peaks", _Peaks), ("tracker", "kit_nearest", _Still))])
    argnames, pairs = mark.args
    ids = mark.kwargs["ids"]
    assert argnames == "component, check" and len(pairs) == len(ids) == 12
    assert ids[:4] == ["detector:_Peaks-is_a_Detector", "detector:_Peaks-params", "detector:_Peaks-detector_contract",
                       "detector:cfar(pfa=0.0001)-is_a_Detector"]
    assert ids[-1] == "tracker:kit_nearest-tracker_contract"
    for component, check in pairs[:3] + pairs[-3:]:  # each pair runs on its own, a fresh instance each
        assert check(component).check == check.name
    component, check = pairs[-1]
    with pytest.raises(AssertionError, match="_Still: one moving point produced track ids"):
        _Still.jumpy = True
        try:
            check(component)
        finally:
            _Still.jumpy = False


class _Still(Tracker):
    """One track per frame for each point, ids counting up when ``jumpy`` (a broken tracker)."""

    jumpy = False

    def reset(self):
        self.n = 0

    def update(self, points, timestamp):
        self.n += 1
        ids = np.arange(len(points)) + (self.n if self.jumpy else 0)
        return Tracks(ids, points.mean, np.zeros_like(points.mean), points.mean, timestamp)


@parametrize_with_checks([("detector", _Peaks, {"min_power": 2.0}), _plugin_module(("tracker", "kit_still", _Still))])
def test_the_kit_as_pytest_tests(component, check):
    result = check(component)
    assert result.component == component.id and result.steps


def test_the_kit_imports_pytest_only_where_its_marks_are_asked_for():
    code = ("import sys, xnlos_core.testing as kit; assert 'pytest' not in sys.modules; "
            "kit.parametrize_with_checks([]); assert 'pytest' in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, timeout=120)
