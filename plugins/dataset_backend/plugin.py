"""Entry point ``xnlos-dataset-backend``: registers the ``dataset`` backend (a dataset split as frames)."""
from xnlos_core import hookimpl


@hookimpl
def xnlos_register_components(registry):
    from .backend import DatasetBackend

    registry.add("backend", "dataset", DatasetBackend)
