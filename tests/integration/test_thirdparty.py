"""A third-party distribution registers a detector through the entry point and runs in a pipeline.

The distribution (tests/thirdparty_plugin) is pip-installed into a temporary directory that only the
subprocesses here see (the ``thirdparty_env`` fixture): the environment running the tests is left
as it was."""
import json
import subprocess
import sys
from pathlib import Path


def test_thirdparty_detector_listed_and_runs(thirdparty_env, tmp_path):
    out = subprocess.run([sys.executable, "-m", "xnlos_core", "plugins", "--json"], capture_output=True,
                         text=True, check=True, env=thirdparty_env)
    rows = json.loads(out.stdout)
    row = next(r for r in rows if r["name"] == "peak_threshold")
    assert row["kind"] == "detector" and row["provider"] == "xnlos-thirdparty-demo 0.0.1"
    assert set(row["parameters"]) == {"margin_db", "split_range"}

    # One config line names the third-party detector; the pipeline runs in a fresh process.
    lines = ['name = "thirdparty"', "seed = 1", "[radar]", "n_samples = 256", "max_range = 60.0",
             "n_azimuth_bins = 121", "[scene]", 'builtin = "corner"', "[forward_model]", 'name = "image"',
             "[detector]", 'name = "peak_threshold"', "[wall_estimator]", 'name = "lsq"',
             "[reconstructor]", 'name = "mirror"', "[run]", "frames = 1", "figure = false"]
    cfg = tmp_path / "tp.toml"
    cfg.write_text("\n".join(lines) + "\n")
    run = subprocess.run([sys.executable, "-m", "xnlos_core", "run", str(cfg), "--out", str(tmp_path / "o"), "-q"],
                         capture_output=True, text=True, env=thirdparty_env)
    assert run.returncode == 0, run.stderr
    prov = json.loads((tmp_path / "o" / "provenance.json").read_text())
    assert prov["plugins"]["detector"] == {"name": "peak_threshold", "provider": "xnlos-thirdparty-demo 0.0.1",
                                           "params": {"margin_db": 20.0, "split_range": 35.0}}
    check = subprocess.run([sys.executable, "-c", "from xnlos_core.testing import check_component;"
                            "check_component('detector', 'peak_threshold')"], capture_output=True, text=True,
                           env=thirdparty_env)
    assert check.returncode == 0, check.stderr
    # The subprocesses loaded it from the temporary --target directory, not from site-packages.
    where = subprocess.run([sys.executable, "-c", "import xnlos_thirdparty_demo as m; print(m.__file__)"],
                           capture_output=True, text=True, check=True, env=thirdparty_env).stdout.strip()
    assert Path(where).is_relative_to(thirdparty_env["XNLOS_TEST_PLUGIN_TARGET"]), where
