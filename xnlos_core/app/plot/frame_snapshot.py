"""What the animation of a run needs from one frame beyond its results.jsonl record.

``xnlos run`` keeps one small ``.npz`` per frame (``animation/frame_NNNN.npz``) so that the
animation is drawn at the end from files, frame by frame, in bounded memory, and a resumed run
need not recompute frames it has already recorded. The record holds the tracks (with forecasts);
the snapshot holds the imagery: the RA map in dB above its median (float16, ≈ 60 kB a frame for a
240 × 121 map), the detections with their radial velocities (NaN where none), the fitted walls as
polylines, the reconstructed hidden points with their covariances and the ground truth's walls and
hidden points.
"""
from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.app.plot.figures import wall_curve
from xnlos_core.io import atomic_write_bytes


@dataclass(frozen=True)
class FrameSnapshot:
    """One frame for the animation.

    index, timestamp [s]; ra_db (R, A) power above the map's median [dB]; range_axis (R,) [m];
    azimuth_axis (A,) [rad]; det_range (D,) [m], det_azimuth (D,) [rad], det_label (D,) int,
    det_velocity (D,) radial velocity [m/s], NaN where the detector gave none; walls: list of
    (n, 2) [m] polylines of the fitted walls; hidden_mean (H, 2) [m], hidden_cov (H, 2, 2) [m²];
    true_walls (W, 2, 2) [m] start/end; true_hidden (M, 2) [m] (both empty without ground truth).
    """

    index: int
    timestamp: float
    ra_db: np.ndarray
    range_axis: np.ndarray
    azimuth_axis: np.ndarray
    det_range: np.ndarray
    det_azimuth: np.ndarray
    det_label: np.ndarray
    det_velocity: np.ndarray
    walls: list
    hidden_mean: np.ndarray
    hidden_cov: np.ndarray
    true_walls: np.ndarray
    true_hidden: np.ndarray

    @classmethod
    def from_result(cls, result) -> FrameSnapshot:
        """The snapshot of a :class:`xnlos_core.pipeline.FrameResult`."""
        frame, det, h = result.frame, result.detections, result.hidden
        p_db = frame.ra_map.power_db()
        gt = frame.ground_truth
        curves = [c for c in (wall_curve(w) for w in result.walls) if c is not None]
        vel = np.full(len(det), np.nan) if det.velocity is None else np.asarray(det.velocity, float)
        return cls(index=int(frame.index), timestamp=float(frame.timestamp),
                   ra_db=(p_db - np.median(p_db)).astype(np.float16),
                   range_axis=np.asarray(frame.ra_map.range_axis, float),
                   azimuth_axis=np.asarray(frame.ra_map.azimuth_axis, float),
                   det_range=np.asarray(det.range, float), det_azimuth=np.asarray(det.azimuth, float),
                   det_label=np.asarray(det.label, np.int8), det_velocity=vel, walls=curves,
                   hidden_mean=np.asarray(h.mean, float).reshape(-1, 2),
                   hidden_cov=np.asarray(h.cov, float).reshape(-1, 2, 2),
                   true_walls=np.zeros((0, 2, 2)) if gt is None else
                   np.asarray([[w.start, w.end] for w in gt.walls], float).reshape(-1, 2, 2),
                   true_hidden=np.zeros((0, 2)) if gt is None else np.asarray(gt.hidden_points, float).reshape(-1, 2))

    @property
    def det_position(self) -> np.ndarray:
        """(D, 2) [m] detections in Cartesian coordinates (mNLOS: the virtual point o')."""
        return np.column_stack([self.det_range * np.cos(self.det_azimuth), self.det_range * np.sin(self.det_azimuth)])

    def save(self, path: str | Path) -> Path:
        """Write as compressed ``.npz``, atomically; returns the path."""
        lens = [len(c) for c in self.walls]
        arrays = {k: getattr(self, k) for k in ("ra_db", "range_axis", "azimuth_axis", "det_range", "det_azimuth",
                                                "det_label", "det_velocity", "hidden_mean", "hidden_cov",
                                                "true_walls", "true_hidden")}
        buf = io.BytesIO()
        np.savez_compressed(buf, index=self.index, timestamp=self.timestamp,
                            wall_points=np.concatenate(self.walls) if self.walls else np.zeros((0, 2)),
                            wall_lengths=np.asarray(lens, np.int64), **arrays)
        atomic_write_bytes(path, buf.getvalue())
        return Path(path)

    @classmethod
    def load(cls, path: str | Path) -> FrameSnapshot:
        """Read a snapshot written by :meth:`save`; InputError naming the file when it is not one."""
        try:
            with np.load(path, allow_pickle=False) as z:
                d = {k: z[k] for k in z.files}
            splits = np.cumsum(d.pop("wall_lengths"))[:-1]
            walls = [w for w in np.split(d.pop("wall_points"), splits) if len(w)]
            return cls(index=int(d.pop("index")), timestamp=float(d.pop("timestamp")), walls=walls, **d)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise InputError(f"{path}: not an animation frame snapshot ({exc})") from None
