"""``xnlos train configs/training/residual_mirror.toml``: train the residual network Δo_θ (Sec. 4.2,
Eq. 9) on pairs built from a simulated dataset's ground truth (:mod:`.data`).

Loss: L = L_geo (Eq. 9, ℓ1 [m], trains Δo_θ) + ``nll_weight``·Laplace NLL (trains the predicted
scales only, :func:`.net.laplace_nll`). Validation per epoch: L_geo, NLL and the mean hidden-point
error [m] of the analytic mirror and of the corrected one. Reproducible: pairs are seeded by
(seed, map index, draw); batch order of epoch e by ``numpy.random.default_rng([seed, e])``; the
initial weights by a torch generator seeded with ``seed`` inside ``torch.random.fork_rng`` (the
global RNG state is left untouched). A rerun resumes after the last finished epoch and gives
the same result as an uninterrupted run.

This module supplies the residual's network, pairs, loss and validation metric (lowest L_geo) to
the shared training core (:mod:`plugins.training`), which runs the epochs and writes ``out``
(atomically): ``run.json`` (config + digests), ``metrics.jsonl`` (one record per epoch),
``last.pt`` (weights + optimizer + scheduler + progress + RNG states + metrics history + best
weights, sealed by one hash; ``metrics.jsonl`` and ``best.pt`` are rebuilt from it on resume:
:mod:`plugins.training.resume`), ``best.pt`` (lowest validation L_geo), ``model.pt`` (+
``model.json``; the best weights with metadata), copied to ``export`` (into the installed package
only when the command names it: :func:`plugins.training.run.export_target`).
Checkpoints use :mod:`plugins.training.checkpoint` (state_dict + JSON metadata, weights hash,
``torch.load(weights_only=True)``) with architecture ``residual_mirror``.

TOML::

    name = "residual_mirror"
    seed = 0
    out = "out/train/residual_mirror"
    export = "plugins/mirror/residual/models/residual_mirror.pt"
    threads = 1                        # torch CPU threads (the machine is shared)

    [data]
    dataset = "out/data/default"       # xnlos simulate output; train / val splits
    draws = 1                          # noise draws per training map
    noise = { range_std = 0.15, azimuth_std = 0.0175, los_keep_min = 0.1, scale_min = 0.0 }

    [model]
    name = "residual_mirror"
    params = { dim = 24, heads = 2 }
    neighbours = 16                    # K supporting LOS points per query
    support_distance = 3.0             # [m] LOS points this close to a wall support it

    [optim]
    epochs = 30
    batch_size = 256
    lr = 3e-3
"""
from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from plugins.training.optim import OptimConfig
from plugins.training.trainers import Trainer
from xnlos_core.config import validate_model

from .data import NoiseConfig
from .net import ARCHITECTURE, N_POINT, N_QUERY, HParams


class RMData(BaseModel):
    model_config = ConfigDict(extra="forbid")
    dataset: str = Field(..., description="dataset directory written by `xnlos simulate`")
    train_split: str = "train"
    val_split: str = "val"
    draws: int = Field(2, ge=1, le=100, description="noise draws per training map")
    val_draws: int = Field(1, ge=1, le=100)
    max_train_maps: int | None = Field(None, ge=1)
    max_val_maps: int | None = Field(None, ge=1)
    noise: NoiseConfig = Field(default_factory=NoiseConfig)


class RMModel(BaseModel):
    model_config = ConfigDict(extra="forbid")
    name: Literal["residual_mirror"] = ARCHITECTURE
    params: HParams = Field(default_factory=HParams)
    neighbours: int = Field(16, ge=1, le=1024)
    support_distance: float = Field(3.0, gt=0, le=100)


class RMOptim(OptimConfig):
    """AdamW with a cosine learning-rate schedule (no warm-up) and early stopping on the validation
    L_geo (:mod:`plugins.training.optim`), plus the weight of the Laplace NLL in the loss."""

    DEFAULTS: ClassVar[dict[str, Any]] = {"batch_size": 256, "lr": 3e-3, "grad_clip": 1.0, "patience": 8}
    nll_weight: float = Field(0.1, ge=0, le=100, description="weight of the Laplace NLL next to Eq. 9")


class ResidualTrainConfig(BaseModel):
    """A residual_mirror training run (module doc)."""

    model_config = ConfigDict(extra="forbid")
    name: str = "residual_mirror"
    seed: int = 0
    out: str = "out/train/residual_mirror"
    export: str | None = None
    threads: int = Field(1, ge=0, le=1024, description="torch CPU threads (0: torch's default)")
    data: RMData
    model: RMModel = Field(default_factory=RMModel)
    optim: RMOptim = Field(default_factory=RMOptim)

    def digest(self) -> str:
        return hashlib.sha256(json.dumps(self.model_dump(mode="json"), sort_keys=True).encode()).hexdigest()


def parse_config(table: dict, source: str) -> ResidualTrainConfig:
    """Validated config; errors (ConfigError) name ``source`` and the key."""
    return validate_model(ResidualTrainConfig, table, source=source)


def tensors(pairs: dict[str, np.ndarray]) -> dict:
    """Torch tensors of the network inputs and targets of ``pairs`` (:func:`.data.build_pairs`)."""
    import torch

    return {"query": torch.from_numpy(pairs["query"]), "neigh": torch.from_numpy(pairs["neigh"]),
            "mask": torch.from_numpy(pairs["mask"]),
            "normal": torch.from_numpy(pairs["normal"].astype(np.float32)),
            "target": torch.from_numpy(pairs["target"].astype(np.float32))}


def step_losses(net, batch: dict):
    """(L_geo (Eq. 9) [m], Laplace NLL) of ``net`` on a batch of :func:`tensors`."""
    from .net import geo_loss, laplace_nll, local_to_global

    d_local, log_s = net(batch["query"], batch["neigh"], batch["mask"])
    delta = local_to_global(d_local, batch["normal"])
    return geo_loss(delta, batch["target"]), laplace_nll(d_local, log_s, batch["target"], batch["normal"])


def evaluate(net, data: dict, batch_size: int = 4096) -> dict[str, float]:
    """Validation record: L_geo, NLL and mean hidden-point error [m] with and without Δo_θ."""
    import torch

    from .net import local_to_global

    net.eval()
    geo, nll, err, n = 0.0, 0.0, 0.0, len(data["target"])
    with torch.inference_mode():
        for s in range(0, n, batch_size):
            b = {k: v[s:s + batch_size] for k, v in data.items()}
            g, l = step_losses(net, b)
            d = local_to_global(net(b["query"], b["neigh"], b["mask"])[0], b["normal"])
            geo, nll = geo + float(g) * len(b["target"]), nll + float(l) * len(b["target"])
            err += float(torch.linalg.norm(b["target"] - d, dim=-1).sum())
    return {"l_geo": geo / n, "nll": nll / n, "error_m": err / n,
            "mirror_error_m": float(torch.linalg.norm(data["target"], dim=-1).mean())}


def train_epoch(net, train: dict, opt, sched, optim: RMOptim, seed: int, epoch: int, epochs: int,
                progress: bool = False) -> dict[str, Any]:
    """One epoch over :func:`tensors` ``train`` in the order of ``default_rng([seed, epoch])``
    (loss Eq. 9 + nll_weight·NLL); returns its fields of the metrics line."""
    import torch
    from tqdm import tqdm

    from plugins.training.optim import step

    t0 = time.perf_counter()
    n = len(train["target"])
    steps = -(-n // optim.batch_size)
    net.train()
    order = torch.from_numpy(np.random.default_rng([seed, epoch]).permutation(n))
    total = 0.0
    bar = tqdm(range(steps), desc=f"epoch {epoch}/{epochs}", unit="batch", disable=not progress, leave=False)
    for b in bar:
        idx = order[b * optim.batch_size:(b + 1) * optim.batch_size]
        g, l = step_losses(net, {k: v[idx] for k, v in train.items()})
        step(g + optim.nll_weight * l, net, opt, sched, optim.grad_clip)
        total += g.item()
        bar.set_postfix(l_geo=f"{total / (b + 1):.3f}")
    bar.close()
    return {"train_l_geo": total / steps, "train_seconds": time.perf_counter() - t0}


def optimizer(net, n_pairs: int, optim: RMOptim, epochs: int | None = None):
    """(AdamW, cosine schedule over all ``epochs`` of ``n_pairs`` pairs), :mod:`plugins.training.optim`."""
    from plugins.training.optim import make_optimizer

    return make_optimizer(net, optim, -(-n_pairs // optim.batch_size) * (epochs or optim.epochs))


def fit(net, train: dict, val: dict | None, optim: RMOptim, seed: int, epochs: int | None = None, state=None,
        on_epoch=None, progress: bool = False) -> list[dict]:
    """Train ``net`` in place on :func:`tensors` ``train`` without a run directory (tests,
    experiments); returns the per-epoch records. ``state`` ({optimizer, scheduler, epoch}) resumes;
    ``on_epoch(epoch, rec, states)`` is called after each epoch with the optimizer and scheduler
    state dicts and returns True to stop. ``xnlos train`` runs the same epochs through
    :func:`plugins.training.run.train_epochs`."""
    epochs = epochs or optim.epochs
    opt, sched = optimizer(net, len(train["target"]), optim, epochs)
    first = 1
    if state is not None:
        opt.load_state_dict(state["optimizer"])
        sched.load_state_dict(state["scheduler"])
        first = state["epoch"] + 1
    history = []
    for epoch in range(first, epochs + 1):
        rec: dict[str, Any] = {"epoch": epoch, **train_epoch(net, train, opt, sched, optim, seed, epoch, epochs,
                                                             progress)}
        if val is not None:
            rec["val"] = evaluate(net, val)
        history.append(rec)
        if on_epoch is not None and on_epoch(epoch, rec, {"optimizer": opt.state_dict(), "scheduler": sched.state_dict()}):
            break
    return history


def new_network(hp: HParams, seed: int):
    """A freshly initialised :class:`.net.ResidualAttention`, seeded without touching global RNG state."""
    import torch

    from .net import ResidualAttention

    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        return ResidualAttention(hp)


def train(cfg: ResidualTrainConfig, *, overwrite: bool = False, progress: bool = True,
          source: str = "<config>", named_export: bool = False, base_dir: str | Path = ".") -> dict[str, Any]:
    """Train per ``cfg`` and write the files of the module doc; returns a summary. named_export: the
    command line named ``cfg.export`` (:func:`plugins.training.run.export_target`); base_dir: the
    config file's folder, which relative paths (out, export, dataset) are taken from."""
    import torch

    from plugins.training.checkpoint import load_checkpoint
    from plugins.training.run import Validation, finish, open_run, train_epochs
    from plugins.training.frames import dataset_backend

    from .data import build_pairs
    from .reconstructor import ResidualMirrorReconstructor

    run = open_run(cfg, overwrite=overwrite, minimise=True, base_dir=base_dir)
    if cfg.threads:
        torch.set_num_threads(cfg.threads)
    recon = ResidualMirrorReconstructor()
    t0 = time.perf_counter()
    sets = {}
    for split, draws, cap in (("train", cfg.data.draws, cfg.data.max_train_maps),
                              ("val", cfg.data.val_draws, cfg.data.max_val_maps)):
        ds = dataset_backend(cfg.data.dataset, getattr(cfg.data, f"{split}_split"), base_dir)
        n = ds.n_frames
        seed = cfg.seed if split == "train" else cfg.seed + 1_000_003
        sets[split] = build_pairs(ds.frames(), n, recon, cfg.data.noise, seed, draws, cfg.model.neighbours,
                                  cfg.model.support_distance, cap, progress)
        sets[split + "_maps"] = min(n, cap or n)
    manifest = Path(base_dir) / cfg.data.dataset / "manifest.json"
    data_rec = {"dataset": cfg.data.dataset, "n_train_pairs": len(sets["train"]["target"]),
                "n_val_pairs": len(sets["val"]["target"]), "n_train_maps": sets["train_maps"],
                "n_val_maps": sets["val_maps"], "pairs_seconds": time.perf_counter() - t0,
                "manifest_sha256": hashlib.sha256(manifest.read_bytes()).hexdigest() if manifest.is_file() else None}
    train_t, val_t = tensors(sets["train"]), tensors(sets["val"])
    net = new_network(cfg.model.params, cfg.seed)
    opt, sched = optimizer(net, len(train_t["target"]), cfg.optim)
    run.restore(net, opt, sched, ARCHITECTURE)  # also restores torch's RNG states
    base_meta = {"architecture": ARCHITECTURE, "hparams": cfg.model.params.model_dump(mode="json"),
                 "neighbours": cfg.model.neighbours, "support_distance": cfg.model.support_distance,
                 "noise": cfg.data.noise.model_dump(), "features": {"version": 1, "query": N_QUERY, "point": N_POINT}}

    def validate(epoch: int) -> Validation:
        v = evaluate(net, val_t)
        return Validation(v["l_geo"], v)

    def line(rec: dict[str, Any]) -> str:
        v = rec["val"]
        return (f"epoch {rec['epoch']}: train L_geo {rec['train_l_geo']:.3f} m, val L_geo {v['l_geo']:.3f} m, "
                f"NLL {v['nll']:.3f}, error {v['error_m']:.3f} m (mirror {v['mirror_error_m']:.3f} m)")

    train_epochs(run, net, opt, sched, base_meta,
                 lambda e: train_epoch(net, train_t, opt, sched, cfg.optim, cfg.seed, e, cfg.optim.epochs, progress),
                 validate, line, progress)
    sd, _, _ = load_checkpoint(run.out / "best.pt")
    net.load_state_dict(sd)
    val = evaluate(net, val_t)
    return finish(cfg, run, net, base_meta, dataset=data_rec, metrics={"val": val}, source=source,
                  named_export=named_export, summary={"val": val, "dataset": data_rec}, base_dir=base_dir)


def report(summary: dict[str, Any]) -> str:
    """The line ``xnlos train`` prints for a finished residual_mirror run."""
    v = summary["val"]
    return (f"{summary['epochs_run']} epoch(s) ({summary['seconds_per_epoch'] or 0:.1f} s/epoch), best epoch "
            f"{summary['best_epoch']}: validation L_geo {v['l_geo']:.3f} m, hidden-point error {v['error_m']:.3f} m "
            f"(analytic mirror {v['mirror_error_m']:.3f} m)")


TRAINER = Trainer(parse=parse_config, train=train, report=report)
