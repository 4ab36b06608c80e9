"""Checks on input: arrays (on construction of every core type) and parameter tables (pydantic
models of plugins and configs). Errors name the input and the rule."""
from __future__ import annotations

import difflib
from typing import Any

import numpy as np
from pydantic import BaseModel, ValidationError

from .errors import ConfigError, InputError


def as_array(
    name: str,
    value,
    *,
    dtype=np.float64,
    ndim: int | None = None,
    shape: tuple[int | None, ...] | None = None,
    finite: bool = True,
    readonly: bool = False,
) -> np.ndarray:
    """Return ``value`` as an array of ``dtype`` after checking dimensions, shape and finiteness.

    ``shape`` entries of ``None`` match any length. Raises :class:`InputError` naming ``name``.
    ``readonly``: return an array that cannot be written (:func:`frozen`), so that what was checked
    stays as checked — the core types store their arrays this way.
    """
    try:
        arr = np.asarray(value)
    except Exception as exc:
        raise InputError(f"{name}: cannot convert {type(value).__name__} to an array ({exc})") from None
    if dtype is not None:
        kind = np.dtype(dtype).kind
        if kind in "fi" and arr.dtype.kind == "c":
            raise InputError(f"{name}: expected real values, got complex dtype {arr.dtype}")
        if kind == "c" and arr.dtype.kind not in "fciub":
            raise InputError(f"{name}: expected numeric (complex) values, got dtype {arr.dtype}")
        if kind in "fi" and arr.dtype.kind not in "fiub":
            raise InputError(f"{name}: expected numeric values, got dtype {arr.dtype}")
        with np.errstate(over="ignore", invalid="ignore"):  # overflow becomes inf: refused below
            arr = arr.astype(dtype, copy=False)
    if ndim is not None and arr.ndim != ndim:
        raise InputError(f"{name}: expected a {ndim}-D array, got shape {arr.shape}")
    if shape is not None:
        if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
            want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
            raise InputError(f"{name}: expected shape {want}, got {arr.shape}")
    if finite and arr.dtype.kind in "fc" and arr.size and not np.all(np.isfinite(arr)):
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise InputError(f"{name}: {bad} of {arr.size} values are NaN or infinite; all must be finite")
    return frozen(arr, value) if readonly else arr


def frozen(arr: np.ndarray, source=None) -> np.ndarray:
    """``arr`` made read-only (``flags.writeable = False``); copied first when it shares memory
    with ``source`` (the caller's array: freezing a view of it would lock the caller's own data, and
    the caller could still change what was validated through its writable original) or is not the
    owner of its memory."""
    if arr.base is not None or (isinstance(source, np.ndarray) and np.may_share_memory(arr, source)):
        arr = arr.copy()
    arr.flags.writeable = False
    return arr


def check_ascending(name: str, axis: np.ndarray) -> None:
    """Require a strictly ascending 1-D axis."""
    if axis.size > 1 and not np.all(np.diff(axis) > 0):
        raise InputError(f"{name}: must be strictly ascending, got {axis[:4]}…")


def check_length(name: str, arr: np.ndarray, n: int, like: str) -> None:
    """Require ``len(arr) == n`` (the length of ``like``)."""
    if len(arr) != n:
        raise InputError(f"{name}: has {len(arr)} entries but {like} has {n}; they must match")


def format_errors(model: type[BaseModel], exc: ValidationError, source: str, prefix: str) -> str:
    """One line per pydantic error: ``source: [prefix.key] message``, with a did-you-mean for an
    unknown key and the offending value."""
    lines = []
    for err in exc.errors():
        loc = ".".join(str(x) for x in err["loc"])
        key = f"{prefix}.{loc}" if prefix and loc else (prefix or loc)
        msg = err["msg"]
        if err["type"] == "extra_forbidden":
            allowed = list(model.model_fields)
            if len(err["loc"]) == 1:
                close = difflib.get_close_matches(str(err["loc"][0]), allowed, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                msg = f"unknown key{hint} Allowed keys: {', '.join(allowed)}"
            else:
                msg = "unknown key"
        elif "input" in err and err["type"] != "missing":
            msg = f"{msg} (got {err['input']!r})"
        lines.append(f"{source}: [{key}] {msg}")
    return "\n".join(lines)


def validate_model(model: type[BaseModel], data: Any, *, source: str, prefix: str = "",
                   context: dict[str, Any] | None = None):
    """Validate ``data`` into ``model``; errors become one ConfigError naming source and keys.
    ``context``: pydantic validation context (e.g. :class:`xnlos_core.param_paths.PathContext`'s,
    which makes path fields relative to the config file)."""
    if isinstance(data, model):
        return data
    try:
        return model.model_validate(data, context=context)
    except ValidationError as exc:
        raise ConfigError(format_errors(model, exc, source, prefix)) from None
    except ConfigError:
        raise
    except ValueError as exc:  # raised by a model_post_init, which pydantic does not wrap
        raise ConfigError(f"{source}: [{prefix or model.__name__}] {exc}") from None
