"""The stamp of a run directory's derived outputs (``outputs.json``): a rerun of a finished run leaves
its summary, figures and GIF alone when they are those of this config and these results.

``xnlos run`` derives summary.md, summary.json, the ``frame_NNNN.png`` figures and ``sequence.gif``
from the config and results.jsonl. After writing them it records

- ``key``: sha256 of the canonical JSON of the whole config (``run.figures`` and ``run.animation``
  included, unlike :meth:`xnlos_core.config.PipelineConfig.digest`: they choose the pictures), the
  provenance (less its ``resumed`` counter), the xnlos version, the sha256 of results.jsonl's bytes,
  and the summary texts;
- ``files``: output name (relative to the run directory) → sha256 of its bytes.

A rerun whose key is the recorded one, with every recorded file on disk holding the recorded bytes,
writes none of them (a finished run re-run ≤ 1 s). Anything else (a new frame, a
changed figure or animation setting, a deleted or edited output, another xnlos version) rewrites them
as before. The check reads each output once (a few MiB: milliseconds); no timestamp is trusted.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any, Iterable

from xnlos_core import __version__
from xnlos_core.io import atomic_write_text

STAMP = "outputs.json"


def _sha256_file(path: Path) -> str | None:
    """sha256 (hex) of ``path``'s bytes, or None when it cannot be read."""
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def outputs_key(config, prov: dict[str, Any], results: Path, texts: Iterable[str]) -> str:
    """sha256 (hex) naming what the outputs are derived from: ``config`` (a PipelineConfig, every
    key but ``base_dir`` and ``run.blas_threads``), ``prov`` (the provenance record; ``resumed`` left
    out, it counts reruns), the results file ``results`` (its bytes) and the rendered ``texts``."""
    dump = config.model_dump(exclude={"base_dir": True, "run": {"blas_threads"}})
    blob = json.dumps({"config": dump, "provenance": {k: v for k, v in prov.items() if k != "resumed"},
                       "xnlos": __version__, "results_sha256": _sha256_file(results), "texts": list(texts)},
                      sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()


def outputs_current(out: str | Path, key: str, names: Iterable[str]) -> bool:
    """True when ``out/outputs.json`` records ``key`` and exactly the outputs ``names``, each on disk
    with its recorded sha256; False otherwise (no stamp, an unreadable one, any difference)."""
    out = Path(out)
    try:
        stamp = json.loads((out / STAMP).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    if not isinstance(stamp, dict) or stamp.get("key") != key:
        return False
    files = stamp.get("files")
    if not isinstance(files, dict) or set(files) != set(names):
        return False
    return all(_sha256_file(out / name) == digest for name, digest in files.items())


def write_outputs_stamp(out: str | Path, key: str, names: Iterable[str]) -> None:
    """Record ``key`` and the sha256 of each output ``names`` (relative to ``out``) in ``out/outputs.json``."""
    out = Path(out)
    files = {name: _sha256_file(out / name) for name in names}
    atomic_write_text(out / STAMP, json.dumps({"key": key, "files": files}, indent=2, sort_keys=True) + "\n")
