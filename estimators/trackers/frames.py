"""Input checks shared by the trackers: one frame's hidden points and its timestamp, and the
forecast horizons parameter."""
from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import Field

from xnlos_core.errors import InputError
from xnlos_core.types import HiddenPoints, Tracks


# The ``horizons`` parameter of every tracker: 1–64 forecast horizons [s], each within [0, 3] s
Horizons = Annotated[tuple[Annotated[float, Field(ge=0.0, le=3.0)], ...], Field(min_length=1, max_length=64)]
HORIZONS = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
HORIZONS_DOC = "forecast horizons [s] ahead of each frame, each within [0, 3] s"


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
