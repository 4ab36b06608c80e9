"""Bird's-eye-view plotting primitives shared by the figure modules: coordinates, limits, PNG output.

Bird's-eye axes: x forward is up, y left is to the left, as seen from above, so a point (x, y) [m]
is plotted at (−y, x) — a rotation by +90°, which keeps counter-clockwise polygons counter-clockwise.
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from .io import atomic_write_bytes


def bev(points) -> tuple[np.ndarray, np.ndarray]:
    """Plot coordinates (−y, x) [m] of points (…, 2) [m] in the bird's-eye view: x forward is up,
    y left is to the left, as seen from above."""
    p = np.asarray(points, float).reshape(-1, 2)
    return -p[:, 1], p[:, 0]


def save_png(fig, path: str | Path, dpi: int = 110) -> Path:
    """Lay out ``fig``, write it to ``path`` as PNG atomically and close it; returns the path."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
    return Path(path)


def set_bev_limits(ax, points, margin: float = 5.0) -> None:
    """Equal-aspect bird's-eye limits around ``points`` (N, 2) [m] (finite ones) with ``margin`` [m]."""
    p = np.asarray(points, float).reshape(-1, 2)
    p = p[np.isfinite(p).all(1)]
    if not len(p):
        p = np.zeros((1, 2))
    lo, hi = p.min(0) - margin, p.max(0) + margin
    ax.set_xlim(-hi[1], -lo[1])
    ax.set_ylim(lo[0], hi[0])
    ax.set_aspect("equal")
    ax.set_xlabel("−y [m] (right →)")
    ax.set_ylabel("x [m] (forward)")


#: Label of every RA-map azimuth axis (θ = atan2(y, x), DESIGN.md conventions).
AZIMUTH_LABEL = "azimuth θ [deg] (positive = left)"


def orient_azimuth(ax, azimuth_deg) -> None:
    """Put positive azimuth on the LEFT of an RA-map panel's x-axis, as in the bird's-eye view
    (y left is drawn to the left), over the span of ``azimuth_deg`` (any array of azimuths [deg]):
    the x limits run from the largest azimuth to the smallest, whatever was drawn before, and the
    axis is labelled :data:`AZIMUTH_LABEL`. Idempotent (unlike ``invert_xaxis``)."""
    a = np.asarray(azimuth_deg, float)
    ax.set_xlim(float(a.max()), float(a.min()))
    ax.set_xlabel(AZIMUTH_LABEL)


def legend_outside(ax, handles=None, where: str = "right", **kw):
    """A legend placed outside ``ax``'s data area: to its right (``where="right"``, top-aligned) or
    below its tick labels (``"below"``) or above it (``"above"``, under the title); returns it."""
    anchors = {"right": ("upper left", (1.02, 1.0)), "below": ("upper center", (0.5, -0.13)),
               "above": ("lower center", (0.5, 1.01))}
    if where not in anchors:
        from .errors import InputError

        raise InputError(f"legend where={where!r}: expected one of {sorted(anchors)}")
    loc, anchor = anchors[where]
    kw.setdefault("fontsize", 7)
    if where != "right":
        kw.setdefault("ncol", 3)
    if handles is not None:
        kw["handles"] = handles
    return ax.legend(loc=loc, bbox_to_anchor=anchor, borderaxespad=0.0, **kw)
