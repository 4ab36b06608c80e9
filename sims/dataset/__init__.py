"""Dataset generation: sharded, resumable, verifiable RA-map datasets with ground truth (`xnlos simulate`).

>>> from sims.dataset import load_dataset_config, simulate_dataset, open_dataset
>>> simulate_dataset(load_dataset_config("configs/datasets/smoke.toml"), "out/smoke")   # doctest: +SKIP
>>> for frame in open_dataset("out/smoke", "train"):                                   # doctest: +SKIP
...     frame.ra_map.data, frame.ground_truth.hidden_points
"""
from .config import SPLITS, DatasetConfig, SplitConfig, load_dataset_config, parse_dataset_config, resolve
from .plan import Plan, ShardSpec, make_plan, noise_seed, scene_seed
from .manifest import manifest_config, read_manifest
from .reader import Dataset, open_dataset
from .shard import SCHEMA_VERSION, DatasetError, build_shard
from .verify import VerifyReport, verify_dataset
from .writer import simulate_dataset

__all__ = [
    "SPLITS", "DatasetConfig", "SplitConfig", "load_dataset_config", "parse_dataset_config", "resolve",
    "Plan", "ShardSpec", "make_plan", "noise_seed", "scene_seed", "Dataset", "open_dataset",
    "SCHEMA_VERSION", "DatasetError", "build_shard", "VerifyReport", "manifest_config", "read_manifest",
    "simulate_dataset", "verify_dataset",
]
