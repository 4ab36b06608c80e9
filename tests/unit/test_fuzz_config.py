"""Seeded fuzzing of the config loaders and ``xnlos check``.

Each case mutates one shipped config (pipelines, datasets, training, and the corner scene inline
in a pipeline): values replaced by other types, huge / NaN / ±inf / negative numbers, long
strings, path traversal, deleted and unknown keys, deep nesting, invalid UTF-8, truncation. The
config is written into a copy of ``configs/`` (the working directory during the test, as when
``xnlos`` runs from the project) and checked in-process with :func:`xnlos_core.app.cli.check_file`.
Every case must either pass or raise an :class:`~xnlos_core.errors.XnlosError`, within a
generous per-case bound (SIGALRM), and no config holding a NaN may pass. The case count comes
from the ``fuzz_cases`` fixture (50 in ``make test``, 10,000 in ``make fuzz``).
"""
from __future__ import annotations

import copy
import json
import math
import random
import shutil
import signal
import tomllib
from collections import Counter
from pathlib import Path

import pytest

from xnlos_core.app.cli import check_file
from xnlos_core.config import expand_sweep
from xnlos_core.errors import XnlosError

ROOT = Path(__file__).resolve().parents[2]
CASE_LIMIT_S = 120  # a hang, not a slow case: checking a shipped config takes < 0.1 s
BASES = ("pipelines/corner.toml", "pipelines/corner_emcee.toml", "pipelines/replay.toml", "ablations/cfar.toml",
         "ablations/walls.toml", "datasets/smoke.toml", "datasets/default.toml", "training/tiny.toml",
         "training/swin_unet.toml", "training/unet.toml", "training/rtn.toml", "training/residual_mirror.toml",
         "pipelines/inline_scene.toml")
WEIRD = [3.5, -1, 0, 1, 2**31, 2**63 - 1, -2**63, 1e308, -1e308, 5e-324, math.nan, math.inf, -math.inf, "", "x",
         "x" * 300, "../../x", "../" * 12 + "etc/passwd", "/etc/passwd", "/dev/zero", "fifo.npy", ".", "..",
         "\u00e9\u4e2d", True, False, [], {}, [0, 4], [math.nan, 1.0], [1e308, -1e308], {"a": 1}, [[1, 2], [3]],
         "corner", "image", "mirror"]
PATH_KEYS = [("radar", "preset"), ("radar", "coupling_file"), ("scene", "file"), ("scene", "builtin"),
             ("data", "dataset"), ("init",), ("export",)]
PATH_VALUES = ["../../x", "../" * 12 + "etc/passwd", "/etc/passwd", "/dev/null", "fifo.npy", "fifo.toml",
               "a_dir.toml", "outside.toml", "x" * 300 + ".toml", ("y" * 200 + "/") * 30 + "z.toml", 3.5, [],
               "../scenes/corner.toml", "../radar/xband_default.toml", "esc.npy", "../../../../x.obj"]


def _key(k: str) -> str:
    return json.dumps(k)


def _value(v) -> str:
    """TOML text of ``v``: inline tables and arrays (valid TOML 1.0 at any depth)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if v != v else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def to_toml(table: dict) -> str:
    return "".join(f"{_key(k)} = {_value(v)}\n" for k, v in table.items())


def _nodes(t, path=()):
    """Every (path, value) below t (dict keys, list indices)."""
    items = t.items() if isinstance(t, dict) else enumerate(t) if isinstance(t, list) else ()
    for k, v in items:
        yield path + (k,), v
        yield from _nodes(v, path + (k,))


def _set(t, path, value, delete=False):
    for k in path[:-1]:
        t = t[k]
    if delete:
        del t[path[-1]]
    else:
        t[path[-1]] = value


def _has_nan(t) -> bool:
    return any(isinstance(v, float) and v != v for _, v in _nodes({"": t}))


def _pick(rng: random.Random, pool: list):
    return copy.deepcopy(rng.choice(pool))  # a fresh value: the pools must not be mutated or shared


def mutate(table: dict, rng: random.Random) -> tuple[dict | None, bytes | None, str]:
    """One mutation of ``table``: (new table, None, kind) or (None, raw file bytes, kind)."""
    op = rng.choice(["replace", "replace", "replace", "delete", "add", "number", "path", "path", "nest", "bytes",
                     "truncate", "multi"])
    nodes = list(_nodes(table))
    if op == "multi":
        for _ in range(rng.randint(2, 5)):
            nodes = list(_nodes(table))
            p, _ = rng.choice(nodes)
            _set(table, p, _pick(rng, WEIRD))
        return table, None, op
    if op == "replace":
        p, _ = rng.choice(nodes)
        _set(table, p, _pick(rng, WEIRD))
    elif op == "delete":
        p, _ = rng.choice(nodes)
        _set(table, p, None, delete=True)
    elif op == "add":
        dicts = [{"": table}[""]] + [v for _, v in nodes if isinstance(v, dict)]
        rng.choice(dicts)[rng.choice(["extra", "preset", "file", "builtin", "coupling_file", "base_dir"])] = \
            _pick(rng, WEIRD + PATH_VALUES)
    elif op == "number":
        nums = [(p, v) for p, v in nodes if isinstance(v, (int, float)) and not isinstance(v, bool)]
        if nums:
            p, v = rng.choice(nums)
            _set(table, p, rng.choice([v * 1e300, -v, v * 2**31, 2**31, 1e308, math.nan, math.inf, -math.inf, 0,
                                       -1, 2**62, float(v) + 0.5]))
    elif op == "path":
        keys = rng.choice(PATH_KEYS)
        node = table
        for k in keys[:-1]:
            if not isinstance(node.get(k), dict):
                node[k] = {}
            node = node[k]
        node[keys[-1]] = _pick(rng, PATH_VALUES)
        if keys[:1] == ("scene",):
            for other in ("file", "builtin"):
                if other != keys[-1]:
                    node.pop(other, None)
    elif op == "nest":
        depth = rng.choice([40, 200, 1_000, 10_000, 100_000])
        val = rng.choice(["[" * depth + "1" + "]" * depth, "{a = " * depth + "1" + "}" * depth])
        text = to_toml(table) + f"deep = {val}\n"
        return None, text.encode(), op
    elif op == "bytes":
        data = bytearray(to_toml(table).encode())
        for _ in range(rng.randint(1, 4)):
            i = rng.randrange(len(data) + 1)
            data[i:i] = rng.choice([b"\xff", b"\xc3", b"\xed\xa0\x80", b"\x00", bytes([rng.randrange(256)])])
        return None, bytes(data), op
    elif op == "truncate":
        data = to_toml(table).encode()
        return None, data[:rng.randrange(len(data))], op
    return table, None, op


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    """A copy of configs/ with the files the mutations point at: a FIFO, a directory named like a
    config, a file outside the copy, an inline-scene pipeline, and symlinks that escape."""
    import os

    top = tmp_path_factory.mktemp("fuzz")
    (top / "outside.toml").write_text('name = "outside"\n')
    root = top / "proj"
    shutil.copytree(ROOT / "configs", root / "configs")
    pipes = root / "configs" / "pipelines"
    scene = tomllib.loads((root / "configs" / "scenes" / "corner.toml").read_text())
    inline = tomllib.loads((pipes / "corner.toml").read_text())
    inline["scene"] = scene
    inline["radar"] = {"n_samples": 256, "max_range": 60.0, "n_azimuth_bins": 61}
    (pipes / "inline_scene.toml").write_text(to_toml(inline))
    for d in pipes.parent.iterdir():
        os.mkfifo(d / "fifo.npy")
        os.mkfifo(d / "fifo.toml")
        (d / "a_dir.toml").mkdir()
        (d / "esc.npy").symlink_to(top / "outside.toml")
    return root


def run_case(tree: Path, base: str, seed: int) -> tuple[str, str]:
    """(mutation kind, outcome) of case ``seed`` on ``base``; outcome "ok", "typed" or a failure."""
    rng = random.Random(seed)
    src = tree / "configs" / base
    table, raw, kind = mutate(tomllib.loads(src.read_text()), rng)
    case = src.with_name(f"case_{seed}.toml")
    case.write_bytes(raw if raw is not None else to_toml(table).encode())

    def hang(*_):
        raise TimeoutError(f"case {seed} ({base}, {kind}) ran over {CASE_LIMIT_S} s")

    old = signal.signal(signal.SIGALRM, hang)
    signal.alarm(CASE_LIMIT_S)
    try:
        check_file(case)
        # what the checked config means: a sweep's points (which may override a NaN in the base table)
        points = [t for _, t in expand_sweep(table)] if table is not None else []
        outcome = "NaN accepted" if any(_has_nan(t) for t in points) else "ok"
    except XnlosError:
        outcome = "typed"
    except TimeoutError as exc:
        outcome = f"hang: {exc}"
    except Exception as exc:  # noqa: BLE001 (the point: nothing untyped may escape)
        outcome = f"untyped {type(exc).__name__}: {str(exc)[:200]}"
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
        case.unlink()
    return kind, outcome


@pytest.mark.filterwarnings("ignore::xnlos_core.errors.PipelineWarning")  # mutated configs may swap in cfar
@pytest.mark.fuzz
def test_check_raises_only_typed_errors(tree, fuzz_cases, monkeypatch):
    monkeypatch.chdir(tree)  # the config root of the copies, as when xnlos runs from the project
    counts: Counter = Counter()
    failures = []
    for i in range(fuzz_cases):
        base = BASES[i % len(BASES)]
        kind, outcome = run_case(tree, base, 1000 + i)
        counts[outcome if outcome in ("ok", "typed") else outcome.split(":")[0]] += 1
        if outcome not in ("ok", "typed"):
            failures.append(f"seed {1000 + i} {base} [{kind}]: {outcome}")
    print(f"\nconfig fuzz: {fuzz_cases} cases: {dict(counts)}")
    assert not failures, f"{len(failures)} of {fuzz_cases} cases failed:\n" + "\n".join(failures[:40])
    assert counts["ok"] and counts["typed"]  # the mutations reach both sides
