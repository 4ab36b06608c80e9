"""Cheap start-up: building the ``xnlos`` parser with every installed plugin
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
import xnlos_core.app.cli as cli
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


def _learned(config: Path) -> bool:
    """Whether the pipeline has a stage that reads learned weights (a learned detector, residual_mirror)."""
    import tomllib

    from plugins.detectors.learned import LEARNED

    t = tomllib.loads(config.read_text(encoding="utf-8"))
    return (t.get("detector", {}).get("name") in LEARNED
            or t.get("reconstructor", {}).get("name") == "residual_mirror")


def test_checking_the_shipped_pipelines_imports_no_heavy_package():
    configs = sorted((ROOT / "configs" / "pipelines").glob("*.toml"))
    plain = [str(p) for p in configs if not _learned(p)]
    assert plain and _imported(*plain) == []


def test_checking_a_learned_pipeline_imports_torch_alone():
    # `check` loads the checkpoint a run loads (torch.load(weights_only=True)), so that a missing or
    # damaged one is refused before a run; torch is the one heavy package that takes
    learned = [str(p) for p in sorted((ROOT / "configs" / "pipelines").glob("*.toml")) if _learned(p)]
    assert learned and _imported(*learned) == ["torch"]


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
