"""A 3-D view of a scene: walls as vertical faces of their heights, objects as boxes, the ground
plane, the radar at its mounting height and, optionally, propagation paths as polylines.

Coordinates are the ego frame (DESIGN conventions): radar at the origin of the plan, x along
boresight, y to the left, z up from the ground [m].
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from xnlos_core.app.plot import palette
from xnlos_core.bev import save_png
from xnlos_core.errors import InputError

#: Mounting height of the radar above the ground [m] when none is given: the forward models'
#: default ``radar_height``.
DEFAULT_RADAR_HEIGHT = 0.75
#: Margin [m] of the ground plane around everything drawn on it.
GROUND_MARGIN = 5.0
WALL_COLOUR = "0.55"
GROUND_COLOUR = "tan"
MESH_COLOUR = "lightsteelblue"
PATH_COLOUR = "tab:red"


@dataclass
class Scene3DArtists:
    """What :func:`draw_scene_3d` added to the axes.

    ``walls``: one Poly3DCollection per planar wall piece (a curved wall gives one per facet), a
    single quad (start, 0) → (end, 0) → (end, h) → (start, h); ``objects``: one Poly3DCollection
    per box (its 6 faces) or a marker per point object; ``centres``: one marker per object at its
    scattering-centre height; ``ground``: the ground quad or None; ``radar``: the radar marker;
    ``paths``: one line per path; ``meshes``: one Poly3DCollection per mesh given.
    """

    walls: list = field(default_factory=list)
    objects: list = field(default_factory=list)
    centres: list = field(default_factory=list)
    ground: object | None = None
    radar: object | None = None
    paths: list = field(default_factory=list)
    meshes: list = field(default_factory=list)


def wall_quad(start, end, height: float) -> np.ndarray:
    """(4, 3) [m] corners of a vertical wall face from plan points ``start`` and ``end`` (2,) [m]
    up to ``height`` [m]: start and end on the ground, then end and start at the top."""
    (x0, y0), (x1, y1) = np.asarray(start, float), np.asarray(end, float)
    return np.array([[x0, y0, 0.0], [x1, y1, 0.0], [x1, y1, height], [x0, y0, height]])


def box_faces(footprint, height: float) -> list[np.ndarray]:
    """The 6 faces (each (4, 3) [m]) of a prism over a 4-corner plan ``footprint`` (4, 2) [m]
    from the ground to ``height`` [m]: the 4 sides, then bottom and top."""
    f = np.asarray(footprint, float).reshape(4, 2)
    sides = [wall_quad(f[i], f[(i + 1) % 4], height) for i in range(4)]
    bottom = np.column_stack([f, np.zeros(4)])
    top = np.column_stack([f, np.full(4, height)])
    return sides + [bottom, top]


def centre_height(obj, radar_height: float) -> float:
    """Height [m] of an object's scattering centres: ``centre_height`` when set, else the radar's
    mounting height capped at the object's height (as ObjectSpec documents)."""
    return obj.centre_height if obj.centre_height is not None else min(radar_height, obj.height)


def _check_paths(paths) -> list[np.ndarray]:
    out = []
    for i, p in enumerate(paths):
        a = np.asarray(p, float)
        if a.ndim != 2 or a.shape[1] != 3 or len(a) < 2 or not np.isfinite(a).all():
            raise InputError(f"paths[{i}]: expected a (K, 3) array of finite points [m] with K >= 2, "
                             f"got shape {a.shape}" + ("" if a.ndim != 2 or np.isfinite(a).all() else " with non-finite values"))
        out.append(a)
    return out


def _mesh_arrays(meshes) -> list[tuple[np.ndarray, np.ndarray]]:
    out = []
    for i, m in enumerate(meshes):
        v, f = (m.vertices, m.faces) if hasattr(m, "vertices") else m
        v, f = np.asarray(v, float), np.asarray(f)
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or not len(f):
            raise InputError(f"meshes[{i}]: expected a trimesh or (vertices (V, 3), faces (F, 3)), "
                             f"got vertices {v.shape} and faces {f.shape}")
        out.append((v, f))
    return out


def draw_scene_3d(ax, scene, radar_height: float = DEFAULT_RADAR_HEIGHT, paths=None, meshes=None,
                  t: float = 0.0, path_labels=None) -> Scene3DArtists:
    """Draw ``scene`` (:class:`xnlos_core.scene.Scene`) on the 3-D axes ``ax`` (``projection="3d"``).

    Each planar wall piece becomes a translucent vertical quad of the wall's ``height`` [m]; each
    object a box over its footprint at time ``t`` [s] up to its ``height`` (a point object a
    marker), with a marker at its scattering-centre height (:func:`centre_height`); the ground
    plane z = 0 when ``scene.ground`` is set; the radar a marker at (0, 0, ``radar_height``) [m].
    ``paths``: propagation paths, each a (K, 3) [m] polyline in the ego frame (e.g. radar →
    wall → object → wall → radar). ``meshes``: placed meshes to draw (trimesh objects or
    (vertices (V, 3) [m], faces (F, 3)) pairs); a scene's mesh files are not read here, so a
    caller that has them loaded passes them. Sets the axes' limits (equal scale on x, y, z) and
    labels; the view angle is the caller's. Returns the artists (:class:`Scene3DArtists`).
    """
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    if not (isinstance(radar_height, (int, float)) and math.isfinite(radar_height) and radar_height >= 0):
        raise InputError(f"radar_height: expected a finite height above the ground >= 0 [m], got {radar_height!r}")
    paths = _check_paths(paths or [])
    meshes = _mesh_arrays(meshes or [])
    if path_labels is not None and len(path_labels) != len(paths):
        raise InputError(f"path_labels: expected one label per path ({len(paths)}), got {len(path_labels)}")
    art = Scene3DArtists()
    extent = [np.array([[0.0, 0.0, 0.0], [0.0, 0.0, radar_height]])]

    for i, w in enumerate(scene.planar_walls()):
        quad = wall_quad(w.start, w.end, w.height)
        pc = Poly3DCollection([quad], facecolor=WALL_COLOUR, edgecolor="0.3", alpha=0.35, linewidths=0.8,
                              label="walls" if i == 0 else None)
        pc.set_gid(w.name)
        art.walls.append(ax.add_collection3d(pc) or pc)
        extent.append(quad)

    for i, obj in enumerate(scene.objects):
        foot = obj.footprint(t)
        zc = centre_height(obj, radar_height)
        if len(foot) == 4:
            faces = box_faces(foot, obj.height)
            pc = Poly3DCollection(faces, facecolor=palette.TRUTH, edgecolor="darkgreen", alpha=0.45,
                                  linewidths=0.6, label="objects" if i == 0 else None)
            pc.set_gid(obj.name)
            art.objects.append(ax.add_collection3d(pc) or pc)
            extent.extend(faces)
        else:
            (m,) = ax.plot([foot[0, 0]], [foot[0, 1]], [zc], "o", color=palette.TRUTH, ms=7,
                           label="objects" if i == 0 else None, gid=obj.name)
            art.objects.append(m)
            extent.append(np.array([[foot[0, 0], foot[0, 1], obj.height]]))
        c = foot.mean(0)
        (m,) = ax.plot([c[0]], [c[1]], [zc], "x", color="darkgreen", ms=6, gid=obj.name,
                       label="scattering centres" if i == 0 else None)
        art.centres.append(m)

    for i, (v, f) in enumerate(meshes):
        pc = Poly3DCollection(v[f], facecolor=MESH_COLOUR, edgecolor="none", alpha=0.4,
                              label="meshes" if i == 0 else None)
        art.meshes.append(ax.add_collection3d(pc) or pc)
        extent.append(v)

    for i, p in enumerate(paths):
        label = path_labels[i] if path_labels is not None else ("paths" if i == 0 else None)
        (line,) = ax.plot(p[:, 0], p[:, 1], p[:, 2], color=PATH_COLOUR, lw=1.2, alpha=0.8, label=label)
        art.paths.append(line)
        extent.append(p)

    (art.radar,) = ax.plot([0.0], [0.0], [radar_height], "^", color="k", ms=9, label="radar",
                           zorder=palette.Z_RADAR)
    ax.plot([0.0, 0.0], [0.0, 0.0], [0.0, radar_height], color="k", lw=1.0, ls=":")

    pts = np.concatenate([np.asarray(e, float).reshape(-1, 3) for e in extent])
    lo, hi = pts.min(0), pts.max(0)
    if scene.ground is not None:
        x0, y0 = lo[:2] - GROUND_MARGIN
        x1, y1 = hi[:2] + GROUND_MARGIN
        quad = np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])
        pc = Poly3DCollection([quad], facecolor=GROUND_COLOUR, edgecolor="none", alpha=0.25, label="ground")
        art.ground = ax.add_collection3d(pc) or pc
        lo, hi = np.minimum(lo, quad.min(0)), np.maximum(hi, quad.max(0))
    _equal_limits(ax, lo, hi)
    ax.set_xlabel("x [m] (forward)")
    ax.set_ylabel("y [m] (left)")
    ax.set_zlabel("z [m] (up)")
    return art


def _equal_limits(ax, lo: np.ndarray, hi: np.ndarray) -> None:
    # one metre is as long on every axis, so heights are seen against plan distances
    span = np.maximum(hi - lo, 1.0)
    ax.set_xlim(lo[0], lo[0] + span[0])
    ax.set_ylim(lo[1], lo[1] + span[1])
    ax.set_zlim(min(lo[2], 0.0), min(lo[2], 0.0) + span[2])
    ax.set_box_aspect(tuple(span))


def scene_3d_figure(scene, path: str | Path, radar_height: float = DEFAULT_RADAR_HEIGHT, paths=None,
                    meshes=None, t: float = 0.0, elev: float = 30.0, azim: float = -135.0,
                    title: str | None = None, dpi: int = 110) -> Path:
    """Write the 3-D view of ``scene`` (:func:`draw_scene_3d`) to ``path`` as PNG, atomically,
    seen from elevation ``elev`` and azimuth ``azim`` [deg] (matplotlib's view angles; the default
    looks from behind and above the radar). Returns the path."""
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(8, 6.5))
    ax = fig.add_subplot(projection="3d")
    draw_scene_3d(ax, scene, radar_height=radar_height, paths=paths, meshes=meshes, t=t)
    ax.view_init(elev=elev, azim=azim)
    ax.set_title(title if title is not None else f"{scene.name}: radar at {radar_height:g} m")
    ax.legend(loc="upper left", fontsize=8)
    return save_png(fig, path, dpi=dpi)
