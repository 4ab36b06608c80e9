"""Entry point ``xnlos-residual-mirror``: registers the learned-residual mirror reconstructor (residual_mirror)."""
from xnlos_core import hookimpl


@hookimpl
def xnlos_register_components(registry):
    from .reconstructor import ResidualMirrorReconstructor

    registry.add("reconstructor", "residual_mirror", ResidualMirrorReconstructor)
