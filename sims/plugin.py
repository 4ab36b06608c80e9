"""Registers the built-in forward models (entry point ``xnlos-sims`` of group ``xnlos.plugins``)."""
from xnlos_core import hookimpl

from .image import ImageForwardModel


@hookimpl
def xnlos_register_components(registry):
    registry.add("forward_model", "image", ImageForwardModel)
