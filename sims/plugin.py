"""Registers the built-in forward models, scene generators (the families and ``osm``, a scene from a map file), the ``dataset`` backend and the ``spad``
transient model (entry point
``xnlos-sims`` of group ``xnlos.plugins``)."""
from xnlos_core import hookimpl

from .commands import xnlos_add_commands, xnlos_check_config  # noqa: F401  (hook implementations)


@hookimpl
def xnlos_register_components(registry):
    from .dataset.backend import DatasetBackend
    from .generators.components import COMPONENTS
    from .image import ImageForwardModel
    from .maps.generator import OsmSceneGenerator
    from .raytrace.model import RaytraceForwardModel
    from .spad.model import SpadTransientModel

    registry.add("forward_model", "image", ImageForwardModel)
    registry.add("forward_model", "raytrace", RaytraceForwardModel)
    for name, component in COMPONENTS.items():
        registry.add("scene_generator", name, component)
    registry.add("scene_generator", "osm", OsmSceneGenerator)
    registry.add("backend", "dataset", DatasetBackend)
    registry.add("transient_model", "spad", SpadTransientModel)

