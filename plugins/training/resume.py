"""Resume state of a training run: ``last.pt`` holds everything a resumed run needs, sealed by one
hash, and the run's other files are rebuilt from it. Used by the epoch loop (:mod:`.run`) that
trains every learned component (detectors, residual mirror).

``last.pt`` is a sealed checkpoint (:mod:`.checkpoint`: a sha256 of the whole file in its header)
of the weights plus: optimizer and scheduler state dicts, the run's progress (epoch, early-stopping
counters), torch's RNG states, the whole metrics history (JSON text) and a copy of the best
weights so far with their metadata. A flipped bit anywhere in it is refused on resume with an
InputError naming the file. The run then stops rather than falling back: only one resume point is
kept, and silently restarting from scratch would discard the run and hide a disk fault; the
message says how to restart (delete ``last.pt`` or pass ``--overwrite``).

Crash safety, per epoch: (1) train and validate; (2) a new best is written to ``best.pt``;
(3) ``last.pt`` is replaced atomically (it now holds the epoch's metrics line and the best copy);
(4) the line is appended to ``metrics.jsonl``. ``last.pt`` is the single commit point: on resume,
``metrics.jsonl`` is rewritten from its history (a crash after (3) loses no line, a crash in (4)
leaves no torn one) and ``best.pt`` from its best copy (a crash between (2) and (3) leaves no
``best.pt`` of an epoch the run has not committed); a crash before (3) repeats the epoch.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from xnlos_core.errors import InputError
from xnlos_core.io import append_jsonl, atomic_write_text, json_default

from .checkpoint import load_checkpoint, save_checkpoint

LAST, BEST, METRICS = "last.pt", "best.pt", "metrics.jsonl"


def rng_state() -> dict[str, Any]:
    """torch's global RNG states (CPU, and every CUDA device once CUDA is in use): weights-only safe
    uint8 tensors."""
    import torch

    cuda = torch.cuda.get_rng_state_all() if torch.cuda.is_available() and torch.cuda.is_initialized() else []
    return {"torch": torch.get_rng_state(), "cuda": list(cuda)}


def _set_rng_state(state: dict[str, Any]) -> None:
    import torch

    torch.set_rng_state(state["torch"].cpu())
    if state.get("cuda") and torch.cuda.is_available():
        torch.cuda.set_rng_state_all([s.cpu() for s in state["cuda"]])


@dataclass
class ResumeState:
    """What ``last.pt`` holds (module doc). state_dict: the weights after ``progress``'s epoch;
    history: the metrics records of every finished epoch; best: (state_dict, metadata) of the
    best weights so far, or None before the first validation."""

    state_dict: dict
    metadata: dict
    optimizer: dict
    scheduler: dict
    progress: dict
    history: list[dict]
    best: tuple[dict, dict] | None


def save_epoch(out: Path, net, metadata: dict, optimizer: dict, scheduler: dict, progress: dict,
               history: list[dict], best: tuple[dict, dict] | None) -> None:
    """Commit a finished epoch: write ``last.pt`` (module doc), then append ``history[-1]`` to
    ``metrics.jsonl``. optimizer / scheduler: their state dicts; progress: plain JSON-able values."""
    extra: dict[str, Any] = {"optimizer": optimizer, "scheduler": scheduler, "progress": progress,
                             "rng": rng_state(), "history_json": json.dumps(history, default=json_default)}
    if best is not None:
        sd, meta = best
        extra["best"] = {"state_dict": sd, "metadata_json": json.dumps(meta, default=str)}
    save_checkpoint(out / LAST, net, metadata, extra=extra, sidecar=False, sealed=True)
    append_jsonl(out / METRICS, history[-1])


def best_copy(net, metadata: dict) -> tuple[dict, dict]:
    """(CPU copy of ``net``'s state_dict, ``metadata``): the best weights as ``save_epoch`` keeps them."""
    return {k: v.detach().cpu().clone() for k, v in net.state_dict().items()}, dict(metadata)


def start_fresh(out: Path) -> None:
    """A run without ``last.pt`` has no committed epoch: empty ``metrics.jsonl`` (lines left by a
    run whose ``last.pt`` was deleted would otherwise be followed by the same epochs again)."""
    atomic_write_text(out / METRICS, "")


def load_resume(out: Path, architecture: str | None = None, map_location="cpu") -> ResumeState:
    """Read and verify ``out/last.pt``, restore torch's RNG states and rewrite ``metrics.jsonl``
    and ``best.pt`` from it (module doc). InputError naming the file when it is corrupted, was
    written without a whole-file hash, or lacks an entry."""
    path = out / LAST
    sd, meta, payload = load_checkpoint(path, architecture, map_location=map_location, sealed=True)
    try:
        history = json.loads(payload["history_json"])
        best = None
        if "best" in payload:
            best = (payload["best"]["state_dict"], json.loads(payload["best"]["metadata_json"]))
        state = ResumeState(sd, meta, payload["optimizer"], payload["scheduler"], dict(payload["progress"]),
                            history, best)
        rng = payload["rng"]
    except (KeyError, TypeError, json.JSONDecodeError) as exc:
        raise InputError(f"checkpoint {str(path)!r}: not a resume checkpoint of xnlos train (entry {exc} is "
                         "missing or unreadable); delete it to start the run afresh, or pass --overwrite") from None
    if not isinstance(history, list) or not all(isinstance(r, dict) for r in history):
        raise InputError(f"checkpoint {str(path)!r}: its metrics history is not a list of records")
    _set_rng_state(rng)
    atomic_write_text(out / METRICS, "".join(json.dumps(r, sort_keys=True, default=json_default) + "\n"
                                             for r in history))
    if best is not None:
        save_checkpoint(out / BEST, best[0], best[1])
    return state
