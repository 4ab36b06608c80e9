"""``xnlos new-plugin KIND NAME``: write a ready plugin package to start from.

The package NAME/ holds ``pyproject.toml`` (the ``xnlos.plugins`` entry point), ``NAME/__init__.py``
(a working component of KIND, registered as NAME through ``xnlos_register_components``),
``tests/test_conformance.py`` (the conformance kit, each check one pytest test) and a README. Each
template uses the public xnlos API only and passes the kit as generated. The templates are the
``*.tmpl`` files beside this module (``string.Template``: ``$name``, ``$Class``, ``$kind``, ``$dist``).
"""
from __future__ import annotations

import importlib.util
import keyword
import re
from pathlib import Path
from string import Template

from xnlos_core.errors import ConfigError

TEMPLATES = Path(__file__).resolve().parent / "plugin_template"
KINDS_WITH_TEMPLATE = ("detector", "wall_estimator", "reconstructor", "tracker")
NAME = re.compile(r"[a-z][a-z0-9_]*")


def class_name(name: str) -> str:
    """The component's class name: ``my_peaks`` → ``MyPeaks``."""
    return "".join(part[:1].upper() + part[1:] for part in name.split("_") if part)


def check_request(kind: str, name: str, registry=None) -> None:
    """ConfigError unless a template of ``kind`` exists and ``name`` can be the new package's import name
    and the component's registered name (a lower-case identifier that no importable module and no
    registered component of ``kind`` has)."""
    from xnlos_core.interfaces import KINDS

    if kind not in KINDS_WITH_TEMPLATE:
        what = "a plugin kind without a template" if kind in KINDS else "no plugin kind"
        raise ConfigError(f"new-plugin: {kind!r} is {what}; templates exist for {', '.join(KINDS_WITH_TEMPLATE)}")
    if not NAME.fullmatch(name) or keyword.iskeyword(name):
        raise ConfigError(f"new-plugin: NAME {name!r} must be a lower-case Python identifier (letters, digits, _; "
                          "e.g. my_detector): it is the package's import name and the name a config gives")
    if importlib.util.find_spec(name) is not None:
        raise ConfigError(f"new-plugin: a module named {name!r} can already be imported here; the new package "
                          "would hide it or be hidden by it: choose another NAME")
    if registry is None:
        from xnlos_core.registry import get_registry

        registry = get_registry()
    if (kind, name) in registry:
        raise ConfigError(f"new-plugin: a {kind} named {name!r} is already registered (by "
                          f"{registry.get(kind, name).provider}); choose another NAME")


def write_plugin(kind: str, name: str, out: str | Path = ".", registry=None) -> Path:
    """Write the package ``out/name`` for a component of ``kind`` named ``name``; returns its folder.
    ConfigError for a kind without a template, an unusable name (:func:`check_request`) or an
    existing folder; OSError where ``out`` cannot be written."""
    check_request(kind, name, registry)
    root = Path(out) / name
    if root.exists():
        raise ConfigError(f"new-plugin: {root} exists; remove it or give another --out")
    fields = {"name": name, "Class": class_name(name), "kind": kind, "dist": "xnlos-" + name.replace("_", "-")}
    files = {"pyproject.toml": "pyproject.toml.tmpl", "README.md": "README.md.tmpl",
             f"{name}/__init__.py": f"{kind}.py.tmpl", "tests/test_conformance.py": "test_conformance.py.tmpl"}
    for target, template in files.items():
        path = root / target
        path.parent.mkdir(parents=True, exist_ok=True)
        text = Template((TEMPLATES / template).read_text(encoding="utf-8")).substitute(fields)
        path.write_text(text, encoding="utf-8")
    return root


def add_command(sub) -> None:
    """``xnlos new-plugin KIND NAME [--out DIR]`` (called by :func:`xnlos_core.app.cli.build_parser`)."""
    c = sub.add_parser("new-plugin", help="write a plugin package to start from: a working component, its "
                       "entry point and its conformance tests")
    c.add_argument("kind", metavar="KIND", help=f"the plugin kind: {', '.join(KINDS_WITH_TEMPLATE)}")
    c.add_argument("name", metavar="NAME", help="lower-case identifier: the package's import name and the "
                   "name a config gives, e.g. my_detector")
    c.add_argument("--out", type=Path, default=Path("."), help="the folder to write NAME/ into (default: here)")
    c.set_defaults(func=_cmd)


def _cmd(args) -> int:
    root = write_plugin(args.kind, args.name, args.out)
    print(f"wrote {root}: the {args.kind} {args.name!r} in {args.name}/__init__.py, its entry point in "
          "pyproject.toml and its conformance tests in tests/")
    print(f"next: cd {root} && pytest    (pip install -e . registers it: xnlos plugins --kind {args.kind})")
    return 0
