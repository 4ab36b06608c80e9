"""Azimuth–elevation beamforming at one range bin, for layouts whose channels sit at several heights.

The RA map stays (n_range, n_azimuth), beamformed at ε = 0 (:func:`xnlos_core.signal.chain.beamform`).
Where the virtual array has an elevation aperture (a raised transmitter, or ``rx_positions`` /
``tx_positions`` at several z) the channels of one range bin can also be steered in elevation:

    κ(r, θ, ε) = Σ_k w_k a_k*(θ, ε) X_k(r) / Σ_k w_k

with a_k the channel steering vector (:func:`xnlos_core.signal.antenna.steering_vector`) and w_k the
azimuth taper (:func:`xnlos_core.signal.antenna.azimuth_weights`) over every channel, so the ε = 0 row is
the RA map's row at that range bin (unless the map uses one row, ``radar.azimuth_channels = "row"``) and a
unit plane wave from a grid direction gives 1.
"""
from __future__ import annotations

import numpy as np

from xnlos_core.signal.antenna import array_response, azimuth_weights, channel_positions, has_elevation_aperture
from xnlos_core.errors import InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.validation import as_array


def elevation_axis(radar: RadarConfig) -> np.ndarray:
    """Default elevation grid ε [rad], shape (n_azimuth_bins,): uniform over ±field_of_view (the azimuth grid's span)."""
    return radar.azimuth_axis


def azimuth_elevation_spectrum(range_profiles, radar: RadarConfig, range_bin: int, azimuth=None,
                               elevation=None, window: str | None = None) -> np.ndarray:
    """κ(θ, ε) at one range bin, complex128 of shape (n_elevation_dirs, n_azimuth_dirs).

    range_profiles: (n_range, n_channels) complex, the range FFT of a cube (after
    :func:`xnlos_core.signal.chain.decouple` where the radar is calibrated); range_bin: row index;
    azimuth θ, elevation ε [rad]: 1-D grids, default ``radar.azimuth_axis`` and
    :func:`elevation_axis`; window: scipy window name of the taper, default ``radar.azimuth_window``.
    Raises InputError when the channels all sit at one height (no elevation aperture).
    """
    if not has_elevation_aperture(radar):
        raise InputError("azimuth_elevation_spectrum: this radar's channels all sit at one height z, so "
                         "elevation cannot be beamformed; give tx_positions / rx_positions (or "
                         "tx_elevation_offset with MIMO) that place channels at two heights or more")
    x = as_array("range_profiles", range_profiles, dtype=np.complex128, ndim=2)
    if x.shape[1] != radar.n_channels:
        raise InputError(f"range_profiles: expected (n_range, n_channels = {radar.n_channels}), got {x.shape}")
    if not (isinstance(range_bin, (int, np.integer)) and 0 <= range_bin < x.shape[0]):
        raise InputError(f"range_bin: expected an integer in [0, {x.shape[0]}), got {range_bin!r}")
    th = as_array("azimuth", radar.azimuth_axis if azimuth is None else azimuth, ndim=1)
    el = as_array("elevation", elevation_axis(radar) if elevation is None else elevation, ndim=1)
    # every channel, also where the RA map uses one row (azimuth_channels = "row"): heights resolve elevation
    w = azimuth_weights(radar.model_copy(update={"azimuth_channels": "all"}), window)
    grid_th, grid_el = np.meshgrid(th, el)  # (n_el, n_az)
    a = array_response(channel_positions(radar), radar.wavelength, grid_th.ravel(), grid_el.ravel())
    weights = (w / w.sum())[:, None] * a.conj()  # (n_channels, n_dirs), as signal_chain.beam_weights
    return (x[range_bin] @ weights).reshape(grid_th.shape)


def elevation_spectrum(range_profiles, radar: RadarConfig, range_bin: int, azimuth: float,
                       elevation=None, window: str | None = None) -> np.ndarray:
    """κ(ε) at one range bin and one azimuth θ [rad], complex128 of shape (n_elevation_dirs,);
    see :func:`azimuth_elevation_spectrum` (same arguments and errors)."""
    return azimuth_elevation_spectrum(range_profiles, radar, range_bin, [float(azimuth)], elevation, window)[:, 0]
