"""Output directories that belong to one configuration: claimed, resumed, refused, overwritten.

``xnlos run``, ``xnlos eval`` and ``xnlos train`` each write into an ``--out`` directory and resume
a killed run from it. The rule they share: the directory holds a JSON *record* (``provenance.json``,
``run.json``) with the digest of the configuration that made it. A rerun with the same digest
resumes; another digest is refused with a ConfigError naming the directory and both hashes, unless
``--overwrite``, which discards the run's files and starts afresh. Stages that hold learned weights
are compared too (:func:`xnlos_core.provenance.require_same_state`), so results made with other
weights under the same config are not resumed either. Records are written atomically
(:func:`xnlos_core.io.atomic_write_text`).

:func:`package_dir_of` answers the other question an output path raises: does it lie inside the
installed xnlos package, whose shipped files (e.g. a model checkpoint) a command must replace
only when told to in so many words.
"""
from __future__ import annotations

import importlib.util
import json
from collections.abc import Iterable
from importlib.metadata import packages_distributions
from pathlib import Path
from typing import Any

from .errors import ConfigError
from .io import atomic_write_text, read_json_object
from .provenance import require_same_state


def claim(out: str | Path, record: str, digests: dict[str, str], *, overwrite: bool, what: str,
          clear: Iterable[str] = (), state: dict[str, str] | None = None,
          label: str | None = None) -> dict[str, Any] | None:
    """Make ``out`` the directory of one configuration; returns the previous ``record`` to resume
    from, or None for a fresh start (after deleting the files matching the ``clear`` globs).

    digests: record key → this run's digest; the first key the old record holds decides (so a
    record written before a digest was added is still recognised by an older one). what: the
    run's contents for messages, e.g. "results" or "an evaluation". state: stage → hash of its
    learned weights, compared with the record's ``state_sha256``. label: the record in messages
    (default: its file name's stem).

    Raises ConfigError when ``out`` holds another configuration's (or other weights') run and not
    ``overwrite``; InputError when the record is not a JSON object.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / record
    if path.exists() and not overwrite:
        old = read_json_object(path, label or Path(record).stem)
        key = next((k for k in digests if k in old), next(iter(digests)))
        if old.get(key) != digests[key]:
            raise ConfigError(f"{out}: holds {what} of another configuration (config hash "
                              f"{str(old.get(key, '?'))[:12]} ≠ {digests[key][:12]}); choose another --out "
                              "or pass --overwrite")
        if state is not None:
            require_same_state(out, old.get("state_sha256"), state, what)
        return old
    for pattern in clear:
        for f in out.glob(pattern):
            f.unlink()
    return None


def write_record(out: str | Path, record: str, data: dict[str, Any]) -> None:
    """Write ``out/record`` (JSON, keys sorted) atomically."""
    atomic_write_text(Path(out) / record, json.dumps(data, indent=2, sort_keys=True, default=str) + "\n")


def package_dirs(distribution: str = "xnlos") -> list[Path]:
    """The resolved folders of the top-level packages ``distribution`` installs (xnlos_core, sims,
    plugins, …; an editable install's are the checkout's folders)."""
    names = sorted(n for n, dists in packages_distributions().items() if distribution in dists)
    dirs = []
    for name in names:
        spec = importlib.util.find_spec(name)
        dirs += [Path(p).resolve() for p in (spec.submodule_search_locations or [])] if spec else []
    return dirs


def package_dir_of(path: str | Path) -> Path | None:
    """The installed package folder (:func:`package_dirs`) that ``path`` lies in, or None."""
    target = Path(path).resolve()
    return next((d for d in package_dirs() if target.is_relative_to(d)), None)
