"""The LOS detections of earlier frames, pooled into a wall fit (a static radar, static walls).

A radar that does not move sees the same facades frame after frame, each time with fresh noise and,
behind a CFAR detector, a different handful of cells: one frame may hold three LOS points of a wall,
the next twenty. Fitting the wall to the LOS detections of the last K frames (positions are in the
radar's frame, so this holds only while the radar stands still) gives every frame the wall the last
K frames saw. With independent noise per frame the (φ, b) covariance of a wall seen in all K frames
shrinks about K-fold (:mod:`estimators.lsq`, Var φ = σ²/Σt_i²).

Only what stands still is held: a road user in line of sight leaves an LOS echo in every frame, and
those of K frames line up along its path into a "wall" that is not there (a car driving out of the
cross street, 5 m/s over 5 frames of 0.2 s: a 4 m segment). With Doppler, a detection is held only if
its radial velocity |v_r| ≤ ``max_speed`` [m/s] (a wall's is 0 up to the noise; the default X-band
Doppler bin is 0.57 m/s wide); a road user moving across the line of sight (v_r ≈ 0) still passes.
Without Doppler every LOS detection is held.

Held here: the LOS rows (range, azimuth, label, confidence, range_std, azimuth_std) of up to K − 1
earlier frames, newest first. The estimator's state (``WallEstimator.state``) is these rows as JSON
lists, exact through ``json``; nothing in a loaded state is trusted (:class:`StateReader`).
"""
from __future__ import annotations

import numpy as np

from estimators.state import StateReader
from xnlos_core.errors import InputError
from xnlos_core.types import LOS, Detections

FIELDS = ("range", "azimuth", "label", "confidence", "range_std", "azimuth_std")
FORMAT = 1


class LOSHistory:
    """The static LOS detections of the ``frames`` − 1 frames before the current one (``frames`` ≥ 1;
    with Doppler, static: |radial velocity| ≤ ``max_speed`` [m/s])."""

    def __init__(self, frames: int, max_speed: float = np.inf):
        self.frames = int(frames)
        self.max_speed = float(max_speed)
        self.held: list[Detections] = []  # newest first, static LOS rows only

    def pool(self, detections: Detections, who: str) -> Detections:
        """``detections`` (all rows, in order) followed by the held LOS rows, newest frame first; then
        remembers this frame's LOS rows and forgets the oldest frame beyond ``frames`` − 1. With
        ``frames`` = 1 returns ``detections`` itself. Of this frame's LOS rows only the static ones are
        remembered (module docstring); this frame's fit uses them all. Rows 0 … len(detections) − 1 of the result are
        ``detections``' rows, so indices below len(detections) point into it. InputError (naming
        ``who``) for anything but Detections."""
        if not isinstance(detections, Detections):
            raise InputError(f"{who}.estimate: expected Detections, got {type(detections).__name__}")
        if self.frames == 1:
            return detections
        pooled = Detections.concat(detections, *self.held) if self.held else detections
        keep = detections.label == LOS
        if detections.velocity is not None:
            keep &= np.abs(detections.velocity) <= self.max_speed
        self.held = [detections.select(np.flatnonzero(keep)), *self.held][: self.frames - 1]
        return pooled

    def reset(self) -> None:
        self.held = []

    def state(self) -> dict:
        """The held rows as JSON-able lists: {"format", "frames": [{field: [...]}, …]} (newest first)."""
        return {"format": FORMAT, "frames": [{f: getattr(d, f).tolist() for f in FIELDS} for d in self.held]}

    def load_state(self, state: dict, who: str) -> None:
        """Restore :meth:`state`; InputError naming ``who`` and the key for anything else (then empty)."""
        self.reset()
        r = StateReader(state, f"{who}.load_state")
        if r.integer("format") != FORMAT:
            raise InputError(f"{who}.load_state: history format {r.data['format']}; expected {FORMAT}")
        frames = r.items("frames")
        if len(frames) > self.frames - 1:
            raise InputError(f"{who}.load_state: frames holds {len(frames)} frames; history_frames = {self.frames} "
                             f"keeps at most {self.frames - 1}")
        held = []
        for i, d in enumerate(frames):
            f = StateReader(d, f"{who}.load_state: frames[{i}]")
            cols = [f.array(k, (None,), np.int8 if k == "label" else np.float64) for k in FIELDS]
            if len({len(c) for c in cols}) != 1:
                raise InputError(f"{f.where}: the fields {FIELDS} have lengths {[len(c) for c in cols]}; expected one")
            if not np.all(cols[2] == LOS):
                raise InputError(f"{f.where}: label holds {sorted(set(cols[2].tolist()))}; expected LOS (0) rows only")
            held.append(Detections(*cols))
        self.held = held
