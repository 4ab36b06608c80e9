"""The one render path of the radar forward models: propagation paths → ADC cube and Frame.

Given the paths a forward model found (:class:`sims.paths.Paths`), :func:`render_paths`

1. applies the ITU-R P.676 gaseous loss over each round trip when the ``atmosphere`` component is on;
2. forms each path's complex amplitude √P·e^{j(arg α + φ)} with the scatterer's random phase φ;
3. dechirps every path with positive power into the ADC cube (:func:`xnlos_core.signal.chain.dechirp`),
   through the radar's coupling matrix only when the ``coupling`` component is on;
4. adds receiver noise (``noise``), forms the RA map (coupling compensated as the radar says);
   with 3-D propagation (``dimensions``, :mod:`sims.ground`; "auto" decided from the scene by
   :func:`sims.dimensions.decide_dimensions`) steps 1–4 run over each path's
   direct and ground-reflected twins, at their arrival elevations;
   with ``doppler`` on, steps 3–4 run over the chirp sequence instead (:func:`render_doppler`);
5. lists as ground truth the LOS and mNLOS paths inside the field of view and range whose RA-map
   SNR reaches ``min_snr_db`` (other multipath is clutter, not ground truth), with the owning
   object of each (``mnlos_object``, ``los_object``: −1 for a wall seen directly).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np

from xnlos_core.signal.doppler import add_chirp_noise, chirp_sequence_cube, doppler_ra_maps
from xnlos_core.metrics import resolution_cell
from xnlos_core.radar import RadarConfig
from sims.scene_truth import image_velocities, point_velocities
from xnlos_core.signal.chain import add_noise, dechirp, ra_map_from_cube
from xnlos_core.types import Frame, GroundTruth, RAMap

from . import ground
from .atmosphere import attenuation_db
from .dimensions import decide_dimensions
from .motion_paths import radial_velocity
from .params import ForwardParams
from .paths import LOS, MNLOS, Paths
from .propagation import ra_snr_db


def render_paths(paths: Paths, scene, radar: RadarConfig, rng: np.random.Generator, params: ForwardParams,
                 use: dict[str, str], *, forward_model: str, walls: Sequence, timestamp: float = 0.0,
                 index: int = 0, cell_snr: bool = False, surface_names: Sequence[str] = (),
                 describe: Callable[[np.ndarray], dict] | None = None) -> tuple[np.ndarray, Frame]:
    """Render ``paths`` of ``scene`` (steps 1–5 of the module doc) into (ADC cube, Frame).

    rng: draws the receiver noise only (the models draw their random phases before). use: the
    components in use, name → "on" or "off: why" (:func:`sims.params.components_needed`).
    walls: the WallSegments the ground truth lists. cell_snr: the ground-truth SNR of a path is
    that of the power of its kind and object summed over its resolution cell (:func:`cell_power`)
    instead of its own. surface_names: names of the static surfaces s of strips with obj = −1 − s
    (an mNLOS strip is owned by ``"wall:<name>"``). describe: extra frame meta from the (P,) mask of
    rendered paths. Returns the noisy ADC cube (n_samples, n_channels) [√W] — with
    ``params.doppler`` the chirp sequence (n_samples, n_chirps, n_channels) — and the Frame at
    ``timestamp`` [s] with its RA map, ground truth and meta.
    """
    dims = decide_dimensions(scene, radar, params, timestamp)
    on3d = dims.use_3d
    use = {**use, "dimensions": dims.label}
    syn, elevation = paths, None  # the paths synthesised: the 2-D ones, or their 3-D twins
    if on3d:
        tw = ground.twins(paths, radar, params.radar_height, params.radar_tilt, scene.ground)
        syn, elevation = tw.paths, tw.elevation
    power, amp = _attenuated(syn, scene, radar, use)
    live = power > 0  # paths behind the array have zero element gain
    amp = np.sqrt(power[live]) * np.exp(1j * syn.phase[live]) if amp is None else amp[live]

    radar_syn = radar
    if use["coupling"] != "on" and radar.has_coupling:
        radar_syn = radar.model_copy(update={"coupling_db": None, "coupling_file": None})
    doppler_meta = {}
    v_r = radial_velocity(paths.pos, _velocity(paths), paths.length)  # range rates [m/s]: the truth's too
    v_syn = v_r[tw.source] if on3d else v_r
    el = None if elevation is None else elevation[live]
    if params.doppler:
        cube, ra, doppler_meta = render_doppler(radar_syn, radar, syn, live, amp, v_syn, rng, params.noise, el)
    else:
        cube = dechirp(radar_syn, syn.length[live], syn.azimuth[live], amp, el)
        if params.noise:
            cube = add_noise(cube, radar_syn, rng)
        ra = ra_map_from_cube(cube, radar)

    if on3d:  # the truth lists each scatterer once, with the power of its twins' carrier sum
        power = _attenuated(paths, scene, radar, use)[0] * tw.gain
        live = paths.power > 0
    snr = ra_snr_db(radar, cell_power(radar, paths, power) if cell_snr else power)
    seen = (live & (snr >= params.min_snr_db) & (np.abs(paths.azimuth) <= radar.field_of_view)
            & (paths.length / 2 <= radar.max_range))
    los, mn = seen & (paths.kind == LOS), seen & (paths.kind == MNLOS)
    names, owner = mnlos_owners([o.name for o in scene.objects], surface_names, paths.obj[mn])
    hidden_velocity = point_velocities(scene, timestamp, paths.obj[mn], paths.hidden[mn])
    gt = GroundTruth(los_points=paths.pos[los], mnlos_points=paths.pos[mn], hidden_points=paths.hidden[mn],
                     mnlos_object=owner, object_names=names, walls=walls,
                     los_snr_db=snr[los], mnlos_snr_db=snr[mn], hidden_velocity=hidden_velocity,
                     mnlos_velocity=image_velocities(paths.hidden[mn], paths.pos[mn], hidden_velocity),
                     los_object=np.where(paths.obj[los] >= 0, paths.obj[los], -1),  # walls: −1
                     los_radial_velocity=v_r[los])
    meta = {"scene": scene.name, "n_paths": int(live.sum()), "n_los_paths": int((live & (paths.kind == LOS)).sum()),
            "n_mnlos_paths": int((live & (paths.kind == MNLOS)).sum()), "forward_model": forward_model,
            **(describe(live) if describe is not None else {}), "components": use}
    if params.doppler:  # ground truth's range rates, row-aligned with los_points / mnlos_points
        meta["doppler"] = {**doppler_meta, "los_radial_velocity": v_r[los], "mnlos_radial_velocity": v_r[mn]}
    return cube, Frame(ra, timestamp=float(timestamp), ground_truth=gt, index=int(index), meta=meta)


def render_doppler(radar_syn: RadarConfig, radar: RadarConfig, paths: Paths, live: np.ndarray, amp: np.ndarray,
                   v_r: np.ndarray, rng: np.random.Generator, noise: bool,
                   elevation: np.ndarray | None = None) -> tuple[np.ndarray, RAMap, dict]:
    """Steps 3–4 with Doppler: chirp sequence of the ``live`` paths moving at range rate ``v_r`` (P,)
    [m/s] (:func:`xnlos_core.signal.doppler.chirp_sequence_cube`, synthesised with ``radar_syn``), per-chirp
    noise from ``rng`` when ``noise``, then :func:`xnlos_core.signal.doppler.doppler_ra_maps` with ``radar``.

    The RA map is ``peak_power``, the strongest Doppler bin of each cell: it keeps the coherent
    gain over the n_chirps chirps, so a mover's SNR is the static one less the Hann window's
    scalloping (≤ 1.42 dB) over a floor ENBW_d (1.76 dB) above the old one, where the coherent mean
    of the snapshot path loses ≈ 18 dB at 1.5 m/s and 28 dB at 5 m/s; ``power`` (Doppler-integrated)
    has no scalloping but sums the noise of every bin, a floor n_chirps (18 dB at 64) higher.
    elevation: arrival elevations of the live paths [rad] (None: 0).
    Returns (cube (n_samples, n_chirps, n_channels) [√W], RAMap with velocity and velocity_std
    maps, meta: map name and its noise-only cell's expected power [W]).
    """
    cube = chirp_sequence_cube(radar_syn, paths.length[live] / 2, paths.azimuth[live], amp, v_r[live],
                               elevation=elevation)
    if noise:
        cube = add_chirp_noise(cube, radar_syn, rng)
    maps = doppler_ra_maps(cube, radar)
    ra = dataclasses.replace(maps.ra_map("peak_power"), velocity=maps.velocity, velocity_std=maps.velocity_std)
    return cube, ra, {"map": "peak_power", "noise_floor": maps.peak_noise_floor}


def _attenuated(paths: Paths, scene, radar: RadarConfig, use: dict[str, str]) -> tuple[np.ndarray, np.ndarray | None]:
    """(power (P,) [W], complex amplitude (P,) [√W] with the random phase, or None) of ``paths`` after
    the gaseous loss over each round trip when the ``atmosphere`` component is on (step 1–2)."""
    power, amp = paths.power, paths.amp
    if amp is not None:
        amp = amp * np.exp(1j * paths.phase)
    if use["atmosphere"] == "on" and len(power):
        conditions = scene.atmosphere.model_dump() if scene.atmosphere is not None else {}
        att = 10 ** (-attenuation_db(radar.carrier_frequency, paths.length, **conditions) / 10)
        power = power * att
        if amp is not None:
            amp = amp * np.sqrt(att)
    return power, amp


def _velocity(paths: Paths) -> np.ndarray:
    """(P, 2) velocity [m/s] of the paths' points, zeros where the model gave none."""
    return np.zeros((len(paths), 2)) if paths.velocity is None else paths.velocity


def mnlos_owners(object_names: Sequence[str], surface_names: Sequence[str],
                 obj: np.ndarray) -> tuple[tuple[str, ...], np.ndarray]:
    """(object_names, (M,) owner index) for mNLOS paths of ``obj`` (object index ≥ 0, or −1 − s for a
    strip of surface s): the scene's objects, then ``"wall:<surface>"`` for each surface seen in a mirror."""
    names = list(object_names)
    surfaces = np.unique(-1 - obj[obj < 0])
    owner = obj.copy()
    for k, s in enumerate(surfaces):
        owner[obj == -1 - s] = len(names) + k
    names += [f"wall:{surface_names[s]}" for s in surfaces]
    return tuple(names), owner


def cell_power(radar: RadarConfig, paths: Paths, power: np.ndarray) -> np.ndarray:
    """(P,) power [W] summed over the paths of the same kind and object that fall into the same
    resolution cell (c/2B in range, the −3 dB beamwidth in azimuth,
    :func:`xnlos_core.metrics.resolution_cell`): the expected power a detector sees of that
    object there (random phases add in power)."""
    if len(power) == 0:
        return power
    dr, da = resolution_cell(radar)
    rb = np.floor(paths.length / 2 / dr).astype(np.int64)
    ab = np.floor(paths.azimuth / da).astype(np.int64)
    inv = _row_groups(np.column_stack([paths.kind, paths.obj, rb, ab]))
    return np.bincount(inv, weights=power)[inv]


def _row_groups(key: np.ndarray) -> np.ndarray:
    """Group label (P,) of each row of the integer key (P, C): equal rows, equal labels.

    Each row is packed into one int64 (mixed radix over the columns' ranges) and the 1-D keys are
    uniqued, ~5× faster than ``np.unique(key, axis=0)`` (a structured sort) for the few hundred
    paths of a map; the grouping is the same, and :func:`cell_power` depends on nothing else
    (``np.bincount`` adds each group's weights in path order whatever the labels). Keys whose
    ranges would overflow int64 take ``np.unique(axis=0)``.
    """
    lo = key.min(axis=0)
    span = [int(s) for s in key.max(axis=0) - lo + 1]
    if np.prod(span, dtype=object) < 2**62:
        flat = np.ravel_multi_index(tuple((key - lo).T), span)
        return np.unique(flat, return_inverse=True)[1].reshape(-1)
    return np.unique(key, axis=0, return_inverse=True)[1].reshape(-1)
