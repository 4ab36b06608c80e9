"""Entry point ``xnlos-detectors``: registers the classical detectors (cfar, nlos_cfar) and the
learned ones (swin_unet, unet, further_than_cfar, rtn)."""
from xnlos_core import hookimpl


@hookimpl
def xnlos_register_components(registry):
    from .cfar import CFARDetector
    from .learned import FurtherThanCFARDetector, RTNDetector, SwinUNetDetector, UNetDetector
    from .nlos_cfar import NLOSCFARDetector

    registry.add("detector", "cfar", CFARDetector)
    registry.add("detector", "nlos_cfar", NLOSCFARDetector)
    registry.add("detector", "swin_unet", SwinUNetDetector)
    registry.add("detector", "unet", UNetDetector)
    registry.add("detector", "further_than_cfar", FurtherThanCFARDetector)
    registry.add("detector", "rtn", RTNDetector)


@hookimpl
def xnlos_add_commands(subparsers):
    from .commands import add_commands

    add_commands(subparsers)


@hookimpl
def xnlos_check_config(table, path):
    from .commands import check_config

    return check_config(table, path)
