"""The command line: errors without tracebacks, plugins listing, sweeps locally and on Dask."""
import json
import subprocess
import sys

import pytest

from xnlos_core.app.cli import main
from xnlos_core.io import read_jsonl


def test_version_and_module_entry():
    out = subprocess.run([sys.executable, "-m", "xnlos_core", "--version"], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.startswith("xnlos ")


def test_plugins_json_lists_kind_name_provider_params(capsys):
    assert main(["plugins", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    cfar = next(r for r in rows if r["kind"] == "detector" and r["name"] == "cfar")
    assert cfar["provider"].startswith("xnlos ")
    assert "pfa" in cfar["parameters"] and cfar["parameters"]["pfa"]["lt"] == 1
    assert main(["plugins"]) == 0
    assert "nlos_cfar" in capsys.readouterr().out


def test_plugins_kind_filters_the_listing(capsys):
    assert main(["plugins", "--kind", "tracker", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert rows and {r["kind"] for r in rows} == {"tracker"}
    assert main(["plugins", "--kind", "tracker", "--kind", "wall_estimator"]) == 0
    heads = [line.split()[0] for line in capsys.readouterr().out.splitlines() if not line.startswith(" ")]
    assert set(heads) == {"tracker", "wall_estimator"} and heads.index("wall_estimator") < heads.index("tracker")
    with pytest.raises(SystemExit) as exc:
        main(["plugins", "--kind", "trackers"])
    assert exc.value.code == 2 and "invalid choice: 'trackers'" in capsys.readouterr().err


def test_every_forward_model_parameter_is_described_and_printed(capsys):
    from xnlos_core.registry import get_registry

    models = [c for c in get_registry().components() if c.kind == "forward_model" and c.provider.startswith("xnlos ")]
    assert {"image", "raytrace"} <= {c.name for c in models}
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out.splitlines()
    for c in models:
        for pname, info in c.parameters().items():
            assert info.get("description"), f"forward model {c.name!r}: parameter {pname!r} has no description"
            assert any(f"- {pname} = " in line and line.endswith(info["description"]) for line in out), pname


def test_bad_config_is_a_clear_error_not_a_traceback(tmp_path, sweep_toml):
    p = tmp_path / "bad.toml"
    p.write_text(sweep_toml.replace('name = "lsq"', 'name = "lsq"\nparams = { cluster_distance = -1 }'))
    out = subprocess.run([sys.executable, "-m", "xnlos_core", "run", str(p), "--out", str(tmp_path / "o")],
                         capture_output=True, text=True)
    assert out.returncode == 2
    assert "Traceback" not in out.stderr
    assert "bad.toml" in out.stderr and "wall_estimator.params.cluster_distance" in out.stderr


def test_run_cli_writes_outputs(tmp_path, capsys, sweep_toml):
    p = tmp_path / "p.toml"
    p.write_text(sweep_toml.split("[sweep]")[0].replace("figure = false", "figure = true"))
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 0
    assert (tmp_path / "o" / "summary.md").exists() and list((tmp_path / "o").glob("*.png"))
    assert "hidden car" in capsys.readouterr().out


def test_sweep_local(tmp_path, sweep_toml):
    p = tmp_path / "s.toml"
    p.write_text(sweep_toml)
    assert main(["sweep", str(p), "--out", str(tmp_path / "o"), "--workers", "1", "-q"]) == 0
    recs = read_jsonl(tmp_path / "o" / "sweep.jsonl")
    assert sorted(r["assignment"]["detector.name"] for r in recs) == ["cfar", "nlos_cfar"]
    table = (tmp_path / "o" / "sweep.md").read_text()
    assert "| 0 | cfar |" in table and "| 1 | nlos_cfar |" in table
    # A rerun finds every point done and runs nothing new.
    assert main(["sweep", str(p), "--out", str(tmp_path / "o"), "--workers", "1", "-q"]) == 0
    assert len(read_jsonl(tmp_path / "o" / "sweep.jsonl")) == 2


def test_sweep_on_dask_local_cluster(tmp_path, sweep_toml):
    distributed = pytest.importorskip("distributed")
    p = tmp_path / "s.toml"
    p.write_text(sweep_toml)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tcp",
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        assert main(["sweep", str(p), "--out", str(tmp_path / "o"), "--scheduler", cluster.scheduler_address,
                     "-q"]) == 0
    assert len(read_jsonl(tmp_path / "o" / "sweep.jsonl")) == 2


def test_unreachable_scheduler_is_a_clear_error(tmp_path, capsys, sweep_toml, monkeypatch):
    distributed = pytest.importorskip("distributed")
    real = distributed.Client
    # The error path, not the sweep's 10 s connect timeout, is the point: give up after 1 s here.
    monkeypatch.setattr(distributed, "Client", lambda address, **kw: real(address, **{**kw, "timeout": "1s"}))
    p = tmp_path / "s.toml"
    p.write_text(sweep_toml)
    assert main(["sweep", str(p), "--out", str(tmp_path / "o"), "--scheduler", "tcp://127.0.0.1:9", "-q"]) == 2
    assert "cannot connect to a Dask scheduler" in capsys.readouterr().err


def test_check_refuses_a_wall_of_unknown_material(tmp_path, capsys, sweep_toml):
    # the core no longer knows the materials: the forward model's check must still refuse the name
    p = tmp_path / "bad_material.toml"
    p.write_text(sweep_toml.split("[sweep]")[0].replace('builtin = "corner"',
                 '[[scene.walls]]\nname = "facade"\nstart = [20.0, 5.0]\nend = [20.0, -5.0]\nmaterial = "concret"'))
    assert main(["check", str(p)]) == 2
    assert "walls[0] ('facade'): unknown material 'concret' — did you mean 'concrete'?" in capsys.readouterr().err
