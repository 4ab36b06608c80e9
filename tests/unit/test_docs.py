"""The documentation cannot rot: every ```python block of every docs page and of README.md runs, in
order, in one namespace per page, in a temporary working directory holding a copy of the project's
configs/ (so a page reads as if run from a checkout); and the site builds with ``mkdocs build --strict``.

A fenced block preceded by ``<!-- file: NAME -->`` is also written to NAME (a relative path, e.g.
``mypkg/__init__.py``) in that directory before the page's blocks run (e.g. the TOML a recipe reads, or a
plugin module the page imports: the directory is on ``sys.path`` while the page runs). Blocks fenced
```py are shown, not run (a file that cannot run on its own)."""
from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
import traceback
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
PAGES = sorted(p.relative_to(ROOT).as_posix() for p in DOCS.rglob("*.md")) + ["README.md"]

FENCE = re.compile(r"^```(?P<lang>[\w+-]*)[^\n]*\n(?P<body>.*?)^```[ \t]*$", re.M | re.S)
FILE_MARK = re.compile(r"<!--\s*file:\s*(?P<name>[\w.-]+(?:/[\w.-]+)*)\s*-->\s*\n```")


def blocks(text: str) -> list[tuple[int, str, str]]:
    """(line number, language, source) of every fenced block, in order."""
    return [(text.count("\n", 0, m.start()) + 1, m["lang"], m["body"]) for m in FENCE.finditer(text)]


def files(text: str) -> dict[str, str]:
    """{name: content} of the blocks marked ``<!-- file: NAME -->``."""
    out = {}
    for m in FILE_MARK.finditer(text):
        fence = FENCE.match(text, m.end() - 3)
        assert fence, f"<!-- file: {m['name']} --> is not followed by a fenced block"
        out[m["name"]] = fence["body"]
    return out


def python_blocks(page: str) -> list[tuple[int, str]]:
    return [(line, body) for line, lang, body in blocks((ROOT / page).read_text(encoding="utf-8")) if lang == "python"]


RUNNABLE = [p for p in PAGES if python_blocks(p)]


def test_the_pages_have_examples_that_run():
    """The guide shows code that runs (a guard for the block parser above)."""
    assert {"docs/index.md", "docs/api.md", "docs/plugins.md", "docs/recordings.md"} <= set(RUNNABLE)


@pytest.mark.parametrize("page", RUNNABLE)
def test_page_examples_run(page, tmp_path, monkeypatch):
    text = (ROOT / page).read_text(encoding="utf-8")
    code = python_blocks(page)
    shutil.copytree(ROOT / "configs", tmp_path / "configs")
    for name, content in files(text).items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(content, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    namespace = {"__name__": "__docs__"}
    try:
        for k, (line, body) in enumerate(code, 1):
            try:
                exec(compile(body, f"{page}:{line}", "exec"), namespace)
            except Exception:
                pytest.fail(f"{page}: python block {k} of {len(code)} (line {line}) raised:\n"
                            f"{traceback.format_exc(limit=-6)}", pytrace=False)
    finally:
        if "matplotlib.pyplot" in sys.modules:
            sys.modules["matplotlib.pyplot"].close("all")
        for name, module in list(sys.modules.items()):  # the page's own modules are forgotten with its directory
            if Path(getattr(module, "__file__", None) or "/").is_relative_to(tmp_path):
                del sys.modules[name]


def test_readme_links_point_at_files_that_exist():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    targets = {t.split("#")[0] for t in re.findall(r"\]\(([^)\s]+)\)", text)
               if not re.match(r"[a-z]+:|#", t)}
    missing = sorted(t for t in targets if not (ROOT / t).exists())
    assert not missing, f"README.md links to missing files: {missing}"


@pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None or importlib.util.find_spec("mkdocstrings") is None,
                    reason="mkdocs and mkdocstrings are not installed (pip install -e '.[docs]'; make demo/test "
                           "install them from the lock)")
def test_site_builds_strict(tmp_path):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    out = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, f"mkdocs build --strict failed:\n{out.stdout[-3000:]}\n{out.stderr[-5000:]}"
    for page in ("index.html", "api.html", "reference/types.html", "benchmarks/index.html", "benchmarks/table2.html",
                 "benchmarks/table2_fig6_proposed.png"):
        assert (tmp_path / "site" / page).is_file(), f"the site lacks {page}"


def test_front_door_files_agree_with_the_package():
    """LICENSE, CITATION.cff and py.typed say what pyproject.toml says (version, licence, typed package)."""
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    assert "MIT License" in (ROOT / "LICENSE").read_text(encoding="utf-8") and project["project"]["license"]["text"] == "MIT"
    cff = (ROOT / "CITATION.cff").read_text(encoding="utf-8")
    assert re.search(r"^cff-version: 1\.2\.0$", cff, re.M) and re.search(r"^license: MIT$", cff, re.M)
    assert re.search(rf"^version: {re.escape(project['project']['version'])}$", cff, re.M), \
        "CITATION.cff's version differs from pyproject.toml's"
    assert (ROOT / "xnlos_core" / "py.typed").is_file()
    assert "py.typed" in project["tool"]["setuptools"]["package-data"]["xnlos_core"]
    assert "docs" in project["project"]["optional-dependencies"]
