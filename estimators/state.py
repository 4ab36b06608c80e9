"""Reading a stage's checkpoint (``state()`` → JSON → ``load_state()``: the trackers, lsq's history of
LOS detections) back with checks.

A state is plain JSON: numbers, strings, lists (arrays as nested lists; Python's float repr makes
every float64 exact through ``json``). It comes from a file, so nothing in it is trusted: each field
is read by one of the functions here, which raise :class:`xnlos_core.errors.InputError` naming the
stage, the key and what was expected. Nothing is ever unpickled or evaluated.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from xnlos_core.errors import InputError

FORMAT = 1  # version of the state layout written by the built-in trackers


class StateReader:
    """Checked access to one dict of a stage's state; ``where`` names it in errors, e.g.
    "KalmanTracker.load_state: tracks[2]"."""

    def __init__(self, data: Any, where: str):
        if not isinstance(data, dict):
            raise InputError(f"{where}: expected a JSON object, got {type(data).__name__}")
        self.data, self.where = data, where

    def _get(self, key: str) -> Any:
        if key not in self.data:
            raise InputError(f"{self.where}: missing key {key!r}")
        return self.data[key]

    def _bad(self, key: str, value: Any, expected: str) -> InputError:
        return InputError(f"{self.where}: {key} = {str(value)[:60]}; expected {expected}")

    def integer(self, key: str, low: int | None = None) -> int:
        v = self._get(key)
        if not isinstance(v, int) or isinstance(v, bool) or (low is not None and v < low):
            raise self._bad(key, v, "an integer" + ("" if low is None else f" ≥ {low}"))
        return v

    def number(self, key: str, optional: bool = False) -> float | None:
        v = self._get(key)
        if v is None and optional:
            return None
        if not isinstance(v, (int, float)) or isinstance(v, bool):
            raise self._bad(key, v, "a number" + (" or null" if optional else ""))
        return float(v)

    def flag(self, key: str) -> bool:
        v = self._get(key)
        if not isinstance(v, bool):
            raise self._bad(key, v, "true or false")
        return v

    def text(self, key: str) -> str:
        v = self._get(key)
        if not isinstance(v, str):
            raise self._bad(key, v, "a string")
        return v

    def array(self, key: str, shape: tuple[int | None, ...], dtype=np.float64) -> np.ndarray:
        """float64 (or ``dtype``) array of ``shape`` (None: any length on that axis)."""
        v = self._get(key)
        try:
            a = np.array(v, dtype=dtype)
        except (TypeError, ValueError):
            raise self._bad(key, v, f"an array of shape {shape}") from None
        if a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape)) or a.dtype == object:
            raise self._bad(key, v, f"an array of shape {shape}")
        if dtype is bool and not _all_bool(v):
            raise self._bad(key, v, "an array of true/false")
        return a

    def items(self, key: str) -> list:
        v = self._get(key)
        if not isinstance(v, list):
            raise self._bad(key, v, "a list")
        return v

    def sub(self, key: str) -> "StateReader":
        return StateReader(self._get(key), f"{self.where}: {key}")


def _all_bool(v) -> bool:
    return isinstance(v, bool) if not isinstance(v, list) else all(_all_bool(x) for x in v)


def header(state: Any, tracker: str) -> StateReader:
    """The checked top level of ``tracker``'s state (its ``tracker`` and ``format`` keys match)."""
    r = StateReader(state, f"{tracker}.load_state")
    if r.text("tracker") != tracker:
        raise InputError(f"{tracker}.load_state: the state is {r.data['tracker']!r}'s, not {tracker!r}'s")
    if r.integer("format") != FORMAT:
        raise InputError(f"{tracker}.load_state: state format {r.data['format']} is not {FORMAT}")
    return r
