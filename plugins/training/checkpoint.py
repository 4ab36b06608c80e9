"""Checkpoints of every learned component (detectors, residual mirror): a ``state_dict`` plus a
JSON metadata record, in one torch file.

File content (``torch.save`` of a plain dict, read back with ``torch.load(weights_only=True)``,
so no pickled code is ever executed)::

    {"format": "xnlos-detector", "version": 1, "metadata_json": "<JSON text>", "state_dict": {...}}

The metadata names the architecture and its hyper-parameters, the output head, the input
features, decoding defaults (threshold, window, calibrated standard deviations), how the model was
trained (config, dataset manifest hash, metrics) and ``weights_sha256``, a hash over every
tensor, checked on load so a corrupted file is refused rather than silently used. A copy of the
metadata is written beside the checkpoint as ``NAME.json`` for people (the embedded one is
authoritative). Writes are atomic (temporary file, fsync, rename).

Sealed checkpoints (``sealed=True``; a training run's ``last.pt``, whose optimizer, scheduler, RNG
and history entries ``weights_sha256`` does not cover) carry a hash of the whole torch file in a
two-line text header::

    xnlos-sealed-checkpoint 1
    sha256 <64 hex digits of the sha256 of the torch file that follows>
    <torch file>

so that a flipped bit anywhere — header, tensors, pickled structure, zip padding — is refused on
load. A plain checkpoint is a zip and starts with ``PK\x03\x04``; anything else is read as a
sealed one and must have an intact header.
"""
from __future__ import annotations

import hashlib
import io
import json
import pickle
import re
import zipfile
from pathlib import Path
from typing import Any

import torch
from torch import nn

from xnlos_core.datafiles import read_regular_bytes
from xnlos_core.errors import InputError
from xnlos_core.io import atomic_write_bytes, atomic_write_text

FORMAT, VERSION = "xnlos-detector", 1  # the name predates the residual mirror; shipped files carry it
SEAL = b"xnlos-sealed-checkpoint 1\nsha256 "
_SEAL_LEN = len(SEAL) + 64 + 1  # the header: SEAL, the hex digest, a newline
_ZIP_MAGIC = b"PK\x03\x04"
MAX_CHECKPOINT_BYTES = 4 * 2**30  # the shipped checkpoints are < 100 MB


def weights_digest(state_dict: dict[str, torch.Tensor]) -> str:
    """sha256 over (name, dtype, shape, bytes) of every tensor, in key order."""
    h = hashlib.sha256()
    for name in sorted(state_dict):
        t = state_dict[name].detach().cpu().contiguous()
        h.update(f"{name}|{t.dtype}|{tuple(t.shape)}|".encode())
        h.update(t.reshape(-1).view(torch.uint8).numpy().tobytes() if t.numel() else b"")
    return h.hexdigest()


def save_checkpoint(path: str | Path, model: nn.Module | dict, metadata: dict[str, Any], extra: dict | None = None,
                    sidecar: bool = True, sealed: bool = False) -> None:
    """Write ``model``'s state_dict (or a state_dict) with ``metadata`` to ``path`` atomically.

    extra: further weights-only-safe entries (e.g. optimizer state for resuming); sealed: prefix
    the whole-file hash header (module doc), so that ``extra`` is covered too.
    """
    sd = model.state_dict() if isinstance(model, nn.Module) else model
    sd = {k: v.detach().cpu() for k, v in sd.items()}
    meta = dict(metadata, format=FORMAT, version=VERSION, weights_sha256=weights_digest(sd))
    text = json.dumps(meta, indent=2, sort_keys=True, default=str)
    buf = io.BytesIO()
    torch.save({"format": FORMAT, "version": VERSION, "metadata_json": text, "state_dict": sd, **(extra or {})}, buf)
    data = buf.getvalue()
    if sealed:
        data = SEAL + hashlib.sha256(data).hexdigest().encode() + b"\n" + data
    atomic_write_bytes(path, data)
    if sidecar:
        atomic_write_text(Path(path).with_suffix(".json"), text + "\n")


def _unseal(path: Path, data: bytes, sealed: bool) -> bytes:
    """The torch file inside ``data`` (module doc); InputError naming ``path`` when the header is
    damaged, the hash does not match, or ``sealed`` is asked for and the file is a plain one."""
    if data.startswith(_ZIP_MAGIC):
        if sealed:
            raise InputError(f"checkpoint {str(path)!r}: has no whole-file hash (written by an xnlos before "
                             "sealed resume checkpoints, or not by xnlos train); delete it to start the run "
                             "afresh, or pass --overwrite")
        return data
    head = data[:_SEAL_LEN]
    digest = head[len(SEAL):-1]
    if not (head.startswith(SEAL) and head.endswith(b"\n") and re.fullmatch(rb"[0-9a-f]{64}", digest)):
        raise InputError(f"checkpoint {str(path)!r}: not a readable torch checkpoint (corrupted or not a "
                         f"checkpoint): neither a zip nor a sealed checkpoint's header {SEAL[:23].decode()!r}")
    body = data[_SEAL_LEN:]
    got = hashlib.sha256(body).hexdigest()
    if got != digest.decode():
        raise InputError(f"checkpoint {str(path)!r}: corrupted — file hash {got[:12]}… does not match the "
                         f"recorded {digest.decode()[:12]}…")
    return body


def load_checkpoint(path: str | Path, architecture: str | None = None,
                    map_location: str | torch.device = "cpu",
                    sealed: bool = False) -> tuple[dict[str, torch.Tensor], dict[str, Any], dict]:
    """(state_dict, metadata, payload) of the checkpoint at ``path`` (plain or sealed; ``sealed``:
    only a sealed one, whose whole-file hash is then checked).

    Only a regular file of at most :data:`MAX_CHECKPOINT_BYTES` is read (a FIFO, a device such as
    ``/dev/zero`` or a directory is refused before a byte is read, :mod:`xnlos_core.datafiles`).
    Raises InputError (naming the file) when it is missing, not a readable torch file, not an
    xnlos detector checkpoint, corrupted (file or weights hash mismatch), or made for another
    ``architecture`` than the one asked for.
    """
    path = Path(path)
    raw = read_regular_bytes(path, what=f"checkpoint {str(path)!r}", max_bytes=MAX_CHECKPOINT_BYTES)
    data = _unseal(path, raw, sealed)
    try:
        payload = torch.load(io.BytesIO(data), map_location=map_location, weights_only=True)
    except (RuntimeError, pickle.UnpicklingError, EOFError, OSError, ValueError, zipfile.BadZipFile,
            AttributeError, TypeError, KeyError, IndexError) as exc:
        raise InputError(f"checkpoint {str(path)!r}: not a readable torch checkpoint (corrupted or not a "
                         f"checkpoint): {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}") from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise InputError(f"checkpoint {str(path)!r}: not an xnlos detector checkpoint (expected format {FORMAT!r}, "
                         "written by xnlos train)")
    if payload.get("version") != VERSION:
        raise InputError(f"checkpoint {str(path)!r}: format version {payload.get('version')!r}, this xnlos reads "
                         f"version {VERSION}")
    try:
        meta = json.loads(payload["metadata_json"])
        sd = payload["state_dict"]
    except (KeyError, TypeError, json.JSONDecodeError) as exc:
        raise InputError(f"checkpoint {str(path)!r}: metadata record is unreadable ({exc})") from None
    got = weights_digest(sd)
    if got != meta.get("weights_sha256"):
        raise InputError(f"checkpoint {str(path)!r}: corrupted — weights hash {got[:12]}… does not match the "
                         f"recorded {str(meta.get('weights_sha256'))[:12]}…")
    if architecture is not None and meta.get("architecture") != architecture:
        raise InputError(f"checkpoint {str(path)!r}: holds a {meta.get('architecture')!r} model, but detector "
                         f"{architecture!r} needs a {architecture!r} checkpoint (train one with xnlos train, "
                         f"model.name = {architecture!r})")
    return sd, meta, payload
