"""Entry point ``xnlos-detectors``: registers the classical detectors (cfar, nlos_cfar)."""
from xnlos_core import hookimpl


@hookimpl
def xnlos_register_components(registry):
    from .cfar import CFARDetector
    from .nlos_cfar import NLOSCFARDetector

    registry.add("detector", "cfar", CFARDetector)
    registry.add("detector", "nlos_cfar", NLOSCFARDetector)
