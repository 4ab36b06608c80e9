"""Parameters every radar forward model shares, and which optional components a scene needs.

:class:`ForwardParams` is the base of ``image``'s and ``raytrace``'s ``Params``: receiver noise,
speckle, the ground-truth SNR threshold, wall reflection and the optional components, each
"auto", "on" or "off" (:func:`components_needed` decides "auto"; a frame's
``meta["components"]`` says what was used and why).
"""
from __future__ import annotations

import math
from typing import ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, model_serializer

from xnlos_core.radar import RadarConfig

from .atmosphere import attenuation_db
from .propagation import DETECTABLE_SNR_DB

Switch = Literal["auto", "on", "off"]
COMPONENTS = ("diffuse", "transmission", "atmosphere", "coupling")


class ForwardParams(BaseModel):
    """Shared forward-model parameters (each documented here once)."""

    model_config = ConfigDict(extra="forbid")
    noise: bool = Field(True, description="add receiver thermal noise (radar.noise_power [W] per ADC sample)")
    random_phase: bool = Field(True, description="uniform random phase [rad] per scatterer, wall cell and wall "
                                                 "strip (speckle); off: every phase 0")
    min_snr_db: float = Field(DETECTABLE_SNR_DB, ge=-100, le=200,
                              description="ground truth lists a path only where its RA-map SNR reaches this [dB] "
                                          "(image: the path's own power; raytrace: summed over its resolution "
                                          "cell); default: detectable at pd 0.5, pfa 1e-5")
    reflection: Literal["analytic", "fdtd"] = Field(
        "analytic", description="specular wall reflection coefficient α of material walls: 'analytic' slab "
                                 "formula or the cached FDTD solver ('fdtd', 5° grid)")
    diffuse: Switch = Field("auto", description="diffuse roughness lobe of material walls (LOS echoes); "
                                                "auto: on when a material wall or mesh is rough")
    transmission: Switch = Field("auto", description="direct paths through walls of finite thickness, power "
                                                     "×|T|⁴ per crossed wall; auto: on when the scene has objects "
                                                     "and a finite-thickness material wall")
    atmosphere: Switch = Field("auto", description="ITU-R P.676 gaseous loss over each round trip; auto: on when "
                                                   "the scene declares an atmosphere whose loss over 2·max_range "
                                                   "reaches tolerance_db")
    coupling: Switch = Field("auto", description="the radar's mutual-coupling matrix mixes the channels; auto: on "
                                                 "when the radar has one")
    doppler: bool = Field(False, description="render the chirp sequence (n_chirps loops of TDM chirps, timing "
                                             "from the radar [s]) with each path's radial velocity [m/s] and "
                                             "form the RA map by Doppler processing (peak Doppler bin per cell, "
                                             "with velocity [m/s] and σ maps); off: one snapshot chirp, movers "
                                             "frozen at the frame's timestamp")
    tolerance_db: float = Field(0.1, ge=0, le=60, description="'auto' leaves out a loss term whose largest "
                                                              "effect stays below this [dB]")
    diffuse_nlos: Switch = Field(
        "auto", description="three-bounce diffuse NLOS path via rough relay walls (sims.diffuse_nlos); auto: "
                            "on when a relay material wall is mostly diffuse at the carrier (ρ_s(0) < 1/2)")
    diffuse_nlos_cell: float = Field(1.0, ge=0.05, le=10, description="wall cell length [m] of the diffuse "
                                                                     "NLOS path (pairs of cells: cost ∝ 1/cell²)")
    diffuse_nlos_floor_db: float = Field(
        -20.0, ge=-300, le=0, description="importance cut of the diffuse NLOS pairs: the weakest pairs are left "
                                          "out while their summed power stays below this RA-map SNR [dB] "
                                          "(sims.diffuse_nlos.wall_paths); -300 keeps every pair")
    diffuse_nlos_max_paths: int = Field(
        20000, ge=1, le=10_000_000, description="at most this many diffuse NLOS paths per frame (the strongest "
                                                 "pairs; the power left out is in meta['components'])")

    dimensions: Literal["auto", "2d", "3d"] = Field(
        "auto", description="'2d': every path in the radar's horizontal plane, no ground; '3d': the elevation "
                            "pattern at each path's elevation (radar_height, radar_tilt, scatterer heights) and "
                            "the ground-reflected twins of every path when the scene has a ground "
                            "(sims.ground); auto: 3d where, by a closed-form estimate from the scene, those terms "
                            "change some scatterer's response by more than tolerance_db over the scene's range span "
                            "(sims.dimensions)")
    radar_height: float = Field(0.75, gt=0, le=100, description="antenna mounting height above ground [m]")
    radar_tilt: float = Field(0.0, ge=-math.pi / 2, le=math.pi / 2,
                              description="elevation of the antenna boresight [rad], positive up (3-D only)")

    #: fields a subclass had before they moved here: always serialised (their old digests kept them)
    dump_always: ClassVar[frozenset[str]] = frozenset()

    @model_serializer(mode="wrap")
    def _omit_late_defaults(self, handler):
        # fields that arrived after dataset digests existed are left out at their defaults, so those
        # digests stay the same
        data = handler(self)
        if isinstance(data, dict):
            for key, default in LATE_DEFAULTS.items():
                if key in data and data[key] == default and key not in self.dump_always:
                    del data[key]
        return data


#: Parameters added after dataset digests existed, left out of serialised configs at these defaults.
LATE_DEFAULTS = {"doppler": False, "diffuse_nlos": "auto", "diffuse_nlos_cell": 1.0, "diffuse_nlos_floor_db": -20.0,
                 "diffuse_nlos_max_paths": 20000, "dimensions": "auto", "radar_height": 0.75, "radar_tilt": 0.0}


def components_needed(p: ForwardParams, scene, radar: RadarConfig) -> dict[str, str]:
    """Decide the optional components (module doc) from switches ``p`` (fields named as
    COMPONENTS, each "auto"/"on"/"off", and tolerance_db): name → "on" or "off: reason"."""
    mat = [w for w in scene.walls if w.material is not None]
    need = {
        "diffuse": (any(w.roughness > 0 for w in mat)
                    or any(m.roughness > 0 and (m.material or m.materials) for m in scene.meshes),
                    "no rough material wall"),
        "transmission": (bool(scene.objects) and any(w.thickness is not None for w in mat),
                         "no object and finite-thickness material wall"),
        "coupling": (radar.has_coupling, "radar has no coupling matrix"),
    }
    if scene.atmosphere is None:
        need["atmosphere"] = (False, "scene declares no atmosphere")
    else:
        worst = float(attenuation_db(radar.carrier_frequency, 2 * radar.max_range, **scene.atmosphere.model_dump()))
        need["atmosphere"] = (worst >= p.tolerance_db,
                              f"≤ {worst:.3g} dB over the longest round trip < tolerance {p.tolerance_db} dB")
    out = {}
    for name in COMPONENTS:
        switch = getattr(p, name)
        on, why = need[name]
        out[name] = "on" if switch == "on" or (switch == "auto" and on) else (
            "off: switched off" if switch == "off" else f"off: {why}")
    return out
