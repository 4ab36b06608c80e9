"""Cheap start-up (issue 31, item 4): building the ``xnlos`` parser with every installed plugin
registered, and ``xnlos check`` of the shipped pipelines, import no heavy optional package; those are
imported by the functions that use them. Checked in a fresh interpreter through ``sys.modules`` (which
packages got imported), not with a timer."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("pysindy", "sklearn", "pandas", "trimesh", "torch", "casadi", "emcee", "matplotlib", "motmetrics", "dask",
         "numba")

SCRIPT = """
import json, sys
import xnlos_core.cli as cli
from xnlos_core.registry import get_manager, get_registry
cli.build_parser(get_manager())
assert get_registry().names("tracker"), "no tracker registered: the plugins did not load"
for path in sys.argv[1:]:
    assert cli.main(["check", "-q", path]) == 0, path
print(json.dumps(sorted(m for m in {heavy!r} if m in sys.modules)))
"""


def _imported(*argv: str) -> list[str]:
    # cwd = the checkout's root, so its packages (not another install's) are the ones imported
    done = subprocess.run([sys.executable, "-c", SCRIPT.format(heavy=HEAVY), *argv], cwd=ROOT,
                          capture_output=True, text=True, timeout=120, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_registration_and_the_parser_import_no_heavy_package():
    assert _imported() == []


def test_checking_the_shipped_pipelines_imports_no_heavy_package():
    configs = sorted(str(p) for p in (ROOT / "configs" / "pipelines").glob("*.toml"))
    assert configs and _imported(*configs) == []


def test_the_closed_form_chi2_gate_is_scipys_quantile():
    from scipy.stats import chi2

    from estimators.trackers.kalman import chi2_2_ppf

    for p in (1e-6, 0.5, 0.9, 0.99, 0.999, 1 - 1e-9):
        assert abs(chi2_2_ppf(p) - chi2.ppf(p, df=2)) <= 1e-12 * max(1.0, chi2.ppf(p, df=2))


def test_the_windows_radar_accepts_without_scipy_are_scipy_windows():
    from scipy.signal import get_window

    from xnlos_core.radar import SCIPY_WINDOWS

    for name in sorted(SCIPY_WINDOWS):
        assert get_window(name, 8).shape == (8,), name
