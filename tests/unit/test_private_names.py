"""No module of the project imports another module's private (underscored) name: what a module
shares is public, so a change inside one file cannot break another silently. Tests may reach into
private names (they pin internals on purpose); the packages may not."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("xnlos_core", "sims", "plugins", "estimators", "hardware")


def private_imports(path: Path) -> list[str]:
    """'file:line: from MODULE import _name' for each import of an underscored name from another module."""
    tree = ast.parse(path.read_text(), str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module != "__future__":
            for alias in node.names:
                if alias.name.startswith("_") and not alias.name.startswith("__"):
                    out.append(f"{path.relative_to(ROOT)}:{node.lineno}: from {'.' * node.level}{node.module or ''} "
                               f"import {alias.name}")
    return out


def test_no_module_imports_a_private_name_of_another():
    found = [hit for pkg in PACKAGES for f in sorted((ROOT / pkg).rglob("*.py")) for hit in private_imports(f)]
    assert not found, "private names imported across modules:\n" + "\n".join(found)


def test_the_check_sees_a_private_import(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("from xnlos_core.signal.chain import range_fft, _window\n")
    assert len(private_imports_of(f)) == 1


def private_imports_of(path: Path) -> list[str]:
    global ROOT
    root, ROOT = ROOT, path.parent
    try:
        return private_imports(path)
    finally:
        ROOT = root
