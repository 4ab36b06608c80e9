"""`make demo` and `make test` install exactly the locked versions (requirements.lock): every locked
package whose environment marker holds here is installed at its locked version."""
from __future__ import annotations

import os
import re
from importlib import metadata
from pathlib import Path

import pytest
from packaging.markers import Marker

LOCK = Path(__file__).resolve().parents[2] / "requirements.lock"
PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s;]+)\s*(?:;\s*(.+))?$")


def locked() -> dict[str, str]:
    """{normalised name: version} of the lock's pins whose marker holds in this interpreter."""
    out = {}
    for line in LOCK.read_text().splitlines():
        m = PIN.match(line.strip())
        if m and (m.group(3) is None or Marker(m.group(3)).evaluate()):
            out[re.sub(r"[-_.]+", "-", m.group(1)).lower()] = m.group(2)
    return out


def test_the_lock_pins_cpu_torch_and_the_declared_dependencies():
    pins = locked()
    assert pins["torch"] == "2.13.0+cpu"
    assert not [n for n in pins if n.startswith("nvidia-")], "the lock pulls CUDA packages"
    for name in ("numpy", "scipy", "pysindy", "scikit-learn", "numba", "pandas", "h5py", "pytest"):
        assert name in pins, f"{name} is not locked"


@pytest.mark.skipif(os.environ.get("XNLOS_UNLOCKED") == "1", reason="`make test-latest` runs unlocked on purpose")
def test_installed_versions_are_the_locked_ones():
    wrong = {}
    for name, version in locked().items():
        try:
            have = metadata.version(name)
        except metadata.PackageNotFoundError:
            have = None
        if have != version:
            wrong[name] = (have, version)
    assert not wrong, f"installed ≠ locked (installed, locked): {wrong}; run `make test` in a fresh clone"
