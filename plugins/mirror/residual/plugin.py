"""Entry point ``xnlos-residual-mirror``: registers the learned-residual mirror reconstructor
(residual_mirror) and its trainer (``xnlos train configs/training/residual_mirror.toml``)."""
from plugins.training.trainers import register
from xnlos_core import hookimpl

register(("residual_mirror",), "plugins.mirror.residual.train:TRAINER")  # .net.ARCHITECTURE; .net imports torch


@hookimpl
def xnlos_register_components(registry):
    from .reconstructor import ResidualMirrorReconstructor

    registry.add("reconstructor", "residual_mirror", ResidualMirrorReconstructor)
