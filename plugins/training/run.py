"""A training run in its output directory: claimed, resumed or extended, trained epoch by epoch,
finished into a documented model — the same for every learned component.

A trainer (:mod:`.trainers`) supplies its network, data, loss (``train_epoch``) and validation
metric (``validate``); this module does the rest:

* :func:`open_run` claims ``cfg.out`` (:func:`xnlos_core.rundir.claim`, record ``run.json``) for the
  run's identity, :func:`run_sha256`: the config without where outputs go (``out``, ``export``),
  torch's thread count and ``optim.epochs``. So a rerun with a larger ``--epochs`` resumes the
  finished run from ``last.pt`` and trains the extra epochs, one with a smaller ``--epochs`` than
  the run already has is refused, and any other change is another run (refused unless
  ``--overwrite``). The learning-rate schedule spans ``optim.epochs`` (:mod:`.optim`): an extended
  run continues from its step count on the cosine of the new total, so its extra epochs train at a
  higher rate than the last ones of the shorter run did, and it does not equal a run started with
  the larger ``--epochs`` (whose first epochs already decayed more slowly).
* :func:`train_epochs` is the epoch loop: train an epoch → validate → select the best
  (``best.pt``) → early stopping after ``optim.patience`` validations without improvement →
  commit ``last.pt``, the single commit point (:mod:`.resume`) → the metrics line.
* :func:`finish` writes ``model.pt`` (best weights, the training record), the export and
  ``summary.json``. A config's ``export`` that lies inside the installed xnlos package (a shipped
  model) is written only when the command names it (``--export PATH``); otherwise the summary says
  why it was not.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from xnlos_core.errors import ConfigError
from xnlos_core.io import atomic_write_text
from xnlos_core.rundir import claim, package_dir_of, write_record

from . import resume
from .checkpoint import save_checkpoint

RUN_FILES = ("run.json", "metrics.jsonl", "last.pt", "best.pt", "best.json", "model.pt", "model.json",
             "summary.json")


def run_sha256(cfg) -> str:
    """sha256 identifying a run for resuming (module doc): ``cfg`` without out, export, threads and
    optim.epochs."""
    dump = cfg.model_dump(mode="json", exclude={"out", "export", "threads"})
    del dump["optim"]["epochs"]
    return hashlib.sha256(json.dumps(dump, sort_keys=True).encode()).hexdigest()


@dataclass
class Validation:
    """One validation as a trainer reports it to the loop. score: the selection metric; record:
    the metrics (the line's ``val`` and best.pt's ``training.val``); extra: further fields of the
    metrics line; meta: further metadata of best.pt (e.g. decoding thresholds)."""

    score: float
    record: dict[str, Any]
    extra: dict[str, Any] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)


@dataclass
class Run:
    """Progress of a run: epochs done, the best score and its epoch, validations since the best,
    the metrics history and a copy of the best weights (as :func:`.resume.best_copy`)."""

    out: Path
    epochs: int
    patience: int
    minimise: bool
    resumable: bool = False
    epoch: int = 0
    best: float = 0.0
    best_epoch: int = -1
    bad_epochs: int = 0
    history: list[dict[str, Any]] = field(default_factory=list)
    best_weights: tuple[dict, dict] | None = None
    resumed_from: int | None = None  # the epochs a resumed run had done when it was restored

    def stop_reason(self) -> str | None:
        """Why the run ended before ``epochs``, or None (it ran them all, or has not ended)."""
        if self.epoch < self.epochs and self.bad_epochs >= self.patience:
            return (f"stopped early after epoch {self.epoch} of {self.epochs}: {self.bad_epochs} validation(s) without "
                    f"a better score (optim.patience = {self.patience}); the best model is epoch {self.best_epoch}'s")
        return None

    def __post_init__(self):
        self.best = float("inf") if self.minimise else float("-inf")

    def progress(self) -> dict[str, Any]:
        return {"epoch": self.epoch, "best": self.best, "best_epoch": self.best_epoch, "bad_epochs": self.bad_epochs}

    def done(self) -> bool:
        return self.epoch >= self.epochs or self.bad_epochs >= self.patience

    def restore(self, net, opt, sched, architecture: str, map_location="cpu") -> None:
        """Load ``last.pt`` into ``net``, ``opt``, ``sched`` and this record (also torch's RNG
        states: call after the network is built). ConfigError when the run already has more epochs
        than ``optim.epochs``."""
        if not self.resumable:
            resume.start_fresh(self.out)
            return
        saved = resume.load_resume(self.out, architecture, map_location=map_location)
        p = _progress(saved.progress)
        if p["epoch"] > self.epochs:
            raise ConfigError(f"{self.out}: holds a run of {p['epoch']} epochs, longer than optim.epochs = "
                              f"{self.epochs}; give --epochs {p['epoch']} or more to resume or extend it, or "
                              "choose another --out")
        net.load_state_dict(saved.state_dict)
        opt.load_state_dict(saved.optimizer)
        sched.load_state_dict(saved.scheduler)
        self.epoch, self.best, self.best_epoch, self.bad_epochs = (p[k] for k in ("epoch", "best", "best_epoch",
                                                                                  "bad_epochs"))
        self.history, self.best_weights = saved.history, saved.best
        self.resumed_from = self.epoch


def _progress(p: dict) -> dict[str, Any]:
    """``last.pt``'s progress in today's keys, also from the two trainers' earlier records."""
    if "state" in p:  # residual mirror before the shared loop
        return {"epoch": p["epoch"], "best": p["state"]["best"], "best_epoch": p["state"]["best_epoch"],
                "bad_epochs": p["state"]["bad"]}
    return {"epoch": p["epoch"], "best": p.get("best", p.get("best_f1")), "best_epoch": p["best_epoch"],
            "bad_epochs": p["bad_epochs"]}


def config_path(base_dir: str | Path, path: str | Path) -> Path:
    """``path`` from a training config, resolved against the config file's folder ``base_dir``
    (absolute paths stay as they are), as every path in every xnlos config is; ``..`` folded away
    (``os.path.normpath``) so that printed paths read ``out/train/tiny``, not
    ``configs/training/../../out/train/tiny``."""
    path = Path(path)
    return Path(os.path.normpath(path if path.is_absolute() else Path(base_dir) / path))


def open_run(cfg, *, overwrite: bool, minimise: bool, base_dir: str | Path = ".") -> Run:
    """Claim ``cfg.out`` (relative to ``base_dir``, the config file's folder) for this run (module
    doc), write ``run.json``; the returned :class:`Run` resumes from ``last.pt`` when
    :meth:`Run.restore` is called, if there is one."""
    out = config_path(base_dir, cfg.out)
    ident, digest = run_sha256(cfg), cfg.digest()
    # config_sha256 decides for directories written before run_sha256 existed (epochs included then)
    old = claim(out, "run.json", {"run_sha256": ident, "config_sha256": digest}, overwrite=overwrite,
                what="a training run", clear=RUN_FILES)
    write_record(out, "run.json", {"config": cfg.model_dump(mode="json"), "config_sha256": digest, "run_sha256": ident})
    return Run(out, cfg.optim.epochs, cfg.optim.patience, minimise,
               resumable=old is not None and (out / resume.LAST).is_file())


def train_epochs(run: Run, net, opt, sched, meta: dict[str, Any], train_epoch: Callable[[int], dict],
                 validate: Callable[[int], Validation | None], line: Callable[[dict], str],
                 progress: bool = True) -> None:
    """Train until ``run`` is done (module doc). train_epoch(epoch) trains one epoch and returns
    its fields of the metrics line; validate(epoch) returns a :class:`Validation` or None (no
    validation this epoch); line(record) is the progress line; meta: the metadata of every
    checkpoint (architecture, hyper-parameters, …)."""
    from tqdm import tqdm

    if run.resumed_from is not None and progress:
        tqdm.write(f"resuming {run.out} after epoch {run.resumed_from} of {run.epochs}" +
                   ("" if run.best_epoch < 0 else f" (best so far: epoch {run.best_epoch})"))
    while not run.done():
        epoch = run.epoch + 1
        rec: dict[str, Any] = {"epoch": epoch, **train_epoch(epoch)}
        v = validate(epoch)
        if v is not None:
            rec.update(val=v.record, **v.extra)
            if v.score < run.best if run.minimise else v.score > run.best:
                run.best, run.best_epoch, run.bad_epochs = v.score, epoch, 0
                run.best_weights = resume.best_copy(net, {**meta, **v.meta, "training": {"epoch": epoch, "val": v.record}})
                save_checkpoint(run.out / resume.BEST, *run.best_weights)
            else:
                run.bad_epochs += 1
        run.epoch = epoch
        run.history.append(rec)
        resume.save_epoch(run.out, net, {**meta, "training": {"epoch": epoch}}, opt.state_dict(), sched.state_dict(),
                          run.progress(), run.history, run.best_weights)
        if progress:
            tqdm.write(line(rec))


def export_target(export: str | None, named: bool, base_dir: str | Path = ".") -> tuple[Path | None, str | None]:
    """(where the final model goes besides ``out``, or None; why not, or None). ``named``: the
    command line named ``export`` (``--export``), the only way to write into the installed package.
    ``base_dir``: the config file's folder, which a relative ``export`` is taken from."""
    if export is None:
        return None, None
    export = str(config_path(base_dir, export))
    package = package_dir_of(export)
    if package is not None and not named:
        return None, (f"not exported to {export}: it lies inside the installed xnlos package ({package}); "
                      f"pass --export {export} to replace the shipped model")
    return Path(export), None


def finish(cfg, run: Run, net, meta: dict[str, Any], *, dataset: dict[str, Any], metrics: dict[str, Any],
           source: str, named_export: bool = False, training: dict[str, Any] | None = None,
           summary: dict[str, Any] | None = None, base_dir: str | Path = ".") -> dict[str, Any]:
    """Write ``model.pt`` (``net`` with ``meta`` and the training record), the export and
    ``summary.json``; returns the summary. training / summary: a trainer's further fields;
    base_dir: the config file's folder (a relative ``export`` is taken from it)."""
    import torch

    out = run.out
    epochs = [r for r in run.history if "train_seconds" in r]
    record = {
        "config": cfg.model_dump(mode="json"), "config_sha256": cfg.digest(), "config_file": source,
        "command": f"xnlos train {source}", "dataset": dataset, "best_epoch": run.best_epoch,
        "epochs_run": len(epochs), "torch": torch.__version__,
        "seconds_per_epoch": float(np.mean([r["train_seconds"] for r in epochs])) if epochs else None,
        "metrics": metrics, "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"), **(training or {}),
    }
    n_params = sum(p.numel() for p in net.parameters())
    save_checkpoint(out / "model.pt", net, {**meta, "n_parameters": n_params, "training": record})
    dest, skipped = export_target(cfg.export, named_export, base_dir)
    if dest is not None:
        dest.parent.mkdir(parents=True, exist_ok=True)
        for src, dst in ((out / "model.pt", dest), (out / "model.json", dest.with_suffix(".json"))):
            shutil.copyfile(src, dst.with_name(dst.name + ".tmp"))
            dst.with_name(dst.name + ".tmp").replace(dst)
    result = {"out": str(out), "model": str(out / "model.pt"), "export": str(dest) if dest else None,
              "best_epoch": run.best_epoch, "epochs_run": len(epochs), "n_parameters": n_params,
              "seconds_per_epoch": record["seconds_per_epoch"], "stopped_early": len(epochs) < cfg.optim.epochs,
              "stop_reason": run.stop_reason(), "resumed_from_epoch": run.resumed_from, **(summary or {})}
    if skipped:
        result["export_skipped"] = skipped
    atomic_write_text(out / "summary.json", json.dumps(result, indent=2, sort_keys=True, default=str) + "\n")
    return result
