"""Array checks used on construction of every core type; errors name the input and the rule."""
from __future__ import annotations

import numpy as np

from .errors import InputError


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
