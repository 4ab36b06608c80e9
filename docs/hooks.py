"""MkDocs hooks of the xnlos site (``hooks:`` in mkdocs.yml).

* The benchmark pages stay where the benchmark scripts write them, ``benchmarks/*.md`` beside their
  figures ``benchmarks/*.png``: they join the site as generated files under ``benchmarks/`` (read from
  the repository at build time, never copied into docs/), with an index page that lists them by title
  (less the tracker references some titles carry) and a nav entry per page under "Benchmarks".
* The API reference renders docstrings written for Sphinx: the roles (``:func:``, ``:class:``, …) in
  front of a name are dropped, and so is the ``~`` that shortens it, leaving the name as code; a
  paragraph that introduces a literal block ends in one colon, not reST's two.
"""
from __future__ import annotations

import re
from pathlib import Path

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"
ROLE = re.compile(r":(?:py:)?(?:func|class|meth|attr|data|mod|exc|obj|const):(<code>)~?")
LITERAL_INTRO = re.compile(r"::(</p>\s*<pre>)")
TRACKER_REF = re.compile(r"issue \d+(?:,? item \d+)?(?:\s*,\s*issue \d+)*\s*[;,]?\s*")


def _title(md: Path) -> str:
    """A page's first heading, for the index: without the tracker references some titles carry."""
    for line in md.read_text(encoding="utf-8").splitlines():
        if line.startswith("# "):
            title = re.sub(r"\s*\(\s*\)", "", TRACKER_REF.sub("", line[2:].strip()))
            return re.sub(r"\(\s+", "(", title).strip()
    return md.stem


def benchmark_index(pages: list[Path]) -> str:
    """The generated ``benchmarks/index.md``: one line per benchmark page, by its title."""
    lines = ["# Benchmarks", "",
             "Speed and speed-versus-accuracy measurements, written by the scripts in `benchmarks/` "
             "(`make bench` reruns the main ones; each page names its command and machine). Pages registered "
             "in `benchmarks/pages.toml` are rerun by `make benchmarks`, and their deterministic tables are "
             "checked against a rerun by `make benchmarks-check` ([how](../reproducibility.md)). "
             "The user guide links here wherever it quotes a figure.", ""]
    lines += [f"- [{_title(p)}]({p.name})" for p in pages]
    return "\n".join(lines) + "\n"


def on_config(config):
    """Fill the nav's "Benchmarks" entry: the generated index, then every benchmark page, labelled by its
    file name (their titles are long)."""
    pages = sorted(BENCHMARKS.glob("*.md"))
    for i, entry in enumerate(config.nav or []):
        if isinstance(entry, dict) and entry.get("Benchmarks") == "benchmarks/index.md":
            config.nav[i] = {"Benchmarks": ["benchmarks/index.md",
                                            *({p.stem.replace("_", " "): f"benchmarks/{p.name}"} for p in pages)]}
    return config


def on_files(files: Files, config) -> Files:
    pages = sorted(BENCHMARKS.glob("*.md"))
    for path in [*pages, *sorted(BENCHMARKS.glob("*.png"))]:
        files.append(File.generated(config, f"benchmarks/{path.name}", abs_src_path=str(path)))
    files.append(File.generated(config, "benchmarks/index.md", content=benchmark_index(pages)))
    return files


def on_page_content(html: str, page, config, files) -> str:
    if page.file.src_uri.startswith("reference/"):
        return LITERAL_INTRO.sub(r":\1", ROLE.sub(r"\1", html))
    return html
