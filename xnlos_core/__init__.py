"""xnlos core: types, plugin interfaces and registry, configuration, signal chain, metrics, CLI."""
# First, before numpy (below), numba or torch load their thread libraries: the process thread policy
# (thread counts from the cores actually available; xnlos_core.threads).
from .threads import apply_process_policy as _apply_process_policy

_apply_process_policy()

from .errors import ConfigError, InputError, InsufficientDataError, PluginError, XnlosError
from .hookspecs import hookimpl
from .interfaces import (KINDS, Backend, Detector, ForwardModel, NLOSSolver, Plugin, Reconstructor,
                         SceneGenerator, Tracker, TransientModel, WallEstimator)
from .radar import RadarConfig
from .types import (CLASS_NAMES, LOS, MNLOS, UNCLASSIFIED, Detections, Frame, GroundTruth,
                    HiddenPoints, RAMap, Tracks, WallPosterior, WallSegment)

__version__ = "0.1.0"

__all__ = [
    "ConfigError", "InputError", "InsufficientDataError", "PluginError", "XnlosError", "hookimpl",
    "KINDS", "Backend", "Detector", "ForwardModel", "NLOSSolver", "Plugin", "Reconstructor", "SceneGenerator", "Tracker", "TransientModel",
    "WallEstimator", "RadarConfig", "CLASS_NAMES", "LOS", "MNLOS", "UNCLASSIFIED", "Detections",
    "Frame", "GroundTruth", "HiddenPoints", "RAMap", "Tracks", "WallPosterior", "WallSegment",
]
