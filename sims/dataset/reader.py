"""Reading a dataset: Frames (RA map + exact ground truth) lazily, shard by shard, one split at a time."""
from __future__ import annotations

import hashlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from xnlos_core.radar import RadarConfig
from xnlos_core.types import Frame, GroundTruth, RAMap

from .config import SPLITS
from .shard import DatasetError, decode_npz, frames_from_arrays
from .manifest import SHARD_DIR, completed_records, read_manifest


class Dataset:
    """The maps of dataset directory ``path`` (one ``split`` or all), read lazily shard by shard.

    ``len()`` counts maps; iterating yields :class:`~xnlos_core.types.Frame` objects in shard
    order (``frame.index`` is the global map index; ``frame.meta`` names shard, split, scene,
    family and seeds, and holds ``object_outlines``: the scene objects' true bird's-eye outlines at
    the map's time, :mod:`sims.dataset.outlines`). verify: check each shard's sha256 before parsing it. An unfinished
    dataset is an error unless ``allow_incomplete`` (then only finished shards are read).
    Files are read with ``np.load(allow_pickle=False)`` only.
    """

    def __init__(self, path: str | Path, split: str | None = None, *, verify: bool = True,
                 allow_incomplete: bool = False):
        if split is not None and split not in SPLITS:
            raise DatasetError(f"split {split!r}: expected one of {', '.join(SPLITS)} (or None for all)")
        self.path = Path(path)
        self.split = split
        self.verify = verify
        self.manifest = read_manifest(self.path)
        self.radar = RadarConfig.model_validate(self.manifest["radar"])
        recs = completed_records(self.path, self.manifest)
        wanted = [s for s in self.manifest["shards"] if split is None or s["split"] == split]
        todo = [s["name"] for s in wanted if s["name"] not in recs]
        if todo and not allow_incomplete:
            raise DatasetError(f"{self.path}: {len(todo)} shard(s){'' if split is None else ' of split ' + split} "
                               f"not generated yet (first: {todo[0]}); rerun xnlos simulate to finish, or "
                               "open with allow_incomplete=True")
        self.shards = [{**s, "sha256": recs[s["name"]]["sha256"]} for s in wanted if s["name"] in recs]
        self._starts = np.cumsum([0] + [s["n_maps"] for s in self.shards])
        self._cache: tuple[str, list[Frame]] | None = None

    def __len__(self) -> int:
        return int(self._starts[-1])

    def __iter__(self) -> Iterator[Frame]:
        for s in self.shards:
            yield from self._frames(s)

    def __getitem__(self, i: int) -> Frame:
        """Map ``i`` of this view (0 ≤ i < len); its shard stays cached for neighbouring reads."""
        n = len(self)
        if not -n <= i < n:
            raise IndexError(f"map {i} out of range for a dataset view of {n} maps")
        i %= n
        j = int(np.searchsorted(self._starts, i, side="right")) - 1
        return self._frames(self.shards[j])[i - int(self._starts[j])]

    def pairs(self) -> Iterator[tuple[RAMap, GroundTruth]]:
        """(RA map, ground truth) per map."""
        for f in self:
            yield f.ra_map, f.ground_truth

    def load_shard(self, name: str) -> dict[str, np.ndarray]:
        """Every array of shard ``name`` (see :mod:`sims.dataset.shard` for the keys)."""
        rec = next((s for s in self.shards if s["name"] == name), None)
        if rec is None:
            raise DatasetError(f"{self.path}: no finished shard {name!r} in this view; "
                               f"shards: {', '.join(s['name'] for s in self.shards[:6])}…")
        path = self.path / SHARD_DIR / name
        if not path.is_file():
            raise DatasetError(f"{path}: shard file is missing; repair with: xnlos simulate --repair {self.path}")
        data = path.read_bytes()
        if self.verify:
            got = hashlib.sha256(data).hexdigest()
            if got != rec["sha256"]:
                raise DatasetError(f"{path}: shard {name} is corrupt (sha256 {got[:12]}…, recorded "
                                   f"{rec['sha256'][:12]}…); repair with: xnlos simulate --repair {self.path}")
        return decode_npz(data, name)

    def _frames(self, s: dict[str, Any]) -> list[Frame]:
        if self._cache is None or self._cache[0] != s["name"]:
            frames = frames_from_arrays(self.load_shard(s["name"]), self.radar)
            if len(frames) != s["n_maps"]:  # len() counts the manifest's n_maps: they must agree
                raise DatasetError(f"{self.path / SHARD_DIR / s['name']}: holds {len(frames)} maps but the manifest "
                                   f"records {s['n_maps']}; check with: xnlos simulate --verify {self.path}")
            self._cache = (s["name"], frames)
        return self._cache[1]


def open_dataset(path: str | Path, split: str | None = "train", **kw) -> Dataset:
    """:class:`Dataset` of one split ("train", "val", "test"; None for every map)."""
    return Dataset(path, split, **kw)
