"""Entry point ``xnlos-mirror``: registers the analytic mirror reconstructor (mirror)."""
from xnlos_core import hookimpl


@hookimpl
def xnlos_register_components(registry):
    from .mirror import MirrorReconstructor

    registry.add("reconstructor", "mirror", MirrorReconstructor)
