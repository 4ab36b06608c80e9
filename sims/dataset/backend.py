"""``dataset`` backend: the maps of one split of an `xnlos simulate` dataset, in order, with ground truth.

Frames come from :func:`sims.dataset.reader.open_dataset` (shard order; ``frame.index`` is the global map
index, ``frame.meta`` names the scene family, split and seeds). ``start`` skips the first maps of
the split, ``limit`` caps how many are read. The radar configuration is the dataset's own (each
frame's RA map carries it); ``open``'s radar argument is not used. ``path`` in a pipeline file is
relative to that file's folder (:mod:`xnlos_core.param_paths`); the default ``out/data/default``
(what ``make dataset`` writes) and a path given in Python are relative to the working directory.
"""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.errors import InputError
from xnlos_core.interfaces import Backend
from xnlos_core.types import Frame
from xnlos_core.param_paths import ConfigPath

from .reader import open_dataset
from .shard import DatasetError

SPLIT_NAMES = ("train", "val", "test", "all")


class DatasetParams(BaseModel):
    """Which maps of which dataset to read."""

    model_config = ConfigDict(extra="forbid")
    path: ConfigPath = Field("out/data/default", min_length=1,
                             description="dataset directory written by `xnlos simulate` (holds manifest.json), "
                                         "relative to the config file's folder (the default: to the working "
                                         "directory)")
    split: Literal["train", "val", "test", "all"] = Field("test", description="split to read; 'all': every map")
    start: int = Field(0, ge=0, description="skip this many maps of the split first")
    limit: int | None = Field(None, ge=1, description="read at most this many maps (None: to the split's end)")
    verify: bool = Field(True, description="check each shard's sha256 before reading it")


class DatasetBackend(Backend):
    """Maps ``start`` … ``start + limit`` − 1 of a dataset split, as Frames with ground truth."""

    Params = DatasetParams
    own_radar = True

    def source_radar(self):
        """The dataset's radar (its manifest); None while ``path`` holds no readable dataset."""
        path = Path(self.params.path).expanduser()
        if not (path / "manifest.json").is_file():
            return None
        try:
            return open_dataset(path, None, verify=False).radar
        except DatasetError:
            return None

    def dataset(self):
        """The opened :class:`sims.dataset.reader.Dataset` view; InputError naming the path or split
        when the directory is not a (finished) dataset."""
        p = self.params
        path = Path(p.path).expanduser()
        if not path.is_dir():
            raise InputError(f"DatasetBackend: params.path {str(path)!r} is not a directory; generate a dataset "
                             "with `xnlos simulate configs/datasets/smoke.toml --out DIR` and point path at DIR")
        if not (path / "manifest.json").is_file():
            raise InputError(f"DatasetBackend: params.path {str(path)!r} holds no manifest.json (not a dataset "
                             "written by `xnlos simulate`)")
        try:
            return open_dataset(path, None if p.split == "all" else p.split, verify=p.verify)
        except DatasetError as exc:
            raise InputError(f"DatasetBackend (params.path {str(path)!r}, split {p.split!r}): {exc}") from None

    def record(self) -> dict:
        """Provenance of the whole dataset (every split), for a model trained on it: its name, the
        sha256 of its generating config, a sha256 over its shards' hashes, its map count and the maps
        per split. Training records it beside the checkpoint."""
        import hashlib
        import json

        path = Path(self.params.path).expanduser()
        try:
            ds = open_dataset(path, None, verify=False)
        except DatasetError as exc:
            raise InputError(f"DatasetBackend (params.path {str(path)!r}): {exc}") from None
        shards = sorted(s["sha256"] for s in ds.shards)
        digest = hashlib.sha256(json.dumps({"config": ds.manifest.get("config_sha256"), "shards": shards},
                                           sort_keys=True).encode()).hexdigest()
        return {"name": ds.manifest.get("name"), "config_sha256": ds.manifest.get("config_sha256"),
                "sha256": digest, "n_maps": len(ds),
                "splits": {k: v.get("n_maps") for k, v in ds.manifest.get("splits", {}).items()}}

    @property
    def n_frames(self) -> int:
        """Number of maps this backend yields (after ``start`` and ``limit``)."""
        n = max(len(self.dataset()) - self.params.start, 0)
        return n if self.params.limit is None else min(n, self.params.limit)

    def frames(self, max_frames: int | None = None) -> Iterator[Frame]:
        """Yield up to ``max_frames`` (all when None) of the selected maps in dataset order."""
        self.check_max_frames(max_frames)
        ds = self.dataset()
        p = self.params
        stop = len(ds) if p.limit is None else min(len(ds), p.start + p.limit)
        if max_frames is not None:
            stop = min(stop, p.start + max_frames)
        if p.start >= len(ds) and len(ds):
            raise InputError(f"DatasetBackend: params.start = {p.start} is past the end of split {p.split!r} "
                             f"({len(ds)} maps in {ds.path})")
        for i in range(p.start, stop):
            yield ds[i]  # neighbouring maps share a cached shard
