"""Shared machinery of the scene generators: parameters, object presets, layouts and the draw loop.

A family draws a :class:`Layout` (walls plus the street regions where objects may stand) for a
hidden object on the radar's right; the loop mirrors it to the left when asked, places the hidden
object(s) in the layout's *arms* at ``hidden_distance`` behind the occluding corner, then the extra
objects in its *lanes*, and re-draws (up to ``max_attempts``) until every hidden object is out of
line of sight yet reachable by one specular bounce on a relay wall with its mirror image inside
the field of view, within range and above ``min_snr_db`` (the image method, :mod:`sims.image`).
Sequence families (a ``motion`` and ``visible_share`` / ``hidden_share`` parameters) must moreover
keep that mirror path at ≥ ``visible_share`` of the times 0, STEP, …, ``horizon``
(:meth:`Visibility.share`) and stay out of line of sight at ≥ ``hidden_share`` of them; the
radar of that check is the params' ``radar`` (:meth:`BaseParams.radar_config`), so a dataset on
another radar sets ``[generator_params.radar]`` to its radar's fields. All randomness comes from
``numpy.random.default_rng(seed)`` in a fixed order.
"""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Callable

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.scene import ObjectSpec, Scene, WallSpec

from . import geometry as g
from .params import KINDS, BaseParams, Range, integer, uniform

__all__ = ["KINDS", "STEP", "BaseParams", "Generator", "Layout", "Range", "Region", "Reject", "Surface", "Visibility",
           "block", "draw_body", "draw_object", "draw_surface", "facade", "generate", "integer", "make_object", "times",
           "uniform"]

CLEARANCE = 0.3  # m, free space kept between an object and a wall footprint or another object
RADAR_CLEARANCE = 1.0  # m, free space kept around the radar

# ---- layouts --------------------------------------------------------------------------------
class Reject(Exception):
    """One draw is invalid; the loop draws again. The message is the reason (counted)."""


@dataclass(frozen=True)
class Region:
    """A street area where objects may stand: points origin + a·direction + l·across [m] with
    0 ≤ a ≤ length and lat_min ≤ l ≤ lat_max (direction, across: unit vectors). The lateral room
    is cut further at the first wall met going along ``across`` from the lat_min edge, so that
    edge must lie in free space (a building line, a kerb). ``shadow``: the occluding corner [m];
    objects then stay on the small-lateral side of the ray from the radar through it (hidden)."""

    name: str
    origin: tuple[float, float]
    direction: tuple[float, float]
    across: tuple[float, float]
    length: float
    lat_min: float
    lat_max: float
    shadow: tuple[float, float] | None = None

    def flipped(self) -> "Region":
        """The region mirrored across the x axis (y → −y)."""
        return replace(self, origin=(self.origin[0], -self.origin[1]),
                       direction=(self.direction[0], -self.direction[1]), across=(self.across[0], -self.across[1]),
                       shadow=None if self.shadow is None else (self.shadow[0], -self.shadow[1]))

    def shadow_limit(self, along: float) -> float:
        """Lateral coordinate [m] where the ray radar → ``shadow`` crosses the line at ``along``
        (+inf without a shadow corner or where the ray does not reach that line)."""
        if self.shadow is None:
            return math.inf
        c = np.asarray(self.shadow, float)
        base = np.asarray(self.origin, float) + along * np.asarray(self.direction, float)
        m = np.array([c, -np.asarray(self.across, float)]).T  # t·c − l·across = base
        if abs(np.linalg.det(m)) < 1e-12:
            return math.inf
        t, lat = np.linalg.solve(m, base)
        return float(lat) if t > 0 else math.inf


@dataclass
class Surface:
    """Electromagnetic and size properties shared by the facades of one building."""

    material: str
    roughness: float
    thickness: float | None
    height: float


@dataclass
class Layout:
    """Walls of one draw, hidden-object arms (object i uses arms[i % len]), extra-object lanes, the
    drawn layout values (plain floats, recorded in the scene's meta) and objects the layout itself
    places (e.g. parked cars)."""

    walls: list[WallSpec]
    arms: list[Region]
    lanes: list[Region]
    drawn: dict = field(default_factory=dict)
    fixed: list[ObjectSpec] = field(default_factory=list)

    def flipped(self) -> "Layout":
        walls = [w.model_copy(update={"start": (w.start[0], -w.start[1]), "end": (w.end[0], -w.end[1]),
                                      "radius": None if w.radius is None else -w.radius}) for w in self.walls]
        fixed = [o.model_copy(update={"center": (o.center[0], -o.center[1]), "heading": -o.heading,
                                      "velocity": (o.velocity[0], -o.velocity[1])}) for o in self.fixed]
        return Layout(walls, [a.flipped() for a in self.arms], [a.flipped() for a in self.lanes], dict(self.drawn),
                      fixed)


def draw_surface(rng: np.random.Generator, p: BaseParams, material: str | None = None) -> Surface:
    """One building's facade properties: material (from ``p.materials`` unless given), roughness,
    thickness and height drawn from their intervals."""
    mat = material if material is not None else str(p.materials[int(rng.integers(len(p.materials)))])
    rough = uniform(rng, p.roughness)
    thick = None if p.thickness is None else uniform(rng, p.thickness)
    return Surface(mat, rough, thick, uniform(rng, p.building_height))


def facade(name: str, a, b, s: Surface, radius: float | None = None, facet_length: float = 1.0) -> WallSpec:
    """A relay-capable wall a→b [m] with the surface ``s``."""
    return WallSpec(name=name, start=(float(a[0]), float(a[1])), end=(float(b[0]), float(b[1])),
                    height=s.height, material=s.material, roughness=s.roughness, thickness=s.thickness,
                    radius=radius, facet_length=facet_length)


def block(name: str, corner, dir_a, len_a: float, dir_b, len_b: float, s: Surface,
          chamfer: float = 0.0) -> list[WallSpec]:
    """The two street facades of a building block meeting at ``corner`` [m], running along the unit
    directions dir_a and dir_b for len_a and len_b [m]; a chamfer > 0.1 m cuts the corner by that
    length along both facades and adds the diagonal facade."""
    c = np.asarray(corner, float)
    da, db = np.asarray(dir_a, float), np.asarray(dir_b, float)
    cut = chamfer if chamfer > 0.1 else 0.0
    walls = [facade(f"{name}.a", c + cut * da, c + len_a * da, s), facade(f"{name}.b", c + cut * db, c + len_b * db, s)]
    if cut:
        walls.append(facade(f"{name}.chamfer", c + cut * da, c + cut * db, s))
    return walls


# ---- objects --------------------------------------------------------------------------------
def _wrap(angle: float) -> float:
    return float((angle + math.pi) % (2 * math.pi) - math.pi)


@dataclass(frozen=True)
class Body:
    """A drawn object: class, length, width, height [m], RCS [m²] and speed [m/s] (0: static)."""

    kind: str
    length: float
    width: float
    height: float
    rcs: float
    speed: float


def draw_body(rng: np.random.Generator, p: BaseParams, kind: str | None = None, moving: bool | None = None) -> Body:
    """Class (from ``p.object_kinds`` unless given), size, RCS and speed of one object."""
    if kind is None:
        kind = str(p.object_kinds[int(rng.integers(len(p.object_kinds)))])
    pre = KINDS[kind]
    jit = 1.0 + p.size_jitter * rng.uniform(-1.0, 1.0, 3)
    rcs = uniform(rng, pre.rcs)
    if moving is None:
        moving = bool(rng.random() < p.moving_probability)
    speed = uniform(rng, pre.speed) if moving else 0.0
    return Body(kind, pre.size[0] * float(jit[0]), pre.size[1] * float(jit[1]), pre.height * float(jit[2]), rcs, speed)


def make_object(name: str, b: Body, centre, heading: float) -> ObjectSpec:
    """A box object of body ``b`` at ``centre`` [m] with ``heading`` [rad], moving along its heading."""
    heading = _wrap(heading)
    u = (math.cos(heading), math.sin(heading))
    return ObjectSpec(name=name, shape="box", kind=b.kind, height=float(b.height),
                      center=(float(centre[0]), float(centre[1])), size=(float(b.length), float(b.width)),
                      heading=heading, rcs=float(b.rcs), velocity=(float(b.speed * u[0]), float(b.speed * u[1])))


def draw_object(rng, p: BaseParams, name: str, region: Region, along: float | None, hidden: bool,
                walls: tuple[np.ndarray, np.ndarray, np.ndarray]) -> ObjectSpec | None:
    """An object of a drawn class in ``region`` (at ``along`` [m] or anywhere along it), or None if
    it does not fit across the region."""
    b = draw_body(rng, p)
    base_heading = math.atan2(region.direction[1], region.direction[0])
    if hidden and p.hidden_heading is not None:
        heading = p.hidden_heading
    elif KINDS[b.kind].free_heading:
        heading = float(rng.uniform(-math.pi, math.pi))
    else:
        heading = base_heading + math.pi * int(rng.integers(2)) + float(rng.uniform(-p.heading_jitter,
                                                                                   p.heading_jitter))
    a = float(rng.uniform(0.0, max(region.length, 0.0))) if along is None else along
    lat_u = float(rng.random())
    # lateral room: from the lat_min edge to the first wall (or lat_max), less the object's half extent
    across = np.asarray(region.across, float)
    direction = np.asarray(region.direction, float)
    u = np.array([math.cos(heading), math.sin(heading)])
    v = np.array([-u[1], u[0]])
    half = 0.5 * (b.length * abs(u @ across) + b.width * abs(v @ across))
    half_along = 0.5 * (b.length * abs(u @ direction) + b.width * abs(v @ direction))
    base = np.asarray(region.origin, float) + a * direction
    edge = base + (region.lat_min + 0.01) * across
    room = min(region.lat_max, region.lat_min + 0.01 + g.ray_cast(edge, across, walls[0], walls[1]))
    if hidden:
        room = min(room, region.shadow_limit(a - half_along))
    lo, hi = region.lat_min + half + CLEARANCE, room - half - CLEARANCE
    if hi < lo:
        return None
    return make_object(name, b, base + (lo + lat_u * (hi - lo)) * across, heading)


def clear_of(obj: ObjectSpec, walls, others: list[np.ndarray]) -> str | None:
    """Why ``obj`` may not stand where it is (touching a wall footprint, another object or the
    radar), or None when it is free. Bounding circles skip the exact test for far pairs."""
    poly = g.footprint(obj)
    c = poly.mean(axis=0)
    r = float(np.max(np.linalg.norm(poly - c, axis=1)))
    starts, ends, half = walls
    if len(starts):
        near = g.point_segment_distance(c, starts, ends) < r + half + CLEARANCE
        if near.any() and np.any(g.polygon_segment_distance(poly, starts[near], ends[near]) < half[near] + CLEARANCE):
            return "object inside or against a wall"
    if float(np.linalg.norm(c)) < r + RADAR_CLEARANCE and g.polygon_distance(poly, np.zeros((1, 2))) < RADAR_CLEARANCE:
        return "object on the radar"
    for o in others:
        oc = o.mean(axis=0)
        if np.linalg.norm(oc - c) > r + float(np.max(np.linalg.norm(o - oc, axis=1))) + CLEARANCE:
            continue
        if not g.separated(poly, o, CLEARANCE):
            return "objects overlap"
    return None


class Visibility:
    """Decides whether a mirror path counts for ``radar``: image inside its field of view and range,
    RA-map SNR (:func:`sims.propagation.ra_snr_db`, linear in power, so its 1 W value is cached)."""

    def __init__(self, radar: RadarConfig):
        from sims.propagation import ra_snr_db

        self.radar = radar
        self.snr_1w_db = float(ra_snr_db(radar, 1.0))

    def best(self, scatterers, planar: list[WallSpec], snr: bool = True) -> tuple[float, str | None]:
        """Best SNR [dB] over the mirror paths of ``scatterers`` (points (K, 2), normals (K, 2), RCS
        (K,) [m²]) and the relay wall's name; (−inf, None) without a path, +inf when ``snr`` is False."""
        from sims import walls as wall_em
        from sims.propagation import received_power

        pts, nrm, rcs = scatterers
        radar = self.radar
        parts = []
        for i, idx, img, inc in g.mirror_candidates(pts, nrm, planar):
            r = np.hypot(img[:, 0], img[:, 1])
            th = np.arctan2(img[:, 1], img[:, 0])
            ok = (np.abs(th) <= radar.field_of_view) & (r <= radar.max_range) & (r > 0)
            if ok.any():
                parts.append((i, r[ok], th[ok], rcs[idx][ok], inc[ok]))
        if not parts:
            return -math.inf, None
        if not snr:
            return math.inf, planar[parts[0][0]].name
        alpha = np.concatenate([wall_em.specular_alpha(planar[i], radar, inc) for i, _, _, _, inc in parts])
        r, th, sigma = (np.concatenate([q[k] for q in parts]) for k in (1, 2, 3))
        with np.errstate(divide="ignore"):
            values = 10 * np.log10(received_power(radar, r, th, sigma, alpha)) + self.snr_1w_db
        best = int(np.argmax(values))
        owner = np.concatenate([np.full(len(q[1]), q[0]) for q in parts])
        return float(values[best]), planar[int(owner[best])].name

    def share(self, obj: ObjectSpec, planar: list[WallSpec], ts: np.ndarray, min_snr_db: float | None,
              need: float = 0.0) -> float:
        """Share of the times ``ts`` (T,) [s] at which ``obj`` has a mirror path that counts (in the field
        of view and range, SNR ≥ ``min_snr_db``; None: geometry only), as :meth:`best` at each time.
        Stops early once ``need`` can no longer be met, returning the largest share still possible then
        (below ``need``)."""
        misses_allowed = len(ts) - math.ceil(need * len(ts) - 1e-9)
        misses = 0
        for t in ts:
            snr, relay = self.best(obj.scatterers(float(t)), planar, snr=min_snr_db is not None)
            if relay is None or (min_snr_db is not None and snr < min_snr_db):
                misses += 1
                if misses > misses_allowed:
                    break
        return (len(ts) - misses) / len(ts)


STEP = 0.1  # s, time step at which a moving object's path is checked (one dataset frame_interval)


def times(horizon: float) -> np.ndarray:
    """Check times 0, STEP, …, horizon [s] (T,) (the horizon itself included)."""
    return np.arange(int(math.floor(horizon / STEP + 1e-9)) + 1) * STEP if horizon > 0 else np.zeros(1)


# ---- the draw loop --------------------------------------------------------------------------
@dataclass(frozen=True)
class Generator:
    """A scene family: its name, parameter model, one-line description and layout function
    ``layout(params, rng) -> Layout`` (for a hidden arm on the right; raises Reject). ``motion``
    (optional, sequence families): ``motion(params, obj, arm, rng, walls) -> ObjectSpec`` sets a
    freshly drawn hidden object moving (raises Reject when its path leaves the street); None
    draws nothing, so families without it keep their scenes. ``per_scene`` (optional):
    ``per_scene(params, rng) -> dict`` draws once per scene, before the re-draw loop, what must
    not depend on which draws are rejected (e.g. the motion kind: re-drawing it would favour the
    kinds that pass the checks most easily); ``motion`` then gets it as ``choice=``, and the
    scene's ``meta["drawn"]["per_scene"]`` records it."""

    name: str
    Params: type[BaseParams]
    description: str
    layout: Callable[[BaseParams, np.random.Generator], Layout]
    motion: Callable[..., ObjectSpec] | None = None
    per_scene: Callable[[BaseParams, np.random.Generator], dict] | None = None


PLACEMENTS = 3  # hidden-object placements tried per drawn layout


def _hidden_object(p: BaseParams, i: int, arm: Region, rng, vis: Visibility, walls, planar,
                   polys, motion=None) -> tuple[ObjectSpec, dict]:
    """Hidden object i in ``arm`` (set moving by ``motion``, see Generator): out of line of sight,
    with a mirror path at t = 0 and, for a moving one with ``p.visible_share`` / ``p.hidden_share``,
    with a mirror path / out of line of sight at those shares of the times over ``p.horizon``
    (recorded as ``visible_share``, ``hidden_share``); else Reject."""
    d = uniform(rng, p.hidden_distance)
    if d > arm.length:
        raise Reject(f"hidden_distance beyond the {arm.name} arm")
    o = draw_object(rng, p, f"hidden{i}", arm, d, True, walls)
    if o is None:
        raise Reject("no room across the hidden arm")
    o = o.model_copy(update={"name": f"hidden{i}_{o.kind}"})
    if motion is not None:
        o = motion(p, o, arm, rng, walls)
    why = clear_of(o, walls, polys)
    if why:
        raise Reject(why)
    sc = o.scatterers(0.0)
    if not g.is_hidden(sc[0], walls[0], walls[1]):
        raise Reject("hidden object in line of sight")
    snr, relay = vis.best(sc, planar, snr=p.min_snr_db is not None)
    if relay is None or (p.min_snr_db is not None and snr < p.min_snr_db):
        raise Reject("no mirror path to the hidden object" if relay is None else "mirror path below min_snr_db")
    rec = {"name": o.name, "kind": o.kind, "hidden": True, "region": arm.name, "hidden_distance": d,
           "corner": list(arm.shadow or arm.origin), "arm_direction": list(arm.direction), "relay_wall": relay,
           "mirror_snr_db": round(snr, 3) if math.isfinite(snr) else None}
    share, hidden = getattr(p, "visible_share", None), getattr(p, "hidden_share", None)
    if motion is not None and (share or hidden):
        ts = times(p.horizon)
        seen_hidden = float(np.mean([g.is_hidden(o.scatterers(float(t))[0], walls[0], walls[1]) for t in ts]))
        if hidden and seen_hidden < hidden:
            raise Reject(f"out of line of sight at fewer than hidden_share = {hidden:g} of the times over the horizon")
        seen = vis.share(o, planar, ts, p.min_snr_db, share or 0.0)
        if share and seen < share:
            raise Reject(f"mirror path at fewer than visible_share = {share:g} of the times over the horizon")
        rec["visible_share"], rec["hidden_share"] = seen, seen_hidden
    return o, rec


def _place(p: BaseParams, lay: Layout, rng, vis: Visibility, motion=None) -> tuple[list[ObjectSpec], list[dict]]:
    """The layout's fixed objects, then the hidden objects (each tried PLACEMENTS times), then the
    extra objects; Reject when they do not fit."""
    walls = g.wall_arrays(lay.walls)
    planar = [f for w in lay.walls for f in w.facets()]
    objs: list[ObjectSpec] = []
    polys: list[np.ndarray] = []
    info: list[dict] = []
    for o in lay.fixed:
        why = clear_of(o, walls, polys)
        if why:
            raise Reject(why)
        objs.append(o)
        polys.append(g.footprint(o))
        info.append({"name": o.name, "kind": o.kind, "region": "fixed"})
    for i in range(p.n_hidden):
        arm = lay.arms[i % len(lay.arms)]
        for k in range(PLACEMENTS):
            try:
                o, rec = _hidden_object(p, i, arm, rng, vis, walls, planar, polys, motion)
                break
            except Reject:
                if k == PLACEMENTS - 1:
                    raise
        objs.append(o)
        polys.append(g.footprint(o))
        info.append(rec)
    for j in range(integer(rng, p.n_extra_objects)):
        for _ in range(20):
            lane = lay.lanes[int(rng.integers(len(lay.lanes)))]
            o = draw_object(rng, p, f"object{j}", lane, None, False, walls)
            if o is not None and clear_of(o, walls, polys) is None:
                break
        else:
            raise Reject("no room for the extra objects")
        o = o.model_copy(update={"name": f"object{j}_{o.kind}"})
        objs.append(o)
        polys.append(g.footprint(o))
        info.append({"name": o.name, "kind": o.kind, "region": lane.name})
    for o, rec in zip(objs, info):
        rec.setdefault("hidden", g.is_hidden(o.scatterers(0.0)[0], walls[0], walls[1]))
    return objs, info


def generate(gen: Generator, seed: int, p: BaseParams) -> Scene:
    """Draw layouts and objects from ``default_rng(seed)`` until one is valid (see module doc)."""
    rng = np.random.default_rng(seed)
    vis = Visibility(p.radar_config())
    reasons: Counter = Counter()
    motion, fixed = gen.motion, None
    if gen.per_scene is not None:
        fixed = gen.per_scene(p, rng)
        motion = partial(gen.motion, choice=fixed)
    for attempt in range(1, p.max_attempts + 1):
        side = p.hidden_side if p.hidden_side != "any" else ("right", "left")[int(rng.integers(2))]
        try:
            lay = gen.layout(p, rng)
            if side == "left":
                lay = lay.flipped()
            objects, info = _place(p, lay, rng, vis, motion)
        except Reject as why:
            reasons[str(why)] += 1
            continue
        drawn = {**lay.drawn, "hidden_side": side, "mirrored_y": side == "left", "objects": info}
        if fixed is not None:
            drawn["per_scene"] = fixed
        meta = {"family": gen.name, "seed": int(seed), "attempts": attempt,
                "params": p.model_dump(mode="json", exclude_none=True), "drawn": _plain(drawn)}
        return Scene(name=f"{gen.name}-{seed}", walls=lay.walls, objects=objects, meta=meta)
    top = ", ".join(f"{why} ×{n}" for why, n in reasons.most_common())
    raise InputError(f"scene family {gen.name!r}, seed {seed}: no valid scene in max_attempts = {p.max_attempts} "
                     f"draws (rejected: {top}); widen the parameter intervals (e.g. hidden_distance, the street "
                     "geometry), choose more reflective materials or a stronger radar, or lower min_snr_db")


def _plain(v):
    """Nested dicts/lists of numpy or Python scalars as plain JSON types (floats rounded to 1e-6)."""
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple, np.ndarray)):
        return [_plain(x) for x in v]
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return round(float(v), 6) if math.isfinite(v) else None
    return v
