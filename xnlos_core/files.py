"""Reading the files a configuration names, without trusting the configuration.

The rule (docs "Configs"): a path written in a config is resolved against the folder of the file
that names it (wherever the user stands) and, after every symlink is resolved, must lie inside a
*config root* (:func:`config_roots`):

- the folder of the top-level config file;
- its project: the nearest folder above it (or itself) holding an ``xnlos.toml`` or a
  ``pyproject.toml``, found the way pytest finds its rootdir, so ``configs/pipelines/corner.toml``
  may name ``../scenes/corner.toml`` from any working directory;
- the current working directory;
- folders the user adds on purpose (a lab's shared library of radars and scenes): ``xnlos --root
  DIR``, the ``XNLOS_CONFIG_ROOTS`` environment variable (folders separated by ``os.pathsep``), and
  ``roots = [...]`` under ``[paths]`` of the project's ``xnlos.toml`` (or ``[tool.xnlos]`` of its
  ``pyproject.toml``), relative to that file.

Absolute paths obey the same rule. A config file itself cannot widen it (only the user's command
line, environment or project file can), so a downloaded config cannot read ``~/.ssh`` or
``/etc/passwd`` (``../../../etc/passwd`` or a symlink out of the roots is refused alike).
Only regular files are read: a FIFO, a device or a directory is refused before it is opened,
and the file is opened with ``O_NONBLOCK`` and checked again with ``fstat`` so that a FIFO
swapped in between cannot block the reader. Every refusal is a :class:`ConfigError` naming the
config, the key, the value and what was expected.

Hand-written rather than a library: the standard library has every piece (``os.open``,
``os.fstat``, ``Path.resolve``) and no package implements this rule.
"""
from __future__ import annotations

import errno
import os
import stat
import tomllib
from pathlib import Path
from typing import Any

from .errors import ConfigError

MAX_CONFIG_BYTES = 16 * 2**20  # a TOML config or preset; the shipped ones are < 10 kB
MAX_DATA_BYTES = 2**30  # a mesh or coupling matrix read whole into memory


def file_kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def os_reason(exc: OSError) -> str:
    if exc.errno == errno.ENAMETOOLONG:
        return "the path or one of its names is too long for the file system"
    if exc.errno == errno.ELOOP:
        return "too many levels of symbolic links"
    return exc.strerror or type(exc).__name__


ROOTS_ENV = "XNLOS_CONFIG_ROOTS"  # extra config roots, separated by os.pathsep (``xnlos --root`` adds to it)
PROJECT_FILES = ("xnlos.toml", "pyproject.toml")  # the files that mark a project folder


def project_root(folder: str | Path) -> Path | None:
    """The nearest folder at or above ``folder`` holding one of :data:`PROJECT_FILES` (as pytest finds
    its rootdir from its ini files), symlinks resolved; None when there is none."""
    try:
        d = Path(folder).resolve()
    except (OSError, RuntimeError, ValueError):
        return None
    for p in (d, *d.parents):
        if any((p / name).is_file() for name in PROJECT_FILES):
            return p
    return None


def _project_roots(project: Path) -> list[Path]:
    """``roots`` of ``[paths]`` in ``project``/xnlos.toml, else of ``[tool.xnlos]`` in its pyproject.toml,
    relative to that file; a file that cannot be read or holds no such list gives none (a broken
    pyproject.toml is the packaging tools' to report, not a reason to refuse a config)."""
    for name, keys in (("xnlos.toml", ("paths",)), ("pyproject.toml", ("tool", "xnlos"))):
        f = project / name
        if not f.is_file():
            continue
        try:
            table: Any = tomllib.loads(f.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
            if name == "xnlos.toml":
                raise ConfigError(f"{f}: cannot read the project file (expected TOML with [paths] roots = [...])") \
                    from None
            continue
        for k in keys:
            table = table.get(k, {}) if isinstance(table, dict) else {}
        roots = table.get("roots", []) if isinstance(table, dict) else []
        if not isinstance(roots, list) or not all(isinstance(r, str) and r for r in roots):
            raise ConfigError(f"{f}: [{'.'.join(keys)}] roots must be a list of folder paths, got {roots!r}")
        return [project / Path(r).expanduser() for r in roots]
    return []


def extra_roots() -> list[Path]:
    """The roots the user added: ``XNLOS_CONFIG_ROOTS`` (``xnlos --root``), then none else."""
    return [Path(r).expanduser() for r in os.environ.get(ROOTS_ENV, "").split(os.pathsep) if r.strip()]


def config_roots(root_dir: str | Path) -> tuple[Path, ...]:
    """The folders paths in a config may point into (module doc): ``root_dir`` (the top-level config's
    folder), its project root and that project's ``roots``, the current working directory, and the
    folders of ``XNLOS_CONFIG_ROOTS``; each with symlinks resolved, each once."""
    project = project_root(root_dir)
    candidates = [Path(root_dir)] + ([project, *_project_roots(project)] if project else []) + [Path.cwd()]
    roots: list[Path] = []
    for d in candidates + extra_roots():
        try:
            r = Path(d).resolve()
        except (OSError, RuntimeError, ValueError):
            continue
        if r not in roots:
            roots.append(r)
    return tuple(roots)


OUTSIDE_HINT = (f"allow another folder with xnlos --root DIR, the {ROOTS_ENV} environment variable, or roots = "
                "[...] under [paths] in the project's xnlos.toml")


def resolve_config_path(value, *, source: str, key: str, base_dir: str | Path,
                        root_dir: str | Path | None = None, suffixes: tuple[str, ...] | None = None) -> Path:
    """The regular file a config names at ``key``: resolved against ``base_dir`` (the folder of the
    file that names it), symlinks resolved, inside :func:`config_roots` of ``root_dir`` (default
    ``base_dir``). ``suffixes``: allowed lower-case extensions. Raises ConfigError otherwise."""
    where = f"{source}: [{key}]"
    if not isinstance(value, str) or not value or "\0" in value:
        raise ConfigError(f"{where} expected a non-empty file path string, got {value!r}")
    if suffixes is not None and Path(value).suffix.lower() not in suffixes:
        raise ConfigError(f"{where} {value!r}: expected a file ending in {', '.join(suffixes)}")
    path = Path(value)
    if not path.is_absolute():
        path = Path(base_dir) / path
    try:
        # the roots are checked before existence: a config cannot probe which files exist elsewhere
        real = path.resolve()
        roots = config_roots(root_dir if root_dir is not None else base_dir)
        if not any(real.is_relative_to(r) for r in roots):
            raise ConfigError(f"{where} file {value!r} resolves to {real}, outside the config roots "
                              f"({', '.join(map(str, roots))}); a config may only name files inside its "
                              f"folder, its project, the working directory or a root the user added: {OUTSIDE_HINT}"
                              + linked_out(path, roots))
        mode = real.stat().st_mode
    except FileNotFoundError:
        raise ConfigError(f"{where} file {value!r} does not exist (looked for {path})") from None
    except (OSError, RuntimeError) as exc:  # RuntimeError: a symlink loop on older Pythons
        reason = os_reason(exc) if isinstance(exc, OSError) else str(exc)
        raise ConfigError(f"{where} cannot use file {value[:200]!r}: {reason}") from None
    if not stat.S_ISREG(mode):
        raise ConfigError(f"{where} {value!r} ({real}) is {file_kind(mode)}; expected a regular file")
    return real


def linked_out(path: Path, roots: tuple[Path, ...]) -> str:
    """The part of a refusal that explains a symlink: when ``path`` (absolute, not resolved) lies in
    a config root but resolves outside every root, it or a folder on its way is a symbolic link out
    of the roots. A link does not widen the roots (a downloaded folder may hold links to ~/.ssh); the
    user does, with :data:`ROOTS_ENV` (``xnlos --root``). Empty otherwise."""
    lexical = Path(os.path.abspath(path))
    if not any(lexical.is_relative_to(r) or lexical.is_relative_to(os.path.abspath(r)) for r in roots):
        return ""
    return (f". {str(path)[:200]!r} lies inside them but is, or passes through, a symbolic link that leads out: a "
            "link does not widen the config roots. To read data kept elsewhere (e.g. captures on another disk), add "
            f"its folder with xnlos --root DIR or the environment variable {ROOTS_ENV} (folders separated by "
            f"{os.pathsep!r})")


def open_regular_fd(path: str | Path, *, what: str, error: type[Exception] = ConfigError,
                    missing: str = "no such file (expected an existing regular file)") -> int:
    """A read-only descriptor of ``path`` after ``fstat`` of the open descriptor showed a regular file.

    Opened with O_NONBLOCK, so a FIFO or a device is refused without blocking even when it replaced a
    checked path. Raises ``error`` (naming ``what``) when the file is missing, unreadable or not a
    regular file. The caller closes the descriptor."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise error(f"{what}: {missing}") from None
    except (OSError, TypeError, ValueError) as exc:
        reason = os_reason(exc) if isinstance(exc, OSError) else str(exc)
        raise error(f"{what}: cannot open: {reason}") from None
    try:
        mode = os.fstat(fd).st_mode
    except OSError as exc:
        os.close(fd)
        raise error(f"{what}: cannot read: {os_reason(exc)}") from None
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise error(f"{what} is {file_kind(mode)}; expected a regular file")
    return fd


def read_file_bytes(path: str | Path, *, what: str, max_bytes: int = MAX_DATA_BYTES) -> bytes:
    """The bytes of the regular file ``path``; ``what`` names it in errors (e.g. "config file x.toml").

    Opened with O_NONBLOCK and checked with fstat, so a FIFO or device is refused without blocking
    even when it replaced a checked file. Raises ConfigError for anything but a readable regular
    file of at most ``max_bytes``."""
    fd = open_regular_fd(path, what=what, error=ConfigError, missing="no such file")
    try:
        st = os.fstat(fd)
        if st.st_size > max_bytes:
            raise ConfigError(f"{what} is {st.st_size} bytes; at most {max_bytes} are read")
        chunks, total = [], 0
        while chunk := os.read(fd, min(1 << 20, max_bytes + 1 - total)):
            chunks.append(chunk)
            total += len(chunk)
            if total > max_bytes:
                raise ConfigError(f"{what} grew beyond {max_bytes} bytes while being read")
        return b"".join(chunks)
    except OSError as exc:
        raise ConfigError(f"{what}: cannot read: {os_reason(exc)}") from None
    finally:
        os.close(fd)


def decode_utf8(data: bytes, what: str) -> str:
    """``data`` as UTF-8 text; invalid bytes give a ConfigError naming ``what`` and the byte offset."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise ConfigError(f"{what}: not UTF-8 text: byte {exc.start} (line {line}) is "
                          f"{data[exc.start:exc.start + 1]!r} ({exc.reason})") from None


MAX_DEPTH = 32  # nested tables/arrays; the shipped configs use ≤ 4


def _depth(value: Any) -> int:
    """Nesting depth of tables and arrays (iterative: a deep value cannot overflow the stack)."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        node, d = stack.pop()
        if isinstance(node, dict):
            node = list(node.values())
        if isinstance(node, list):
            deepest = max(deepest, d + 1)
            stack.extend((v, d + 1) for v in node if isinstance(v, (dict, list)))
    return deepest


def load_toml(path: str | Path) -> dict[str, Any]:
    """Parse a TOML file; errors (ConfigError) name the file and say what is wrong.

    Only a regular file of at most 16 MiB is read (a FIFO or device is refused without blocking,
    :mod:`xnlos_core.files`); it must be UTF-8 (the error gives the offending byte's offset), valid
    TOML (the error gives line and column) and nested at most ``MAX_DEPTH`` levels deep.
    """
    path = Path(path)
    what = f"{path}: configuration file"
    text = decode_utf8(read_file_bytes(path, what=what, max_bytes=MAX_CONFIG_BYTES), str(path))
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: invalid TOML: {exc}") from None
    except RecursionError:  # tomllib parses nested arrays / inline tables recursively
        raise ConfigError(f"{path}: invalid TOML: arrays or inline tables nested too deeply "
                          f"(at most {MAX_DEPTH} levels)") from None
    if _depth(table) > MAX_DEPTH:
        raise ConfigError(f"{path}: tables and arrays nested {_depth(table)} levels deep; at most {MAX_DEPTH}")
    return table
