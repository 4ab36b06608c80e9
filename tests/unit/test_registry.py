import pluggy
import pytest

from xnlos_core import Detector, Detections, PluginError, hookimpl
from xnlos_core.registry import PluginManager, get_registry

BUILTINS = {("forward_model", "image"), ("detector", "cfar"), ("detector", "nlos_cfar"),
            ("wall_estimator", "lsq"), ("reconstructor", "mirror"), ("reconstructor", "residual_mirror"), ("tracker", "nearest"), ("backend", "npz")}


def test_builtins_register_through_entry_points():
    reg = get_registry()
    for kind, name in BUILTINS:
        comp = reg.get(kind, name)
        assert comp.provider.startswith("xnlos "), comp.provider  # distribution + version


def test_unknown_name_lists_known():
    with pytest.raises(PluginError, match=r"unknown detector 'nope'; registered detectors: .*cfar.*nlos_cfar"):
        get_registry().get("detector", "nope")
    with pytest.raises(PluginError, match="known kinds: forward_model"):
        get_registry().get("detektor", "cfar")


class _Dummy(Detector):
    """A do-nothing detector."""

    def detect(self, frame):
        return Detections.empty()


class _LatePlugin:
    @hookimpl
    def xnlos_register_components(self, registry):
        registry.add("detector", "dummy", _Dummy)


def test_late_plugin_is_called_historically_and_duplicates_fail():
    mgr = PluginManager(autoload=True)
    mgr.register(_LatePlugin(), name="late", provider="late-dist 1.0")
    assert mgr.registry.get("detector", "dummy").provider == "late-dist 1.0"
    with pytest.raises(PluginError, match="already registered by late-dist 1.0"):
        mgr.register(_LatePlugin(), name="late2", provider="other")


def test_factory_must_subclass_the_interface():
    class Bad:
        @hookimpl
        def xnlos_register_components(self, registry):
            registry.add("detector", "bad", dict)

    with pytest.raises(PluginError, match="must subclass xnlos_core.interfaces.Detector"):
        PluginManager(autoload=False).register(Bad(), name="bad")


def test_check_pending_catches_misspelt_hook():
    class Typo:
        @hookimpl
        def xnlos_register_component(self, registry):  # missing "s"
            pass

    with pytest.raises(pluggy.PluginValidationError, match="unknown hook"):
        PluginManager(autoload=False).register(Typo(), name="typo")


def test_disable_autoload_and_allow_list(monkeypatch):
    assert PluginManager(autoload=False).registry.components() == []
    only = PluginManager(autoload=True, allow=["xnlos-detectors"]).registry
    assert {c.kind for c in only.components()} == {"detector"}
    monkeypatch.setenv("XNLOS_DISABLE_PLUGIN_AUTOLOAD", "1")
    assert PluginManager().registry.components() == []
    monkeypatch.setenv("XNLOS_PLUGINS", "xnlos-sims")
    from sims.generators import FAMILIES

    sims_only = PluginManager().registry
    assert sims_only.names("forward_model") == ["image", "raytrace"]
    assert sims_only.names("scene_generator") == sorted([*FAMILIES, "osm"])  # the families and the map importer
    assert {c.kind for c in sims_only.components()} == {"forward_model", "scene_generator", "backend", "transient_model"}
    assert sims_only.names("backend") == ["dataset"]  # the dataset backend lives with the dataset
    assert sims_only.names("transient_model") == ["spad"]  # the SPAD simulator of the cross-modality study
