"""Raw ADC cubes as radars deliver them → RA maps through the one shared signal chain.

Hardware hands over samples × chirps × channels in some axis order, as complex numbers or as
integer I/Q pairs, with channels tx-major or rx-major and a scale from ADC counts to √W. An
:class:`AdcLayout` describes that; :func:`adc_cube_to_ra_map` brings the cube into the canonical
(n_samples, n_channels) complex √W form (chirps integrated coherently) and runs
:func:`xnlos_core.signal.chain.ra_map_from_cube` — the same code the simulator uses;
:func:`adc_cube_to_doppler_maps` keeps the chirps and runs the Doppler chain of
:mod:`xnlos_core.signal.doppler` (movers keep their SNR, every cell gets a radial velocity).
:func:`encode_adc_cube` is the inverse (simulator or emulator → raw layout), with int16 clipping.
"""
from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from xnlos_core.signal.doppler import DopplerRAMaps, doppler_ra_maps
from xnlos_core.errors import InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.signal.chain import ra_map_from_cube
from xnlos_core.types import RAMap

AXES = ("sample", "chirp", "channel")


class AdcLayout(BaseModel):
    """How a raw ADC cube is laid out in memory.

    axes: the array's axes in order, a permutation of ("sample", "chirp", "channel") or of
    ("sample", "channel") for a single chirp; sample_format: "complex" (complex dtype) or "iq"
    (a trailing axis of length 2 holding I then Q, any integer or float dtype);
    channel_order: "tx_major" (channel = i_tx·n_rx + j_rx, as xnlos uses) or "rx_major"
    (j_rx·n_tx + i_tx), ignored without MIMO; scale: √W per ADC count (amplitude);
    remove_dc: subtract each channel's mean over the samples of a chirp (DC/LO leakage).
    Chirps are averaged coherently (static scene within one frame).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)
    axes: tuple[str, ...] = ("sample", "chirp", "channel")
    sample_format: Literal["complex", "iq"] = "complex"
    channel_order: Literal["tx_major", "rx_major"] = "tx_major"
    scale: float = Field(1.0, gt=0, description="amplitude per ADC count [√W]")
    remove_dc: bool = False

    @field_validator("axes")
    @classmethod
    def _axes(cls, v):
        if sorted(v) not in (sorted(AXES), ["channel", "sample"]):
            raise ValueError(f"axes must be a permutation of {AXES} or of ('sample', 'channel'), got {v}")
        return v


def _channel_permutation(radar: RadarConfig, order: str) -> np.ndarray | None:
    """Index array taking rx-major channels to tx-major, or None when nothing to do."""
    if order == "tx_major" or not radar.mimo:
        return None
    i_tx, j_rx = np.divmod(np.arange(radar.n_channels), radar.n_rx)  # tx-major target index
    return j_rx * radar.n_tx + i_tx


def chirp_cube(raw, layout: AdcLayout, radar: RadarConfig) -> np.ndarray:
    """Raw cube → (n_samples, n_chirps_recorded, n_channels) complex128 [√W], chirps kept in slow time:
    validate, reorder (axes, channel order), scale, optional DC removal. The layout of
    :mod:`xnlos_core.signal.doppler`'s chirp-sequence cubes, so real recordings take the same Doppler path.

    Raises InputError naming the mismatch (axis count, I/Q axis, sizes, dtype, non-finite values).
    """
    arr = np.asarray(raw)
    n_ax = len(layout.axes) + (layout.sample_format == "iq")
    if arr.ndim != n_ax:
        raise InputError(f"adc cube: layout axes {layout.axes}"
                         f"{' + I/Q' if layout.sample_format == 'iq' else ''} need {n_ax} dimensions, "
                         f"got shape {arr.shape}")
    if layout.sample_format == "iq":
        if arr.shape[-1] != 2 or not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
            raise InputError(f"adc cube: sample_format 'iq' expects a real array with a trailing axis of 2 "
                             f"(I, Q), got shape {arr.shape} dtype {arr.dtype}")
        arr = arr[..., 0].astype(np.float64) + 1j * arr[..., 1].astype(np.float64)
    elif not np.issubdtype(arr.dtype, np.complexfloating):
        raise InputError(f"adc cube: sample_format 'complex' expects a complex array, got dtype {arr.dtype}")
    axes = list(layout.axes)
    if "chirp" not in axes:
        arr, axes = arr[..., None], axes + ["chirp"]
    arr = np.transpose(arr, [axes.index(a) for a in ("sample", "chirp", "channel")])
    want = {"sample": radar.n_samples, "channel": radar.n_channels}
    for k, name in ((0, "sample"), (2, "channel")):
        if arr.shape[k] != want[name]:
            raise InputError(f"adc cube: the '{name}' axis has {arr.shape[k]} entries, this radar expects "
                             f"{want[name]} (n_samples={radar.n_samples}, n_channels={radar.n_channels})")
    if arr.shape[1] < 1:
        raise InputError("adc cube: the 'chirp' axis is empty")
    # a new array (the I/Q path built one already), so it is scaled in place
    cube = arr.astype(np.complex128, copy=layout.sample_format != "iq")
    if layout.scale != 1:
        cube *= layout.scale
    if not np.all(np.isfinite(cube)):
        raise InputError("adc cube: contains NaN or infinite samples")
    perm = _channel_permutation(radar, layout.channel_order)
    if perm is not None:
        cube = cube[:, :, perm]
    if layout.remove_dc:
        cube = cube - cube.mean(axis=0, keepdims=True)
    return cube


def canonical_cube(raw, layout: AdcLayout, radar: RadarConfig) -> np.ndarray:
    """Raw cube → (n_samples, n_channels) complex128 [√W]: :func:`chirp_cube`, chirps integrated coherently."""
    return chirp_cube(raw, layout, radar).mean(axis=1)


def adc_cube_to_ra_map(raw, layout: AdcLayout, radar: RadarConfig) -> RAMap:
    """Raw ADC cube in ``layout`` → RAMap via the shared chain (range FFT, decoupling, beamforming)."""
    return ra_map_from_cube(canonical_cube(raw, layout, radar), radar)


def adc_cube_to_doppler_maps(raw, layout: AdcLayout, radar: RadarConfig, *, window: str = "hann",
                             remove_static: bool = False, workers: int | None = None) -> DopplerRAMaps:
    """Raw ADC cube of one frame's chirp sequence → :class:`xnlos_core.signal.doppler.DopplerRAMaps` (range–Doppler,
    beamforming per Doppler bin, velocity per cell) through the chain the simulator's Doppler model uses.

    The recording must hold ``radar.n_chirps`` chirp loops (one chirp per TX each, TDM order as the
    radar's timing fields describe); raises InputError otherwise. workers: FFT threads
    (:func:`xnlos_core.signal.doppler.doppler_ra_maps`).
    """
    cube = chirp_cube(raw, layout, radar)
    if cube.shape[1] != radar.n_chirps:
        raise InputError(f"adc cube: Doppler processing needs the radar's n_chirps={radar.n_chirps} chirp loops "
                         f"on the 'chirp' axis, the recording has {cube.shape[1]}")
    return doppler_ra_maps(cube, radar, window=window, remove_static=remove_static, workers=workers)


def encode_adc_cube(cube, layout: AdcLayout, radar: RadarConfig, n_chirps: int = 1,
                    dtype=np.int16) -> tuple[np.ndarray, int]:
    """Canonical (n_samples, n_channels) √W cube → raw array in ``layout`` (the chirp repeated
    ``n_chirps`` times), and the number of clipped values.

    For "iq" the values are cube/scale rounded to ``dtype`` (integer dtypes clip at their limits;
    clipping is counted, never silent); for "complex" ``dtype`` must be complex (default complex64
    is used when an integer dtype is given).
    """
    c = np.asarray(cube, dtype=np.complex128)
    if c.shape != (radar.n_samples, radar.n_channels):
        raise InputError(f"encode_adc_cube: cube must be (n_samples, n_channels) = "
                         f"{(radar.n_samples, radar.n_channels)}, got {c.shape}")
    perm = _channel_permutation(radar, layout.channel_order)
    if perm is not None:
        c = c[:, np.argsort(perm)]
    c = np.repeat((c / layout.scale)[:, None, :], n_chirps, axis=1)  # (sample, chirp, channel)
    axes = list(layout.axes) if "chirp" in layout.axes else list(layout.axes) + ["chirp"]
    c = np.transpose(c, [("sample", "chirp", "channel").index(a) for a in axes])
    if "chirp" not in layout.axes:
        c = c[..., 0]
    clipped = 0
    if layout.sample_format == "iq":
        iq = np.stack([c.real, c.imag], axis=-1)
        if np.issubdtype(np.dtype(dtype), np.integer):
            info = np.iinfo(dtype)
            iq = np.rint(iq)
            clipped = int(np.count_nonzero((iq < info.min) | (iq > info.max)))
            iq = np.clip(iq, info.min, info.max)
        return iq.astype(dtype), clipped
    out_dtype = dtype if np.issubdtype(np.dtype(dtype), np.complexfloating) else np.complex64
    return c.astype(out_dtype), clipped
