"""Entry point ``xnlos-hardware``: registers the recorded-frame replay backend (npz)."""
from xnlos_core import hookimpl


@hookimpl
def xnlos_register_components(registry):
    from .npz import NPZBackend

    registry.add("backend", "npz", NPZBackend)
