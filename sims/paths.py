"""Propagation paths: what a forward model finds and :func:`sims.render.render_paths` turns into a Frame.

A forward model's own work ends with the paths (``image``: LOS echoes and one-mirror image paths,
Eq. 3–5; ``raytrace``: SBR-guided chains, :mod:`sims.raytrace.tracer`). Everything after the
geometry — atmosphere, coupling, dechirp, noise, RA map, SNR, ground truth — is shared.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

LOS, MNLOS, OTHER = 0, 1, 2  # path kinds: seen directly, via one relay mirror (Eq. 7 maps it back), other multipath


@dataclass(frozen=True)
class Paths:
    """P propagation paths, one entry per path (all arrays of length P).

    length (P,) float [m]: unfolded ROUND-TRIP length (2|o| direct, 2|o'| mirrored, Eq. 4–5);
    azimuth (P,) float [rad]: arrival azimuth;
    power (P,) float [W]: received power without gaseous loss (:func:`sims.propagation.received_power`);
    amp (P,) complex [√W] or None: complex amplitude with the path's own phase (reflection
    coefficients), without the random ``phase``; None where every amplitude is the real √power
    (image method), formed after the atmosphere from the attenuated power;
    phase (P,) float [rad]: the scatterer's random phase (speckle), shared by every path of a scatterer;
    kind (P,) int: :data:`LOS`, :data:`MNLOS` or :data:`OTHER` (two or more mirrors, mixed legs);
    order (P,) int: specular bounces one way;
    pos (P, 2) float [m]: ground-truth BEV position (the LOS point, or the virtual point o');
    hidden (P, 2) float [m]: the scatterer o itself;
    obj (P,) int: object index ≥ 0, or −1 − s for a wall cell or strip of static surface s;
    centre (P,) int: scattering-centre index within the object, −1 for wall cells and strips;
    velocity (P, 2) float [m/s] or None: horizontal velocity of the point ``pos`` (for a mirrored
    path the virtual scatterer's, (I − 2nnᵀ)v, :func:`sims.motion_paths.mirror_velocity`; for a
    mixed path of raytrace only its range-rate component along ``pos``); None: all static;
    height (P,) float [m] or None: height above the ground of the scatterer whose direct path
    ``length`` is (a vertical wall keeps it on every mirror leg); NaN or None: at the radar's
    mounting height, in its horizontal plane (:mod:`sims.ground` adds the 3-D terms).
    """

    length: np.ndarray
    azimuth: np.ndarray
    power: np.ndarray
    amp: np.ndarray | None
    phase: np.ndarray
    kind: np.ndarray
    order: np.ndarray
    pos: np.ndarray
    hidden: np.ndarray
    obj: np.ndarray
    centre: np.ndarray
    velocity: np.ndarray | None = None
    height: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.length)

    def with_phase(self, phase: np.ndarray) -> Paths:
        """These paths with the random phase (P,) [rad] set (drawn once the paths are known)."""
        return dataclasses.replace(self, phase=np.asarray(phase, dtype=np.float64))


_SCALAR = ("length", "azimuth", "power", "amp", "phase", "kind", "order", "obj", "centre", "height")
_VECTOR = ("pos", "hidden", "velocity")
_INT = ("kind", "order", "obj", "centre")


@dataclass
class PathList:
    """Collects paths group by group (:meth:`add`); :meth:`paths` concatenates them into :class:`Paths`."""

    cols: dict[str, list] = field(default_factory=lambda: {k: [] for k in (*_SCALAR, *_VECTOR)})

    def add(self, *, length, azimuth, power, kind, order, pos, hidden, obj, centre, amp=None, phase=0.0,
            velocity=(0.0, 0.0), height=np.nan) -> None:
        """Append n paths: each column (n,) or a scalar broadcast to n, pos/hidden (n, 2), velocity
        (n, 2) or (2,) broadcast [m/s] (default static), height [m] (default NaN: at the radar's
        height). Give ``amp`` for every group or for none (then :attr:`Paths.amp` is None)."""
        given = dict(length=length, azimuth=azimuth, power=power, amp=amp, phase=phase, kind=kind, order=order,
                     obj=obj, centre=centre, height=height)
        if (amp is None) != (not self.cols["amp"]) and self.cols["length"]:
            raise ValueError("PathList.add: give amp for every group of paths or for none")
        n = len(np.atleast_1d(length))
        for k in _SCALAR:
            if k == "amp" and amp is None:
                continue
            v = np.asarray(given[k])
            self.cols[k].append(np.broadcast_to(v, (n,)) if v.ndim == 0 else v)
        for k, v in (("pos", pos), ("hidden", hidden)):
            self.cols[k].append(np.asarray(v, dtype=np.float64).reshape(n, 2))
        self.cols["velocity"].append(np.broadcast_to(np.asarray(velocity, dtype=np.float64), (n, 2)))

    def paths(self) -> Paths:
        """All paths added so far, concatenated in the order they were added."""
        out = {}
        for k, parts in self.cols.items():
            if parts:
                out[k] = np.concatenate(parts)
            else:
                out[k] = np.zeros((0, 2)) if k in _VECTOR else np.zeros(0)
        for k in _INT:
            out[k] = out[k].astype(np.int64)
        out["phase"] = out["phase"].astype(np.float64)
        out["height"] = out["height"].astype(np.float64)
        if not self.cols["amp"]:
            out["amp"] = None
        return Paths(**out)
