"""What a run records about itself: config hash, seed, plugins, package versions, platform."""
from __future__ import annotations

import platform
import sys
import time
from importlib.metadata import PackageNotFoundError, version

from .errors import ConfigError

PACKAGES = ("xnlos", "numpy", "scipy", "pydantic", "pluggy", "matplotlib", "torch", "dask", "distributed")


def package_versions(names=PACKAGES) -> dict[str, str | None]:
    """Installed versions of the packages that shape results (None when absent)."""
    out = {}
    for n in names:
        try:
            out[n] = version(n)
        except PackageNotFoundError:
            out[n] = None
    return out


def state_change(old: dict[str, str] | None, new: dict[str, str]) -> str | None:
    """'detector 1a2b3c4d5e6f ≠ 0f9e8d7c6b5a, …' for each stage whose learned-state hash differs
    between a recorded run (``old``; None: recorded before hashes were kept) and now; None if equal."""
    old = old if isinstance(old, dict) else {}  # a damaged record compares as "unrecorded"
    diff = [f"{k} {str(old.get(k, 'unrecorded'))[:12]} ≠ {str(new.get(k, 'none'))[:12]}"
            for k in sorted(set(old) | set(new)) if old.get(k) != new.get(k)]
    return ", ".join(diff) or None


def require_same_state(out, old: dict[str, str] | None, new: dict[str, str], what: str) -> None:
    """ConfigError when ``out`` holds ``what`` (e.g. "results") made with other learned weights."""
    changed = state_change(old, new)
    if changed:
        raise ConfigError(f"{out}: holds {what} made with other learned weights ({changed}); choose another "
                          "--out or pass --overwrite")


def provenance(config, plugins: dict[str, dict], state: dict[str, str] | None = None,
               mismatch: dict[str, list[str]] | None = None) -> dict:
    """Provenance record of a pipeline run (config: PipelineConfig; plugins: kind → info; state:
    kind → hash of the stage's learned weights, :meth:`xnlos_core.pipeline.Pipeline.state_sha256`;
    mismatch: kind → what differs between a learned stage's training radar and the run's, accepted by
    its settings, :meth:`xnlos_core.pipeline.Pipeline.model_mismatches`, recorded as
    ``accepted_mismatch`` when there is any)."""
    extra = {"accepted_mismatch": {k: list(v) for k, v in mismatch.items()}} if mismatch else {}
    return {
        "config_sha256": config.digest(),
        "run_sha256": config.run_digest(),
        "state_sha256": dict(state or {}),
        "seed": config.seed,
        "plugins": plugins,
        "versions": package_versions(),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        **extra,
    }
