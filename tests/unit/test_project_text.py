"""The project's text speaks of the software only: no tracked .py, .md or .toml file numbers the
project's own work items or working periods (the word for one followed by its number, with a
space, a hyphen or a '#' between), which mean nothing to a reader. CHANGELOG.md records user-visible changes by date instead."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
NUMBERED = re.compile(r"\b(?:issues?|sessions?|stops?)\b[\s-]*(?:#\s*)?\d+|out/eval/s\d+-", re.IGNORECASE)


def tracked_text_files() -> list[Path]:
    out = subprocess.run(["git", "ls-files", "*.py", "*.md", "*.toml"], cwd=ROOT, capture_output=True, text=True)
    if out.returncode != 0:  # not a git checkout (an sdist): every such file under the root
        return [p for ext in ("py", "md", "toml") for p in ROOT.rglob(f"*.{ext}") if ".venv" not in p.parts]
    return [ROOT / f for f in out.stdout.split()]


def numbered_references(text: str) -> list[str]:
    return [m.group(0) for m in NUMBERED.finditer(text)]


def test_no_file_numbers_the_projects_own_work():
    hits = []
    for path in tracked_text_files():
        if path.exists():
            for lineno, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
                hits += [f"{path.relative_to(ROOT)}:{lineno}: {ref!r}" for ref in numbered_references(line)]
    assert not hits, f"{len(hits)} numbered reference(s) to the project's work items:\n" + "\n".join(hits[:40])


def test_the_check_sees_the_usual_forms():
    issue, session = "iss" + "ue", "sess" + "ion"  # spelled apart, so this file holds none itself
    for text in (f"see {issue} 28", f"({issue.title()} #26, item 3)", f"after {session} 12's change",
                 f"{session}s 8 and 9", "out/eval/s" + "18-test", f"the pre-{issue}-31 path"):
        assert numbered_references(text), text
    for text in ("Sec. 5.1.2", "Eq. 7", "GitHub issue tracker", "a session of the CAN bus", "2 stops"):
        assert not numbered_references(text), text


COMMAND = re.compile(r"python[0-9.]* (?:-m )?benchmarks/([a-z_0-9]+)\.py|\bxnlos (?:eval|run|simulate|crossmodal|train)\b|\bmake [a-z]")


def test_every_benchmark_page_names_the_command_that_made_it():
    missing, stale = [], []
    for page in sorted((ROOT / "benchmarks").glob("*.md")):
        found = list(COMMAND.finditer(page.read_text()))
        if not found:
            missing.append(page.name)
        stale += [f"{page.name}: {m.group(1)}.py" for m in found
                  if m.group(1) and not (ROOT / "benchmarks" / f"{m.group(1)}.py").exists()]
    assert not missing, f"benchmark pages that do not say which command made them: {missing}"
    assert not stale, f"benchmark pages naming a script that does not exist: {stale}"
