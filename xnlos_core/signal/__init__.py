"""The shared radar signal chain, from propagation paths to range–azimuth (and range–Doppler) maps.

One chain serves every forward model and every recording:

* :mod:`.antenna` — the array: element and virtual-channel positions [m], element patterns, steering
  vectors, azimuth tapers and coupling.
* :mod:`.chain` — one frame: the dechirped FMCW cube of propagation paths (Eq. 6), thermal noise
  kTB·NF, the windowed range FFT and beamforming onto the azimuth grid (``ra_map_from_cube``).
* :mod:`.doppler` — the slow-time axis: TDM-MIMO chirp sequences of moving paths, range–Doppler
  processing and Doppler-integrated RA maps with a radial velocity per cell (``doppler_ra_maps``),
  in single-precision numba kernels (:mod:`.kernels`).
* :mod:`.elevation` — azimuth–elevation beamforming at one range bin, for arrays with channels at
  several heights.

The names below are the chain's public seam: modules import them from here or from their module,
and no module imports another's private (underscored) name.
"""
from xnlos_core.signal.antenna import (array_response, azimuth_weights, channel_positions, steering_vector,
                                       virtual_layout)
from xnlos_core.signal.chain import (add_noise, adc_to_ra_map, beamform, dechirp, dechirp_paths, noise_floor,
                                     processing_gain, ra_map_from_cube, range_fft, range_taper)
from xnlos_core.signal.doppler import chirp_sequence_cube, doppler_ra_maps, range_doppler, tdm_compensation

__all__ = ["add_noise", "adc_to_ra_map", "array_response", "azimuth_weights", "beamform", "channel_positions",
           "chirp_sequence_cube", "dechirp", "dechirp_paths", "doppler_ra_maps", "noise_floor",
           "processing_gain", "ra_map_from_cube", "range_doppler", "range_fft", "range_taper",
           "steering_vector", "tdm_compensation", "virtual_layout"]
