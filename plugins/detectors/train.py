"""The detectors' trainer: what a learned detector (Sec. 4.2, Eq. 8) brings to the shared training
core (:mod:`plugins.training`): its network, maps and crops (:class:`Batcher`), the head's loss and
the validation Macro-F1 over the decoding grid; the core runs the epochs, checkpoints and resume.

Reproducibility: the data order and crops of epoch e come from ``numpy.random.default_rng([seed,
e])``; the initial weights from ``torch.manual_seed(seed)``, called once here at the start of a
run — the only place xnlos seeds torch's global generator (nn.init draws from it). A resumed run
continues from the last finished epoch and gives the same result as an uninterrupted one.

Files in ``out``: ``run.json`` (config and its digest), ``metrics.jsonl`` (one fsync'd record per
epoch: train loss, validation loss and Macro-F1 over the decoding grid, seconds), ``last.pt``
(weights + optimizer + schedule + progress + RNG states + metrics history + best weights, sealed
by one hash: the resume point, :mod:`plugins.training.resume`; ``metrics.jsonl`` and ``best.pt`` are rebuilt from
it on resume, so no crash separates an epoch's line from its checkpoint), ``best.pt`` (best
validation Macro-F1) and ``model.pt`` (the final model: best weights with tuned decoding and
calibrated standard deviations; ``export`` copies it, :mod:`plugins.training.run`). All written
atomically.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from xnlos_core.errors import ConfigError, InputError
from plugins.training.trainers import Trainer

from .train_config import TrainConfig, check_train_config, parse_train_config

FEATURES = {"version": 2, "channels": ["log_power_10db_over_median", "cos_phase", "sin_phase", "occlusion"],
            "dynamic_range_db": 200.0}


def features_record(channels) -> dict[str, Any]:
    """The checkpoint's ``features`` record: what a detector builds for the network's inputs
    (:func:`plugins.detectors.features.map_features`); version 3 adds the Doppler channels."""
    rec = {**FEATURES, "channels": list(channels)}
    return rec if rec["channels"] == FEATURES["channels"] else {**rec, "version": 3}


def _round_up(n: int, m: int) -> int:
    return -(-n // m) * m


class Batcher:
    """Training batches of (features, targets) with seeded order and crops (aligned to the
    network's multiple so the patch grid sits as at inference), optionally mirrored in azimuth.

    ``flip``: each sample is mirrored in azimuth with probability 1/2 — features reversed along
    azimuth before the zero padding (which stays at the high-azimuth end, as at inference), peak
    azimuth indices a → W − 1 − a. Valid for an azimuth axis symmetric about boresight: the
    power and the occlusion channel mirror exactly, and the phase of a centred array's beamformed
    map is unchanged by the mirror. The extra draw is made only when ``flip``, so runs without it
    draw exactly the order and crops they drew before the option existed."""

    def __init__(self, maps, head, multiple: tuple[int, int], crop: tuple[int, int] | None, batch_size: int,
                 flip: bool = False):
        self.maps, self.head, self.multiple, self.batch_size, self.flip = maps, head, multiple, batch_size, flip
        h, w = maps.features.shape[-2:]
        self.full = (_round_up(h, multiple[0]), _round_up(w, multiple[1]))
        if crop is None:
            self.crop = self.full
        else:
            self.crop = (min(_round_up(crop[0], multiple[0]), self.full[0]),
                         min(_round_up(crop[1], multiple[1]), self.full[1]))

    def n_batches(self) -> int:
        return -(-len(self.maps) // self.batch_size)

    def padded(self, i: int, flip: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Features and targets of map i (mirrored in azimuth when ``flip``), zero-padded to the
        network's multiple."""
        f = self.maps.features[i].astype(np.float32)
        peaks = self.maps.peaks[i]
        if flip:
            f = f[:, :, ::-1]
            peaks = peaks.copy()
            peaks[:, 1] = (f.shape[2] - 1) - peaks[:, 1]
        fh, fw = self.full
        x = np.zeros((f.shape[0], fh, fw), np.float32)
        x[:, : f.shape[1], : f.shape[2]] = f
        return x, self.head.targets(peaks, (fh, fw))

    def epoch(self, seed: int, epoch: int):
        """Yield (features (B, 4, h, w), targets (B, C, h', w')) numpy batches of one epoch."""
        rng = np.random.default_rng([seed, epoch])
        order = rng.permutation(len(self.maps))
        ch, cw = self.crop
        fh, fw = self.full
        mh, mw = self.multiple
        for b in range(self.n_batches()):
            xs, ys = [], []
            for i in order[b * self.batch_size:(b + 1) * self.batch_size]:
                r0 = int(rng.integers(0, (fh - ch) // mh + 1)) * mh
                a0 = int(rng.integers(0, (fw - cw) // mw + 1)) * mw
                x, y = self.padded(int(i), self.flip and bool(rng.random() < 0.5))
                xs.append(x[:, r0:r0 + ch, a0:a0 + cw])
                sr, sa = fh // y.shape[-2], fw // y.shape[-1]  # 1 for dense targets, the stride for a grid
                ys.append(y[:, r0 // sr:(r0 + ch) // sr, a0 // sa:(a0 + cw) // sa])
            yield np.stack(xs), np.stack(ys)


def _initial_weights(cfg: TrainConfig, net, hp, base_dir) -> dict[str, Any]:
    """Load ``cfg.init`` into ``net`` (same architecture and hyper-parameters, else InputError);
    returns its provenance {path, weights_sha256, its own training record} for the metadata, with
    the parent's own ``init`` nested under ``init`` when it was fine-tuned too (the whole chain of
    stages, back to the run that started from random weights)."""
    from plugins.training.checkpoint import load_checkpoint

    from .nets import build_model

    path = Path(cfg.init)
    if not path.is_absolute():
        path = Path(base_dir) / path
    sd, meta, _ = load_checkpoint(path, cfg.model.name, map_location="cpu")
    # the parent as any detector loads it: fields added since it was made take their defaults
    parent_hp = build_model(meta, source=f"init {str(path)!r}").hp.model_dump(mode="json")
    here = hp.model_dump(mode="json")
    widen = parent_hp["in_channels"] < here["in_channels"]
    if {**parent_hp, "in_channels": 0} != {**here, "in_channels": 0} or parent_hp["in_channels"] > here["in_channels"]:
        raise InputError(f"init {str(path)!r}: its hyper-parameters {meta.get('hparams')} differ from model.params "
                         f"{here}; fine-tuning needs the same network (it may only gain input channels)")
    if widen:
        sd = widened_inputs(sd, net.state_dict(), parent_hp["in_channels"])
    net.load_state_dict(sd)
    parent = meta.get("training", {})
    record = {"path": str(cfg.init), "weights_sha256": meta.get("weights_sha256"),
              "command": parent.get("command"), "config_sha256": parent.get("config_sha256"),
              "epochs_run": parent.get("epochs_run"), "val": parent.get("metrics", {}).get("val")}
    grandparent = parent.get("dataset", {}).get("init")
    return {**record, "init": grandparent} if grandparent else record


def widened_inputs(parent: dict[str, Any], target: dict[str, Any], n_parent: int) -> dict[str, Any]:
    """``parent``'s weights for a network with more input channels (``target``'s shapes): a tensor
    that differs only in its input-channel axis (the first convolution, (out, in, kh, kw)) keeps the
    parent's weights for the first ``n_parent`` channels and gets zeros for the new ones, so the
    widened network starts as the parent (same outputs on any map) and learns the new inputs'
    weights from there. Any other difference raises InputError."""
    import torch

    out = {}
    for key, value in parent.items():
        want = target.get(key)
        if want is None or tuple(want.shape) == tuple(value.shape):
            out[key] = value
            continue
        if (value.ndim < 2 or value.shape[0] != want.shape[0] or value.shape[2:] != want.shape[2:]
                or value.shape[1] != n_parent):
            raise InputError(f"init: weights {key} {tuple(value.shape)} do not fit {tuple(want.shape)}")
        grown = torch.zeros(want.shape, dtype=value.dtype)
        grown[:, :n_parent] = value
        out[key] = grown
    return out


def _trained_on(train_set, val_set, data_rec: dict[str, Any]) -> dict[str, Any]:
    """The checkpoint's ``trained_on`` record (:mod:`plugins.training.trained_on`) from the first
    validation map; ConfigError when the training maps are on another grid or radar."""
    from plugins.training.trained_on import grid_mismatches, grid_record

    source = (f"dataset {data_rec.get('path')!r} (config_sha256 {data_rec.get('config_sha256')})"
              if data_rec.get("source") == "dataset" else "generated maps (data.generate)")
    rec = grid_record(val_set.maps[0], source)
    shapes = {tuple(train_set.features.shape[-2:])} | {m.shape for m in val_set.maps}
    if len(shapes) > 1 or any(grid_mismatches(rec, m) for m in val_set.maps):
        raise ConfigError(f"data: the training and validation maps are not all on one RA grid (map shapes "
                          f"{sorted(shapes)}); one model is trained on one radar's maps")
    return rec


def _validate(net, head, val, device, batch_size: int, cfg: TrainConfig):
    """Validation loss and the decoding sweep; returns (loss, outputs, sweep)."""
    import torch

    from .evaluate import sweep_decoding

    net.eval()
    outputs, losses = [], []
    batcher = Batcher(val, head, net.multiple, None, batch_size)
    with torch.inference_mode():
        for s in range(0, len(val), batch_size):
            pairs = [batcher.padded(i) for i in range(s, min(s + batch_size, len(val)))]
            x = torch.from_numpy(np.stack([p[0] for p in pairs])).to(device)
            y = torch.from_numpy(np.stack([p[1] for p in pairs])).to(device)
            out = net(x)
            losses.append(float(head.loss(out, y)) * len(pairs))
            outputs.extend(o for o in out.float().cpu().numpy())
    sweep = sweep_decoding(outputs, head, val.maps, val.truths, cfg.eval.thresholds,
                           [tuple(w) for w in cfg.eval.windows], cfg.data.match_radius)
    return sum(losses) / len(val), outputs, sweep


def train(cfg: TrainConfig, *, overwrite: bool = False, progress: bool = True, source: str = "<config>",
          base_dir: str | Path = ".", named_export: bool = False) -> dict[str, Any]:
    """Train ``cfg.model`` and write the files of the module doc to ``cfg.out``; returns a summary.
    named_export: the command line named ``cfg.export`` (:func:`plugins.training.run.export_target`)."""
    import torch
    from tqdm import tqdm

    from plugins.training.optim import make_optimizer, step
    from plugins.training.run import Validation, open_run, train_epochs

    from .data import dataset_record, load_split
    from .learned import resolve_device
    from .nets import architectures
    from .tasks import default_head

    run = open_run(cfg, overwrite=overwrite, minimise=False, base_dir=base_dir)
    if cfg.threads:
        torch.set_num_threads(cfg.threads)
    device = resolve_device(cfg.device)
    hp = cfg.hparams()
    arch = architectures()[cfg.model.name]
    head = default_head(cfg.model.name, hp, tuple(cfg.model.sigma))
    train_set = load_split(cfg.data, cfg.seed, "train", False, cfg.data.max_train_maps, progress, base_dir)
    val_set = load_split(cfg.data, cfg.seed, "val", True, cfg.data.max_val_maps, progress, base_dir)
    data_rec = dataset_record(cfg.data, base_dir)

    torch.manual_seed(cfg.seed)  # the documented global seed: nn.init of the new network
    net = arch.module(hp).to(device)
    if cfg.data.flip_azimuth:
        axis = val_set.maps[0].azimuth_axis  # the split shares the dataset's radar
        if not np.allclose(axis, -axis[::-1], atol=1e-9):
            raise ConfigError(f"data.flip_azimuth: the azimuth axis ({np.degrees(axis[0]):.2f}° … "
                              f"{np.degrees(axis[-1]):.2f}°, {len(axis)} bins) is not symmetric about boresight, "
                              "so a mirrored map is not a map of this radar; set flip_azimuth = false")
    batcher = Batcher(train_set, head, net.multiple, cfg.data.crop, cfg.optim.batch_size, cfg.data.flip_azimuth)
    steps = min(batcher.n_batches(), cfg.optim.steps_per_epoch or batcher.n_batches())
    opt, sched = make_optimizer(net, cfg.optim, steps * cfg.optim.epochs, cfg.optim.warmup_steps)
    init = _initial_weights(cfg, net, hp, base_dir) if cfg.init else None
    run.restore(net, opt, sched, cfg.model.name, map_location=device)  # also restores torch's RNG
    base_meta = {"architecture": cfg.model.name, "hparams": hp.model_dump(mode="json"), "head": head.describe(),
                 "features": features_record(cfg.channels()), "trained_on": _trained_on(train_set, val_set, data_rec)}

    def train_epoch(epoch: int) -> dict[str, Any]:
        """Eq. 8 (the head's loss) over ``steps`` seeded batches."""
        t0 = time.perf_counter()
        net.train()
        total, n = 0.0, 0
        bar = tqdm(batcher.epoch(cfg.seed, epoch), total=steps, desc=f"epoch {epoch}/{cfg.optim.epochs}",
                   unit="batch", disable=not progress, leave=False)
        for b, (x, y) in enumerate(bar):
            if b >= steps:
                break
            x, y = torch.from_numpy(x).to(device), torch.from_numpy(y).to(device)
            loss = head.loss(net(x), y)
            step(loss, net, opt, sched, cfg.optim.grad_clip)
            total, n = total + loss.detach().item(), n + 1
            bar.set_postfix(loss=f"{total / n:.4f}")
        bar.close()
        return {"train_loss": total / max(n, 1), "train_seconds": time.perf_counter() - t0,
                "lr": sched.get_last_lr()[0]}

    def validate(epoch: int) -> Validation | None:
        """Validation Macro-F1 at the best decoding, every ``eval.every`` epochs and after the last."""
        if not (epoch % cfg.eval.every == 0 or epoch == cfg.optim.epochs):
            return None
        t0 = time.perf_counter()
        val_loss, _, sweep = _validate(net, head, val_set, device, cfg.optim.batch_size, cfg)
        best = sweep["best"]
        dec = {"threshold": best["threshold"], "window": best["window"], "cells": best["cells"]}
        return Validation(best["macro_f1"], best, {"val_loss": val_loss, "val_seconds": time.perf_counter() - t0},
                          {"decode": dec})

    def line(rec: dict[str, Any]) -> str:
        msg = f"epoch {rec['epoch']}: train loss {rec['train_loss']:.4f}"
        if "val" in rec:
            msg += (f", val loss {rec['val_loss']:.4f}, Macro-F1 {rec['val']['macro_f1']:.3f} "
                    f"(LOS {rec['val']['los_f1']:.3f}, mNLOS {rec['val']['mnlos_f1']:.3f})")
        return msg

    train_epochs(run, net, opt, sched, base_meta, train_epoch, validate, line, progress)
    data_rec = {**data_rec, "n_train_maps": len(train_set), "n_val_maps": len(val_set)}
    if init is not None:
        data_rec = {**data_rec, "init": init}
    return _finish(cfg, run, base_meta, head, val_set, device, data_rec, source, named_export, base_dir)


def _finish(cfg, run, base_meta, head, val_set, device, data_rec, source, named_export, base_dir) -> dict[str, Any]:
    """Best weights → calibrated, documented final model (model.pt, export) and summary.json."""
    from plugins.training.checkpoint import load_checkpoint
    from plugins.training.run import finish

    from .evaluate import calibrate
    from .nets import build_model

    sd, meta, _ = load_checkpoint(run.out / "best.pt", cfg.model.name, map_location="cpu")
    net = build_model(meta, sd).to(device)
    val_loss, outputs, sweep = _validate(net, head, val_set, device, cfg.optim.batch_size, cfg)
    best = sweep["best"]
    win = tuple(best["window"])
    cal = calibrate(outputs, head, val_set.maps, val_set.truths, best["threshold"], win, cfg.data.match_radius,
                    best["cells"])
    decode = {"threshold": best["threshold"], "window": list(win), "cells": best["cells"], "calibration": cal}
    return finish(cfg, run, net, {**base_meta, "decode": decode}, dataset=data_rec, source=source,
                     metrics={"val": best, "val_loss": val_loss, "match_radius_m": cfg.data.match_radius},
                     named_export=named_export, training={"device": str(device)}, base_dir=base_dir,
                     summary={"val": best, "calibration": cal, "device": str(device)})


def report(s: dict[str, Any]) -> str:
    """The line ``xnlos train`` prints for a finished detector run."""
    v = s["val"]
    return (f"{s['epochs_run']} epoch(s) on {s['device']} ({s['seconds_per_epoch']:.1f} s/epoch), best epoch "
            f"{s['best_epoch']}: validation Macro-F1 {v['macro_f1']:.3f} (LOS {v['los_f1']:.3f}, mNLOS "
            f"{v['mnlos_f1']:.3f}) at threshold {v['threshold']}, window {v['window']}"
            f"{', one peak per resolution cell' if v.get('cells') else ''}")


TRAINER = Trainer(parse=parse_train_config, train=train, report=report, check=check_train_config)
