"""What a run records about itself: config hash, seed, plugins, package versions, platform."""
from __future__ import annotations

import platform
import sys
import time
from importlib.metadata import PackageNotFoundError, version

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


def provenance(config, plugins: dict[str, dict]) -> dict:
    """Provenance record of a pipeline run (config: PipelineConfig; plugins: kind → info)."""
    return {
        "config_sha256": config.digest(),
        "seed": config.seed,
        "plugins": plugins,
        "versions": package_versions(),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
