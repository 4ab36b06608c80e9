"""Entry point ``xnlos-detectors``: registers the classical detectors (cfar, nlos_cfar), the
ground-truth ``oracle`` (analysis of the later stages) and the
learned ones (swin_unet, unet, further_than_cfar, rtn) with their trainer (``xnlos train`` itself
belongs to the training core, entry point ``xnlos-training``)."""
from plugins.training.trainers import register
from xnlos_core import hookimpl

from .train_config import ARCHITECTURES

register(ARCHITECTURES, "plugins.detectors.train:TRAINER", default="swin_unet")


@hookimpl
def xnlos_register_components(registry):
    from .cfar import CFARDetector
    from .learned import FurtherThanCFARDetector, RTNDetector, SwinUNetDetector, UNetDetector
    from .nlos_cfar import NLOSCFARDetector
    from .oracle import OracleDetector

    registry.add("detector", "cfar", CFARDetector)
    registry.add("detector", "nlos_cfar", NLOSCFARDetector)
    registry.add("detector", "swin_unet", SwinUNetDetector)
    registry.add("detector", "unet", UNetDetector)
    registry.add("detector", "further_than_cfar", FurtherThanCFARDetector)
    registry.add("detector", "rtn", RTNDetector)
    registry.add("detector", "oracle", OracleDetector)

