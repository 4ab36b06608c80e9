"""``xnlos train configs/training/residual_mirror.toml``: train the residual network Δo_θ (Sec. 4.2,
Eq. 9) on pairs built from a simulated dataset's ground truth (:mod:`.data`).

Loss: L = L_geo (Eq. 9, ℓ1 [m], trains Δo_θ) + ``nll_weight``·Laplace NLL (trains the predicted
scales only, :func:`.net.laplace_nll`). Validation per epoch: L_geo, NLL and the mean hidden-point
error [m] of the analytic mirror and of the corrected one. Reproducible: pairs are seeded by
(seed, map index, draw); batch order of epoch e by ``numpy.random.default_rng([seed, e])``; the
initial weights by a torch generator seeded with ``seed`` inside ``torch.random.fork_rng`` (the
global RNG state is left untouched). A rerun resumes after the last finished epoch and gives
the same result as an uninterrupted run.

Files in ``out`` (written atomically): ``run.json`` (config + digest), ``metrics.jsonl`` (one
record per epoch), ``last.pt`` (weights + optimizer + scheduler + progress + RNG states + metrics
history + best weights, sealed by one hash; ``metrics.jsonl`` and ``best.pt`` are rebuilt from it
on resume: :mod:`plugins.detectors.resume`, shared with detector training), ``best.pt`` (lowest
validation L_geo), ``model.pt`` (+ ``model.json``; the best weights with metadata), copied to
``export``.
Checkpoints use :mod:`plugins.detectors.checkpoint` (state_dict + JSON metadata, weights hash,
``torch.load(weights_only=True)``) with architecture ``residual_mirror``.

TOML::

    name = "residual_mirror"
    seed = 0
    out = "out/train/residual_mirror"
    export = "plugins/residual_mirror/models/residual_mirror.pt"
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
import math
import shutil
import time
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.config import load_toml, validate_model
from xnlos_core.io import atomic_write_text

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


class RMOptim(BaseModel):
    model_config = ConfigDict(extra="forbid")
    epochs: int = Field(30, ge=1, le=10_000)
    batch_size: int = Field(256, ge=1, le=1_000_000)
    lr: float = Field(3e-3, gt=0, le=1)
    weight_decay: float = Field(1e-4, ge=0, le=1)
    nll_weight: float = Field(0.1, ge=0, le=100, description="weight of the Laplace NLL next to Eq. 9")
    grad_clip: float = Field(1.0, gt=0)
    patience: int = Field(8, ge=1, description="early stopping: epochs without a lower validation L_geo")


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


def is_residual_config(table: dict) -> bool:
    """True for a training table whose [model] name is residual_mirror (dispatch in ``xnlos train``)."""
    model = table.get("model")
    return isinstance(model, dict) and model.get("name") == ARCHITECTURE


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


def fit(net, train: dict, val: dict | None, optim: RMOptim, seed: int, epochs: int | None = None, state=None,
        on_epoch=None, progress: bool = False) -> list[dict]:
    """Train ``net`` in place on :func:`tensors` ``train`` (AdamW, Eq. 9 + nll_weight·NLL); returns the
    per-epoch records (cosine learning-rate decay over all epochs). ``state`` ({optimizer,
    scheduler, epoch}) resumes; ``on_epoch(epoch, rec, states)`` is called after each epoch with the
    optimizer and scheduler state dicts and returns True to stop."""
    import torch
    from tqdm import tqdm

    n = len(train["target"])
    steps = -(-n // optim.batch_size)
    total_steps = steps * (epochs or optim.epochs)
    opt = torch.optim.AdamW(net.parameters(), lr=optim.lr, weight_decay=optim.weight_decay)
    # cosine decay to 2 % of lr; plain floats so the scheduler state loads with weights_only=True
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda i: 0.02 + 0.98 * 0.5 * (1 + math.cos(math.pi * min(1.0, i / max(1, total_steps)))))
    first = 1
    if state is not None:
        opt.load_state_dict(state["optimizer"])
        sched.load_state_dict(state["scheduler"])
        first = state["epoch"] + 1
    history = []
    for epoch in range(first, (epochs or optim.epochs) + 1):
        t0 = time.perf_counter()
        net.train()
        order = torch.from_numpy(np.random.default_rng([seed, epoch]).permutation(n))
        total = 0.0
        bar = tqdm(range(steps), desc=f"epoch {epoch}/{epochs or optim.epochs}", unit="batch", disable=not progress,
                   leave=False)
        for b in bar:
            idx = order[b * optim.batch_size:(b + 1) * optim.batch_size]
            g, l = step_losses(net, {k: v[idx] for k, v in train.items()})
            loss = g + optim.nll_weight * l
            opt.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), optim.grad_clip)
            opt.step()
            sched.step()
            total += g.item()
            bar.set_postfix(l_geo=f"{total / (b + 1):.3f}")
        bar.close()
        rec: dict[str, Any] = {"epoch": epoch, "train_l_geo": total / steps, "train_seconds": time.perf_counter() - t0}
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
          source: str = "<config>") -> dict[str, Any]:
    """Train per ``cfg`` and write the files of the module doc; returns a summary."""
    import torch
    from tqdm import tqdm

    from plugins.detectors.checkpoint import load_checkpoint, save_checkpoint
    from plugins.detectors.resume import best_copy, load_resume, save_epoch, start_fresh
    from plugins.detectors.train import _prepare_out  # same run.json / resume rule as detector training
    from sims.dataset import open_dataset

    from .data import build_pairs
    from .reconstructor import ResidualMirrorReconstructor

    out = Path(cfg.out)
    resume = _prepare_out(out, cfg, overwrite)
    if cfg.threads:
        torch.set_num_threads(cfg.threads)
    recon = ResidualMirrorReconstructor()
    t0 = time.perf_counter()
    sets = {}
    for split, draws, cap in (("train", cfg.data.draws, cfg.data.max_train_maps),
                              ("val", cfg.data.val_draws, cfg.data.max_val_maps)):
        ds = open_dataset(cfg.data.dataset, getattr(cfg.data, f"{split}_split"))
        seed = cfg.seed if split == "train" else cfg.seed + 1_000_003
        sets[split] = build_pairs(ds, recon, cfg.data.noise, seed, draws, cfg.model.neighbours,
                                  cfg.model.support_distance, cap, progress)
        sets[split + "_maps"] = min(len(ds), cap or len(ds))
    manifest = Path(cfg.data.dataset) / "manifest.json"
    data_rec = {"dataset": cfg.data.dataset, "n_train_pairs": len(sets["train"]["target"]),
                "n_val_pairs": len(sets["val"]["target"]), "n_train_maps": sets["train_maps"],
                "n_val_maps": sets["val_maps"], "pairs_seconds": time.perf_counter() - t0,
                "manifest_sha256": hashlib.sha256(manifest.read_bytes()).hexdigest() if manifest.is_file() else None}
    train_t, val_t = tensors(sets["train"]), tensors(sets["val"])
    net = new_network(cfg.model.params, cfg.seed)
    base_meta = {"architecture": ARCHITECTURE, "hparams": cfg.model.params.model_dump(mode="json"),
                 "neighbours": cfg.model.neighbours, "support_distance": cfg.model.support_distance,
                 "noise": cfg.data.noise.model_dump(), "features": {"version": 1, "query": N_QUERY, "point": N_POINT}}
    progress_state = {"best": float("inf"), "best_epoch": 0, "bad": 0}
    state = None
    history: list[dict[str, Any]] = []
    best_weights = None
    if resume:
        saved = load_resume(out, ARCHITECTURE)  # also restores torch's RNG states
        net.load_state_dict(saved.state_dict)
        progress_state = dict(saved.progress["state"])
        state = {"optimizer": saved.optimizer, "scheduler": saved.scheduler, "epoch": int(saved.progress["epoch"])}
        history, best_weights = saved.history, saved.best
    else:
        start_fresh(out)

    def on_epoch(epoch, rec, states):
        nonlocal best_weights
        v = rec["val"]
        if v["l_geo"] < progress_state["best"]:
            progress_state.update(best=v["l_geo"], best_epoch=epoch, bad=0)
            best_weights = best_copy(net, {**base_meta, "training": {"epoch": epoch, "val": v}})
            save_checkpoint(out / "best.pt", *best_weights)
        else:
            progress_state["bad"] += 1
        history.append(rec)
        save_epoch(out, net, {**base_meta, "training": {"epoch": epoch}}, states["optimizer"], states["scheduler"],
                   {"epoch": epoch, "state": dict(progress_state)}, history, best_weights)
        if progress:
            tqdm.write(f"epoch {epoch}: train L_geo {rec['train_l_geo']:.3f} m, val L_geo {v['l_geo']:.3f} m, "
                       f"NLL {v['nll']:.3f}, error {v['error_m']:.3f} m (mirror {v['mirror_error_m']:.3f} m)")
        return progress_state["bad"] >= cfg.optim.patience

    done = state is not None and (state["epoch"] >= cfg.optim.epochs or progress_state["bad"] >= cfg.optim.patience)
    if not done:
        fit(net, train_t, val_t, cfg.optim, cfg.seed, state=state, on_epoch=on_epoch, progress=progress)
    sd, meta, _ = load_checkpoint(out / "best.pt")
    net.load_state_dict(sd)
    val = evaluate(net, val_t)
    epochs = [r for r in history if "train_seconds" in r]
    training = {"config": cfg.model_dump(mode="json"), "config_sha256": cfg.digest(), "config_file": source,
                "command": f"xnlos train {source}", "dataset": data_rec, "best_epoch": meta["training"]["epoch"],
                "epochs_run": len(epochs), "torch": torch.__version__,
                "seconds_per_epoch": float(np.mean([r["train_seconds"] for r in epochs])) if epochs else None,
                "metrics": {"val": val}, "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    n_params = sum(p.numel() for p in net.parameters())
    save_checkpoint(out / "model.pt", net, {**base_meta, "n_parameters": n_params, "training": training})
    if cfg.export:
        dest = Path(cfg.export)
        dest.parent.mkdir(parents=True, exist_ok=True)
        for src, dst in ((out / "model.pt", dest), (out / "model.json", dest.with_suffix(".json"))):
            shutil.copyfile(src, dst.with_name(dst.name + ".tmp"))
            dst.with_name(dst.name + ".tmp").replace(dst)
    summary = {"out": str(out), "model": str(out / "model.pt"), "export": cfg.export, "val": val,
               "best_epoch": training["best_epoch"], "epochs_run": len(epochs), "n_parameters": n_params,
               "seconds_per_epoch": training["seconds_per_epoch"], "dataset": data_rec}
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2, sort_keys=True, default=str) + "\n")
    return summary


def cli_train(args) -> int:
    """``xnlos train CONFIG`` for a residual_mirror config (same flags as for detectors; --device is ignored: CPU)."""
    table = load_toml(args.config)
    for key, value in (("out", args.out),):
        if value is not None:
            table[key] = str(value)
    if args.epochs is not None:
        table.setdefault("optim", {})["epochs"] = args.epochs
    cfg = parse_config(table, str(args.config))
    s = train(cfg, overwrite=args.overwrite, progress=not args.quiet, source=str(args.config))
    v = s["val"]
    print(f"{s['epochs_run']} epoch(s) ({s['seconds_per_epoch'] or 0:.1f} s/epoch), best epoch {s['best_epoch']}: "
          f"validation L_geo {v['l_geo']:.3f} m, hidden-point error {v['error_m']:.3f} m (analytic mirror "
          f"{v['mirror_error_m']:.3f} m); wrote {s['model']}" + (f" and {s['export']}" if s.get("export") else ""))
    return 0


def check_config(table: dict, path) -> str:
    """``xnlos check`` line for a residual_mirror training config (raises ConfigError when invalid)."""
    cfg = parse_config(table, str(path))
    return f"{path}: valid training config (model {cfg.model.name}, {cfg.optim.epochs} epochs)"
