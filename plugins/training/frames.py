"""Frames for training through the registry's ``dataset`` backend.

Training reads the maps a simulated dataset holds, but the shared training core and the learned
stages import no other stage: they ask the component registry for the ``dataset`` backend (the one a
pipeline's ``[backend]`` table names) and read core :class:`xnlos_core.types.Frame` objects from it,
as any pipeline does. A third-party dataset backend registered under that name serves training too.
"""
from __future__ import annotations

from pathlib import Path

from xnlos_core.interfaces import Backend
from xnlos_core.registry import get_registry


def dataset_backend(path: str | Path, split: str, base_dir: str | Path = ".", verify: bool = True) -> Backend:
    """The ``dataset`` backend over ``split`` ("train", "val", "test" or "all") of the dataset directory
    ``path`` (relative paths from ``base_dir``, the training config's folder). Its ``frames()`` yields the
    split's maps in order, ``n_frames`` counts them and ``record()`` describes the whole dataset."""
    where = Path(base_dir) / Path(path).expanduser()
    return get_registry().create("backend", "dataset", {"path": str(where), "split": split, "verify": verify},
                                 source=f"training data {str(path)!r}")
