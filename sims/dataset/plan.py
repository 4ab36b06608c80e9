"""The dataset plan: scene seeds, families, splits and shards, all derived from the root seed.

Every number comes from ``numpy.random.SeedSequence(seed)`` and its spawned children (no global
RNG), addressed by spawn key so that any one of them is computed alone:

* ``SeedSequence(seed, spawn_key=(0, k))`` — child k of child 0 of the root, i.e.
  ``SeedSequence(seed).spawn(4)[0].spawn(k + 1)[k]`` — gives scene k's seed;
* ``(1, k, f)`` gives the noise seed of frame f of scene k (the ``rng`` of the forward model);
* ``(2,)`` shuffles the family assignment, ``(3,)`` the split assignment.

Scene and noise seeds are 63-bit integers (they fit int64 arrays and JSON). The plan depends
only on the (resolved) config, so a shard can be rebuilt alone and the dataset is the same
whatever the number of workers or the order in which shards finish.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import SPLITS, DatasetConfig


def child_seed(root: int, *key: int) -> int:
    """A 63-bit integer drawn from ``SeedSequence(root, spawn_key=key)``."""
    state = np.random.SeedSequence(root, spawn_key=key).generate_state(1, np.uint64)[0]
    return int(state >> np.uint64(1))


def scene_seed(root: int, scene: int) -> int:
    """Seed handed to the scene generator for scene index ``scene``."""
    return child_seed(root, 0, scene)


def noise_seed(root: int, scene: int, frame: int) -> int:
    """Seed of ``numpy.random.default_rng`` for frame ``frame`` of scene ``scene`` (noise, phases)."""
    return child_seed(root, 1, scene, frame)


def apportion(weights, total: int) -> list[int]:
    """Integer counts ∝ ``weights`` summing to ``total`` (largest remainder; ties to the earlier)."""
    w = np.asarray(weights, dtype=np.float64)
    quota = w / w.sum() * total
    counts = np.floor(quota + 1e-9).astype(int)
    rest = total - int(counts.sum())
    order = sorted(range(len(w)), key=lambda i: (-(quota[i] - counts[i]), i))
    for i in order[:max(rest, 0)]:
        counts[i] += 1
    return [int(c) for c in counts]


def spread_labels(counts: list[int]) -> list[int]:
    """A sequence with exactly ``counts[j]`` labels j, each label spread evenly along it.

    Position i takes the label with the largest deficit (i + 1)·n_j − S·assigned_j (ties to the
    lower label); no label exceeds its count and the totals are exact.
    """
    total = sum(counts)
    assigned = [0] * len(counts)
    out = []
    for i in range(total):
        deficit = [(i + 1) * n - total * a for n, a in zip(counts, assigned)]
        j = max(range(len(counts)), key=lambda k: (deficit[k], -k))
        assigned[j] += 1
        out.append(j)
    return out


@dataclass(frozen=True)
class ShardSpec:
    """One work unit: the file ``name``, its ``split`` and the global scene indices it holds."""

    name: str
    split: str
    scenes: tuple[int, ...]
    frames_per_scene: int

    @property
    def n_maps(self) -> int:
        return len(self.scenes) * self.frames_per_scene


def reduced_counts(fractions, n: int, available: list[int]) -> list[int]:
    """Scenes per split of a reduced dataset: ``apportion(fractions, n)``, each count at most
    ``available[j]`` (the full plan's scenes of split j; n ≤ their sum).

    Largest remainder need not be monotone in the total (the Alabama paradox), so a split could
    ask for one scene more than the full plan holds; that scene then goes to the split, among those
    with room, whose count falls furthest below its quota (ties to the earlier split).
    """
    if n > sum(available):
        raise ValueError(f"n = {n} scenes, but the full plan holds only {sum(available)}")
    counts = [min(c, a) for c, a in zip(apportion(fractions, n), available)]
    w = np.asarray(fractions, dtype=np.float64)
    quota = w / w.sum() * n
    while sum(counts) < n:
        j = max((i for i in range(len(counts)) if counts[i] < available[i]),
                key=lambda i: (quota[i] - counts[i], -i))
        counts[j] += 1
    return counts


@dataclass(frozen=True)
class Plan:
    """The S scenes of a dataset, in ascending global scene index: ``scene_index`` (S,),
    ``scene_seed`` (S,) int64, ``family`` (S,), ``split`` (S,); shards in file order.

    A full dataset's scene indices are 0 … S−1; a reduced one (``--max-maps``) holds a subset of
    its full plan's indices, so positions and indices differ: look a scene up by index with
    :meth:`scene`.
    """

    scene_seed: np.ndarray
    family: tuple[str, ...]
    split: tuple[str, ...]
    shards: tuple[ShardSpec, ...]
    scene_index: tuple[int, ...]

    def shard(self, name: str) -> ShardSpec:
        for s in self.shards:
            if s.name == name:
                return s
        raise KeyError(name)

    def scene(self, k: int) -> tuple[int, str, str]:
        """(scene seed, family, split) of global scene index ``k``; KeyError if the plan lacks it."""
        pos = self._positions().get(int(k))
        if pos is None:
            raise KeyError(f"scene index {k} is not in this plan ({len(self.scene_index)} scenes)")
        return int(self.scene_seed[pos]), self.family[pos], self.split[pos]

    def _positions(self) -> dict[int, int]:
        cache = self.__dict__.get("_pos")
        if cache is None:
            cache = {k: i for i, k in enumerate(self.scene_index)}
            object.__setattr__(self, "_pos", cache)
        return cache

    @property
    def contiguous(self) -> bool:
        """True when the scene indices are 0 … S−1 (every full dataset)."""
        return self.scene_index == tuple(range(len(self.scene_index)))

    def split_seeds(self) -> dict[str, list[int]]:
        """split → the scene seeds in it (each scene seed lands in exactly one split)."""
        return {sp: [int(s) for s, x in zip(self.scene_seed, self.split) if x == sp] for sp in SPLITS}


def make_plan(config: DatasetConfig) -> Plan:
    """The plan of a dataset: a pure function of the config.

    Families get exact counts ∝ weight (largest remainder) in a shuffled order. For the split,
    the scenes are ordered family by family (families sorted by name, scenes shuffled within
    each) and labelled with :func:`spread_labels`, so split sizes are exact and each split
    takes its share of every family. A split's scenes are then cut, in index order, into shards
    of ``shard_size // frames_per_scene`` scenes named ``{split}-{i:05d}.npz``.

    A reduced dataset (``full_n_maps``, from ``--max-maps``) draws families and splits for the
    full dataset's scenes and keeps, of each split, its first k_s scenes in index order, with
    k_s = :func:`reduced_counts` (the split fractions apportioned over ``n_scenes``): split sizes
    follow the fractions exactly, and every kept scene has the full dataset's index, seed,
    family, split and noise seeds, so its maps are the full dataset's. Its scene indices are
    then not contiguous.
    """
    n, n_plan = config.n_scenes, config.plan_scenes
    root = config.seed
    weights = config.weights()
    fams = sorted(weights)
    pool = [f for f, c in zip(fams, apportion([weights[f] for f in fams], n_plan)) for _ in range(c)]
    fam_rng = np.random.default_rng(np.random.SeedSequence(root, spawn_key=(2,)))
    family = tuple(pool[i] for i in fam_rng.permutation(n_plan))

    split_rng = np.random.default_rng(np.random.SeedSequence(root, spawn_key=(3,)))
    order = []
    for f in fams:
        members = np.array([k for k in range(n_plan) if family[k] == f], dtype=np.int64)
        order.extend(int(k) for k in split_rng.permutation(members))
    fractions = [getattr(config.split, s) for s in SPLITS]
    labels = spread_labels(apportion(fractions, n_plan))
    split = [""] * n_plan
    for k, lab in zip(order, labels):
        split[k] = SPLITS[lab]

    by_split = {sp: [k for k in range(n_plan) if split[k] == sp] for sp in SPLITS}
    if n < n_plan:  # a reduced dataset: the first k_s scenes of each split of the full plan
        counts = reduced_counts(fractions, n, [len(by_split[sp]) for sp in SPLITS])
        by_split = {sp: by_split[sp][:c] for sp, c in zip(SPLITS, counts)}
    index = sorted(k for sp in SPLITS for k in by_split[sp])
    seeds = np.array([scene_seed(root, k) for k in index], dtype=np.int64)

    per_shard = config.shard_size // config.frames_per_scene
    shards = []
    for sp in SPLITS:
        idx = by_split[sp]
        for i, start in enumerate(range(0, len(idx), per_shard)):
            shards.append(ShardSpec(f"{sp}-{i:05d}.npz", sp, tuple(idx[start:start + per_shard]),
                                    config.frames_per_scene))
    return Plan(seeds, tuple(family[k] for k in index), tuple(split[k] for k in index), tuple(shards),
                tuple(index))
