"""Paths in plugin parameters, resolved against the folder of the config file that names them.

A plugin declares a path parameter with the annotated type :data:`ConfigPath` (or
:func:`config_path` to add keywords that are not paths, e.g. a checkpoint's ``"default"``)::

    class Params(BaseModel):
        path: ConfigPath = Field("out/data/default", description="dataset folder")
        checkpoint: Annotated[str, config_path("default", "none")] = "default"

When the pipeline validates the parameters it passes a :class:`PathContext` (the config's
``base_dir`` and the folder whose config roots bound it) as pydantic validation context; the
field's value is then replaced by an absolute path:

* a relative path is taken from ``base_dir`` (the config file's folder, not the working
  directory), and after every symlink is resolved it must lie inside the config roots of
  :mod:`xnlos_core.files` (``../../../etc`` or a symlink out of the folder is refused);
* an absolute path (or ``~/…``) is kept as written, as before: the user named that place;
* a keyword of the field (``"default"``, ``"none"``) and ``None`` pass unchanged.

Without a context (a plugin built from a dict in Python, ``Plugin({"path": …})``) nothing is
resolved: a relative path is then relative to the working directory, as any Python path is.
Whether the file exists, and what kind it is, stays the plugin's check at the point of use
(a recording is often made after the config is written).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

from pydantic import AfterValidator, ValidationInfo

from .files import OUTSIDE_HINT, config_roots, linked_out

CONTEXT_KEY = "xnlos_paths"


@dataclass(frozen=True)
class PathContext:
    """Where relative parameter paths resolve: ``base_dir`` (the config file's folder) and
    ``root_dir`` (the top-level config's folder, whose config roots bound them; default base_dir)."""

    base_dir: str | Path
    root_dir: str | Path | None = None

    def validation_context(self) -> dict[str, Any]:
        """The pydantic ``context`` argument that carries this."""
        return {CONTEXT_KEY: self}


def resolve_param_path(value: str, ctx: PathContext) -> str:
    """``value`` as an absolute path string: relative ones from ``ctx.base_dir`` and inside the config
    roots, absolute ones (and ``~/…``) unchanged but for ``~``. Raises ValueError otherwise."""
    if not value or "\0" in value:
        raise ValueError(f"expected a non-empty path without NUL characters, got {value!r}")
    path = Path(value).expanduser()
    if path.is_absolute():
        return str(path)
    try:
        real = (Path(ctx.base_dir) / path).resolve()
    except (OSError, RuntimeError) as exc:  # a symlink loop, a name too long
        raise ValueError(f"cannot use path {value[:200]!r}: {exc}") from None
    roots = config_roots(ctx.root_dir if ctx.root_dir is not None else ctx.base_dir)
    if not any(real.is_relative_to(r) for r in roots):
        raise ValueError(f"path {value[:200]!r} (relative to the config file's folder {ctx.base_dir}) resolves to "
                         f"{real}, outside the config roots ({', '.join(map(str, roots))}); a relative path may only "
                         "name a place inside the config's folder, its project, the working directory or a root the "
                         f"user added (write an absolute path for a place elsewhere, or {OUTSIDE_HINT})"
                         + linked_out(Path(ctx.base_dir) / path, roots))
    return str(real)


def config_path(*keywords: str) -> AfterValidator:
    """The validator that makes a ``str`` field a config-relative path; ``keywords`` are values that
    are not paths and pass unchanged (e.g. ``"default"``, ``"none"``)."""

    def _resolve(value, info: ValidationInfo):
        ctx = (info.context or {}).get(CONTEXT_KEY) if isinstance(info.context, dict) else None
        if ctx is None or value is None or value in keywords:
            return value
        return resolve_param_path(value, ctx)

    return AfterValidator(_resolve)


ConfigPath = Annotated[str, config_path()]
"""A ``str`` parameter holding a file or folder path, relative to the config file that names it."""

RELATIVE_TO_CONFIG = " (relative to the config file's folder)"
"""Appended to the description of a :data:`ConfigPath` field (``xnlos plugins`` shows it)."""
