"""Input checks shared by the trackers: one frame's hidden points and its timestamp."""
from __future__ import annotations

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.types import HiddenPoints, Tracks


def frame_time(owner: str, points, timestamp, t_last: float | None) -> float:
    """``timestamp`` as a float [s] after checking ``points`` is HiddenPoints and time does not run back."""
    if not isinstance(points, HiddenPoints):
        raise InputError(f"{owner}.update: expected HiddenPoints, got {type(points).__name__}")
    t = float(timestamp)
    if not np.isfinite(t):
        raise InputError(f"{owner}.update: timestamp must be finite, got {timestamp}")
    if t_last is not None and t < t_last:
        raise InputError(f"{owner}.update: timestamp {t} s is before the previous frame's "
                         f"{t_last} s; timestamps must not decrease (call reset() to start over)")
    return t


def no_tracks(t: float) -> Tracks:
    """The empty Tracks at time ``t`` [s]."""
    e = np.empty((0, 2))
    return Tracks(np.empty(0, np.int64), e, e, e, t)
