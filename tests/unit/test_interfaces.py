"""interfaces.py owns the contracts: one list of kinds, optional capabilities with defaults, input checks."""
import re

import numpy as np
import pytest

from xnlos_core import Backend, Detector, Detections, ForwardModel, InputError, PluginError, WallEstimator
from xnlos_core.config import PipelineConfig, StageConfig
from xnlos_core.interfaces import BASES, KINDS, STAGE_KINDS
from xnlos_core.registry import get_registry
from xnlos_core.testing import CHECKS, small_radar, synthetic_frame


def test_one_list_of_kinds():
    assert KINDS == tuple(BASES) and all(BASES[k].kind == k for k in KINDS)
    assert STAGE_KINDS == tuple(k for k in KINDS if k not in ("scene_generator", "nlos_solver", "transient_model"))
    assert tuple(CHECKS) == KINDS
    stage_tables = {name for name, f in PipelineConfig.model_fields.items()
                    if StageConfig in (f.annotation, *getattr(f.annotation, "__args__", ()))}
    assert stage_tables == set(STAGE_KINDS)


class _Source(Backend):
    def frames(self, max_frames=None):
        self.check_max_frames(max_frames)
        yield synthetic_frame()


class _Blind(Detector):
    def detect(self, frame):
        self.check_frame(frame)
        return Detections.empty()


class _Flat(ForwardModel):
    def simulate(self, scene, radar, rng, timestamp=0.0, index=0):
        return synthetic_frame(radar)


class _Mean(WallEstimator):
    def estimate(self, detections):
        return []


def test_optional_capabilities_default_to_not_available():
    assert _Source().n_frames is None
    assert _Blind().heatmap(synthetic_frame()) is None
    assert _Mean().warm_up(16) == 0
    flat = _Flat()
    assert not flat.supports_adc
    with pytest.raises(PluginError, match="_Flat.simulate_adc: this forward model renders RA maps only"):
        flat.simulate_adc(None, small_radar(), np.random.default_rng(0))


def test_builtin_forward_models_declare_their_adc_cubes():
    reg = get_registry()
    assert all(reg.create("forward_model", name).supports_adc for name in ("image", "raytrace"))


@pytest.mark.parametrize("bad", [-1, 1.5, "2", [1]])
def test_base_checks_max_frames(bad):
    with pytest.raises(InputError, match=re.escape(f"_Source.frames: max_frames must be None or an integer ≥ 0, "
                                                   f"got {bad!r}")):
        list(_Source().frames(bad))


def test_base_checks_the_frame():
    with pytest.raises(InputError, match=r"_Blind.detect: expected a Frame, got ndarray"):
        _Blind().detect(np.zeros((4, 4)))
