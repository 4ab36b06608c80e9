"""Radar configuration: FMCW waveform, MIMO array and receiver (paper Sec. 3.2, Table 1).

All quantities are SI (Hz, s, W, m, rad) unless the field name says dB.
"""
from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_serializer, model_validator

from .errors import ConfigError
from .files import load_toml, resolve_config_path
from .validation import validate_model

SPEED_OF_LIGHT = 299_792_458.0  # m/s
BOLTZMANN = 1.380_649e-23  # J/K
OVERLAP_TOLERANCE = 1e-6  # [wavelengths]: two elements of one array closer than this are one place
RANGE_BIN_TOLERANCE = 1e-9  # [bins]: max_range within this of a bin centre includes that bin (n_range_bins)
MIN_HALF_FOV = math.radians(1.0)  # [rad]: a narrower azimuth grid (5e-324 …) is a mistake, not a radar

# one element's (y, z) in wavelengths: y along the array (azimuth), z up (elevation)
_Coordinate = Annotated[float, Field(ge=-1000, le=1000, allow_inf_nan=False)]
ElementPositions = tuple[tuple[_Coordinate, _Coordinate], ...]


class RadarConfig(BaseModel):
    """An FMCW radar with a MIMO array in the ego y–z plane: uniform rows along y by default, or any
    layout given element by element (``tx_positions``, ``rx_positions``).

    The default is the X-band configuration of DESIGN.md: 10 GHz carrier, 600 MHz sweep
    (range resolution c/2B = 0.25 m), 512 complex samples per chirp (unambiguous range
    N·c/2B = 128 m, cropped to ``max_range``), 4 TX × 8 RX at λ/2 forming a filled 32-element
    virtual array (≈ 3.6° first-null half width, ≈ 4° resolution with the Taylor window).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    carrier_frequency: float = Field(10e9, gt=1e8, le=3e11, description="f_c [Hz]")
    bandwidth: float = Field(600e6, gt=1e6, le=1e10, description="sweep bandwidth B [Hz]")
    chirp_duration: float = Field(100e-6, gt=1e-7, le=1e-2, description="sweep time T [s]")
    n_samples: int = Field(512, ge=16, le=16384, description="complex ADC samples per chirp")
    n_chirps: int = Field(64, ge=1, le=4096, description="chirps per transmitter averaged coherently into one "
                                                        "frame's ADC cube (static scene: noise power ÷ n_chirps)")
    transmit_power: float = Field(1.6e-3, gt=0, le=1e3, description="power per transmitter [W]")
    noise_figure_db: float = Field(10.0, ge=0, le=40, description="receiver noise figure [dB]")
    temperature: float = Field(290.0, gt=0, le=1000, description="noise temperature [K]")
    system_loss_db: float = Field(3.0, ge=0, le=60, description="cable/processing losses [dB]")
    n_tx: int = Field(4, ge=1, le=64)
    n_rx: int = Field(8, ge=1, le=256)
    rx_spacing: float = Field(0.5, gt=0, le=10, description="RX element spacing [wavelengths]")
    tx_spacing: float | None = Field(
        None, gt=0, le=1000, description="TX spacing [wavelengths]; default n_rx·rx_spacing (filled virtual ULA)"
    )
    tx_elevation_offset: float = Field(
        0.0, ge=-100, le=100, description="height of the TX row above the RX row [wavelengths] (planar layout)")
    # any antenna layout. Unset (None) keeps the uniform rows above and is left out of
    # the serialised config, so existing configs keep their JSON and digest.
    tx_positions: ElementPositions | None = Field(
        None, min_length=1, max_length=64,
        description="TX element positions [[y, z], …] [wavelengths], y along the array (ego y, azimuth), "
                    "z up (elevation), in the same board frame as rx_positions; replaces the uniform TX "
                    "row (tx_spacing, tx_elevation_offset); n_tx is derived from it")
    rx_positions: ElementPositions | None = Field(
        None, min_length=1, max_length=256,
        description="RX element positions [[y, z], …] [wavelengths], same frame as tx_positions; replaces "
                    "the uniform RX row; n_rx is derived from it and rx_spacing (the coupling model's "
                    "neighbour distance) from its smallest element separation")
    mimo: bool = Field(True, description="MIMO virtual array (TX time-multiplexed, n_tx·n_rx channels); "
                                         "False: the TX elements radiate together as one beam steered to "
                                         "tx_steering and only the n_rx RX channels are recorded")
    tx_steering: float = Field(0.0, ge=-math.pi / 2, le=math.pi / 2,
                               description="θ_t [rad]: TX beam direction when mimo = False")
    element_gain_dbi: float = Field(6.0, ge=-10, le=30, description="patch element boresight gain [dBi]")
    element_pattern_exponent: float = Field(
        1.2, ge=0, le=20, description="q in the element power pattern cos(θ)^q (azimuth plane)"
    )
    element_pattern_exponent_el: float = Field(
        1.2, ge=0, le=20, description="q_el in the element power pattern cos(ε)^q_el (elevation plane)"
    )
    n_elevation: int = Field(1, ge=1, le=64, description="patches per element column (fixed broadside "
                                                        "elevation sub-array); raises gain, narrows elevation")
    elevation_spacing: float = Field(0.5, gt=0, le=10, description="patch spacing in a column [wavelengths]")
    polarization: Literal["V", "H"] = Field(
        "V", description="E-field polarisation: V is TE (s) on vertical walls, H is TM (p)")
    coupling_db: float | None = Field(
        None, ge=-100, le=-3, description="modelled mutual coupling between adjacent RX (and TX) elements "
                                          "[dB]; None: no coupling unless coupling_file is given")
    coupling_phase: float = Field(0.0, ge=-2 * math.pi, le=2 * math.pi,
                                  description="phase of the adjacent-element coupling coefficient [rad]")
    coupling_file: str | None = Field(
        None, description="measured coupling matrix (.npy/.npz key 'coupling' or .csv of complex), "
                          "shape (n_channels, n_channels); replaces the modelled one")
    coupling_compensation: bool = Field(
        False, description="the signal chain undoes the coupling (C⁻¹) before beamforming (calibrated radar)")
    field_of_view: float = Field(math.radians(60), ge=MIN_HALF_FOV, lt=math.pi / 2,
                                 description="half FOV [rad]: the azimuth grid spans ±field_of_view; "
                                             "1° (0.01745 rad) ≤ field_of_view < 90° (π/2 rad)")
    n_azimuth_bins: int = Field(121, ge=3, le=4096)
    max_range: float = Field(100.0, gt=0, description="RA maps are cropped to [0, max_range] [m]")
    range_window: str = Field("hann", description="scipy.signal window for the range FFT")
    azimuth_window: str = Field("taylor", description="scipy.signal window for beamforming")
    azimuth_channels: Literal["all", "row"] = Field(
        "all", description="channels the RA map is beamformed from (at elevation 0, each at its true (y, z)): "
                           "'all'; 'row': only the channels at the height most of them share (a raised "
                           "transmitter's channels left out, so a target off the horizontal plane keeps the "
                           "row's sidelobes; xnlos_core.signal.antenna.azimuth_row). Left out of the saved "
                           "config while 'all'")
    # TDM-MIMO slow-time timing. None keeps the implied back-to-back timing, and unset
    # fields are left out of the serialised config, so existing configs keep their JSON and digest.
    chirp_period: float | None = Field(
        None, gt=0, le=1, description="T_c [s]: start-to-start interval of consecutive chirps (any TX), "
                                      "≥ chirp_duration; None: chirp_duration (back-to-back chirps)")
    frame_period: float | None = Field(
        None, gt=0, le=3600, description="start-to-start interval of frames [s], ≥ n_chirps·n_tdm·T_c; "
                                         "None: n_chirps·n_tdm·T_c (back-to-back frames)")

    @field_validator("field_of_view", mode="before")
    @classmethod
    def _field_of_view_in_radians(cls, v: Any) -> Any:
        # the bounds are the Field's; this says them in radians and degrees (a value in degrees, e.g.
        # 60, or a denormal such as 5e-324 is the usual mistake)
        if isinstance(v, (int, float)) and not isinstance(v, bool) and not (MIN_HALF_FOV <= v < math.pi / 2):
            deg = f" (= {math.degrees(v):.6g}°)" if math.isfinite(v) else ""
            raise ValueError(f"field_of_view is the HALF field of view in radians: expected 1° "
                             f"({MIN_HALF_FOV:.5f} rad) ≤ field_of_view < 90° ({math.pi / 2:.5f} rad), got {v!r} "
                             f"rad{deg}; e.g. 1.0471975511965976 for ±60°")
        return v

    @model_validator(mode="before")
    @classmethod
    def _derive_from_positions(cls, data: Any) -> Any:
        # n_tx, n_rx (and rx_spacing) follow from explicit positions unless given; given ones are
        # checked against the positions in _check_layout
        if not isinstance(data, dict):
            return data
        data = dict(data)
        for positions, count in (("tx_positions", "n_tx"), ("rx_positions", "n_rx")):
            pos = data.get(positions)
            if pos is not None and count not in data and hasattr(pos, "__len__"):
                data[count] = len(pos)
        rx = data.get("rx_positions")
        if rx is not None and "rx_spacing" not in data:
            gap = _smallest_separation(rx)
            if gap is not None and gap > OVERLAP_TOLERANCE:
                data["rx_spacing"] = gap
        return data

    @model_validator(mode="after")
    def _check_layout(self) -> "RadarConfig":
        for positions, count in (("tx_positions", "n_tx"), ("rx_positions", "n_rx")):
            pos = getattr(self, positions)
            if pos is not None and len(pos) != getattr(self, count):
                raise ValueError(f"{count}={getattr(self, count)} contradicts {positions}, which lists "
                                 f"{len(pos)} elements; leave {count} out (it is derived) or make them agree")
            if pos is not None:
                _check_no_overlap(positions, pos)
        if self.tx_positions is not None:
            for name, unset in (("tx_spacing", None), ("tx_elevation_offset", 0.0)):
                if getattr(self, name) != unset:
                    raise ValueError(f"{name}={getattr(self, name)} contradicts tx_positions, which places "
                                     f"every TX element; leave {name} out (or {unset}) with tx_positions")
        if self.rx_positions is not None:
            gap = _smallest_separation(self.rx_positions)
            if gap is not None and not math.isclose(self.rx_spacing, gap, rel_tol=1e-9):
                raise ValueError(f"rx_spacing={self.rx_spacing} contradicts rx_positions, whose closest "
                                 f"elements are {gap:.6g} wavelengths apart; leave rx_spacing out (it is "
                                 "derived) or make them agree")
        return self

    @model_validator(mode="after")
    def _check_range(self) -> "RadarConfig":
        if self.max_range > self.max_unambiguous_range:
            raise ValueError(
                f"max_range={self.max_range} m exceeds the unambiguous range "
                f"{self.max_unambiguous_range:.1f} m (n_samples·c/2B); raise n_samples or lower max_range"
            )
        if self.max_range < 2 * self.range_resolution:
            raise ValueError(f"max_range={self.max_range} m is below two range bins ({self.range_resolution:.3f} m each)")
        for name in ("range_window", "azimuth_window"):
            _check_window(name, getattr(self, name))
        if self.chirp_period is not None and self.chirp_period < self.chirp_duration:
            raise ValueError(f"chirp_period={self.chirp_period} s is shorter than chirp_duration="
                             f"{self.chirp_duration} s; a chirp must end before the next starts")
        if self.frame_period is not None and self.frame_period < self.chirp_loop_time * self.n_chirps:
            raise ValueError(f"frame_period={self.frame_period} s is shorter than the frame's chirps "
                             f"n_chirps·n_tdm·T_c = {self.chirp_loop_time * self.n_chirps:.6g} s")
        if self.coupling_db is not None and self.coupling_file is not None:
            raise ValueError("coupling_db and coupling_file are exclusive: give the modelled level or a "
                             "measured matrix, not both")
        return self

    @model_serializer(mode="wrap")
    def _omit_unset_timing(self, handler):
        # the timing fields arrived after configs, digests and saved frames existed: leave them out
        # while unset so those stay byte-identical; a set value serialises and round-trips
        data = handler(self)
        if isinstance(data, dict):
            for name in _OMIT_WHEN_UNSET:
                if data.get(name, 0) is None:
                    del data[name]
            if data.get("azimuth_channels") == "all":
                del data["azimuth_channels"]
        return data

    # --- derived quantities (float64) ----------------------------------------------------
    @property
    def wavelength(self) -> float:
        """λ = c / f_c [m]."""
        return SPEED_OF_LIGHT / self.carrier_frequency

    @property
    def chirp_slope(self) -> float:
        """S = B / T [Hz/s]."""
        return self.bandwidth / self.chirp_duration

    @property
    def sample_rate(self) -> float:
        """Complex sampling rate f_s = N / T [Hz] (the whole sweep is sampled)."""
        return self.n_samples / self.chirp_duration

    @property
    def range_resolution(self) -> float:
        """ΔR = c / (2B) [m], also the range-bin spacing."""
        return SPEED_OF_LIGHT / (2.0 * self.bandwidth)

    @property
    def max_unambiguous_range(self) -> float:
        """Range whose beat frequency equals f_s (complex sampling): N·c/(2B) [m]."""
        return self.n_samples * self.range_resolution

    @property
    def noise_power(self) -> float:
        """Thermal noise per complex sample of the frame's ADC cube, k·T·f_s·NF / n_chirps [W].

        The cube is the coherent mean of ``n_chirps`` chirps per transmitter: a static scene's
        echo is the same in every chirp and the noise is independent, so averaging keeps the
        signal and divides the noise power by n_chirps (an SNR gain of 10·log10(n_chirps) dB;
        18.1 dB for the default 64). A mover's echo turns in phase from chirp to chirp and is lost
        in the mean; :mod:`xnlos_core.signal.doppler` keeps the chirps (per-chirp noise: n_chirps times this).
        """
        return BOLTZMANN * self.temperature * self.sample_rate * 10 ** (self.noise_figure_db / 10) / self.n_chirps

    @property
    def n_range_bins(self) -> int:
        """Range bins kept in the RA map (0 … max_range): ⌊max_range/ΔR⌋ + 1, at most n_samples.

        The quotient is taken with a tolerance of RANGE_BIN_TOLERANCE bins, so a max_range that is
        k·ΔR up to rounding (a recording's default (N − 1)·c/(2B) gives 126.99999999999999 for some
        profiles) keeps bin k, whose centre it names, instead of losing it. Bin N would be range
        N·ΔR, which the complex range FFT folds onto bin 0, so the map never has more than N bins.
        """
        k = int(math.floor(self.max_range / self.range_resolution + RANGE_BIN_TOLERANCE)) + 1
        return min(k, self.n_samples)

    @property
    def range_axis(self) -> np.ndarray:
        """Range-bin centres [m], shape (n_range_bins,), ascending from 0."""
        return np.arange(self.n_range_bins, dtype=np.float64) * self.range_resolution

    @property
    def azimuth_axis(self) -> np.ndarray:
        """Azimuth grid θ [rad], shape (n_azimuth_bins,), uniform over ±field_of_view."""
        return np.linspace(-self.field_of_view, self.field_of_view, self.n_azimuth_bins)

    @property
    def n_channels(self) -> int:
        """Recorded channels: n_tx·n_rx virtual channels with MIMO, else the n_rx receivers."""
        return self.n_tx * self.n_rx if self.mimo else self.n_rx

    @property
    def has_coupling(self) -> bool:
        """True when a modelled or measured coupling matrix is configured."""
        return self.coupling_db is not None or self.coupling_file is not None

    @property
    def tx_layout(self) -> np.ndarray:
        """(n_tx, 2) TX element (y, z) [wavelengths], as configured (not centred).

        ``tx_positions`` when given, else the uniform row y_i = i·tx_spacing (default
        n_rx·rx_spacing: a filled virtual array), z = tx_elevation_offset.
        """
        if self.tx_positions is not None:
            return _layout_array("tx_positions", self.tx_positions, self.n_tx, "n_tx")
        step = self.tx_spacing if self.tx_spacing is not None else self.n_rx * self.rx_spacing
        return np.stack([np.arange(self.n_tx) * step, np.full(self.n_tx, self.tx_elevation_offset)], axis=1)

    @property
    def rx_layout(self) -> np.ndarray:
        """(n_rx, 2) RX element (y, z) [wavelengths]: ``rx_positions``, else y_j = j·rx_spacing, z = 0."""
        if self.rx_positions is not None:
            return _layout_array("rx_positions", self.rx_positions, self.n_rx, "n_rx")
        return np.stack([np.arange(self.n_rx) * self.rx_spacing, np.zeros(self.n_rx)], axis=1)

    @property
    def has_custom_layout(self) -> bool:
        """True when ``tx_positions`` or ``rx_positions`` places the elements (not the uniform rows)."""
        return self.tx_positions is not None or self.rx_positions is not None

    @property
    def virtual_positions(self) -> np.ndarray:
        """y positions of the n_tx·n_rx virtual elements [m], shape (n_tx·n_rx,), centred on 0.

        Virtual element (i, j) sits at y_tx,i + y_rx,j, ordered tx-major (coinciding virtual
        elements are kept: their channels add). Without MIMO the channels are the RX elements
        themselves, (n_rx,) centred on 0. Heights: :func:`xnlos_core.signal.antenna.channel_positions`.
        """
        lam = self.wavelength
        rx = self.rx_layout[:, 0] * lam
        if not self.mimo:
            return rx - rx.mean()
        tx = self.tx_layout[:, 0] * lam
        v = (tx[:, None] + rx[None, :]).ravel()
        return v - v.mean()

    # --- slow time (TDM-MIMO chirp sequence) -------------------------------------
    @property
    def chirp_interval(self) -> float:
        """T_c [s]: start-to-start time of consecutive chirps, ``chirp_period`` or chirp_duration."""
        return self.chirp_duration if self.chirp_period is None else self.chirp_period

    @property
    def n_tdm(self) -> int:
        """N_tx of the slow-time formulas: TX slots per chirp loop (n_tx with MIMO, 1 without: all TX at once)."""
        return self.n_tx if self.mimo else 1

    @property
    def chirp_loop_time(self) -> float:
        """T_c·N_tx [s]: slow-time sampling interval of one virtual channel (one chirp per TX)."""
        return self.chirp_interval * self.n_tdm

    @property
    def frame_interval(self) -> float:
        """Frame start-to-start time [s]: ``frame_period``, or n_chirps·T_c·N_tx (back-to-back)."""
        return self.n_chirps * self.chirp_loop_time if self.frame_period is None else self.frame_period

    @property
    def doppler_wavelength(self) -> float:
        """λ₀ = c / (f_c + B/2) [m]: the wavelength of the sweep's centre frequency.

        A range bin's phase follows the echo's phase at the middle of the chirp (the range FFT's
        phase centre), so a mover's slow-time frequency is 2·v_r/λ₀, not 2·v_r/λ (3 % apart for
        the default 600 MHz sweep at 10 GHz). The velocity formulas below use λ₀.
        """
        return SPEED_OF_LIGHT / (self.carrier_frequency + 0.5 * self.bandwidth)

    @property
    def max_unambiguous_velocity(self) -> float:
        """v_max = λ₀ / (4·T_c·N_tx) [m/s]: radial velocities fold into [−v_max, v_max)."""
        return self.doppler_wavelength / (4.0 * self.chirp_loop_time)

    @property
    def velocity_resolution(self) -> float:
        """Δv = λ₀ / (2·N·T_c·N_tx) [m/s] (N = n_chirps), also the Doppler-bin spacing in velocity."""
        return self.doppler_wavelength / (2.0 * self.n_chirps * self.chirp_loop_time)

    @property
    def doppler_axis(self) -> np.ndarray:
        """Doppler-bin centres f_D [Hz], shape (n_chirps,), ascending (fft-shifted), spacing 1/(N·T_c·N_tx)."""
        return np.fft.fftshift(np.fft.fftfreq(self.n_chirps, d=self.chirp_loop_time))

    @property
    def velocity_axis(self) -> np.ndarray:
        """Radial velocity v_r = λ₀·f_D/2 [m/s] of each Doppler bin, shape (n_chirps,), ascending from −v_max.

        v_r is the range rate dR/dt: positive receding (the sign
        :func:`xnlos_core.signal.chain.dechirp` gives f_D); λ₀ is :attr:`doppler_wavelength`.
        """
        return 0.5 * self.doppler_wavelength * self.doppler_axis


_OMIT_WHEN_UNSET = ("chirp_period", "frame_period", "tx_positions", "rx_positions")


def _layout_array(name: str, positions, n: int, count: str) -> np.ndarray:
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    if len(p) != n:  # only reachable through model_copy(update=…), which skips validation
        raise ConfigError(f"{count}={n} contradicts {name}, which lists {len(p)} elements")
    return p


def _smallest_separation(positions) -> float | None:
    """Smallest distance between two elements [wavelengths], None for fewer than two (or malformed)."""
    try:
        p = np.asarray(positions, dtype=np.float64)
    except (TypeError, ValueError):
        return None
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 2:
        return None
    d = np.hypot(p[:, None, 0] - p[None, :, 0], p[:, None, 1] - p[None, :, 1])
    return float(d[np.triu_indices(len(p), 1)].min())


def _check_no_overlap(name: str, positions) -> None:
    p = np.asarray(positions, dtype=np.float64)
    d = np.hypot(p[:, None, 0] - p[None, :, 0], p[:, None, 1] - p[None, :, 1])
    i, j = np.nonzero(np.triu(d < OVERLAP_TOLERANCE, 1))
    if len(i):
        a, b = int(i[0]), int(j[0])
        raise ValueError(f"{name}: elements {a} and {b} overlap (both at {list(positions[a])} wavelengths); "
                         f"two elements of one array must be at least {OVERLAP_TOLERANCE:g} wavelengths "
                         "apart (virtual elements may coincide, physical ones may not)")


# scipy.signal windows that need no parameter, accepted by get_window under these names (checked
# against scipy in tests/unit/test_startup_imports.py): validating them needs no scipy.signal, whose
# import (~0.3 s) every pipeline load would otherwise pay. Any other name is asked of scipy.
SCIPY_WINDOWS = frozenset({"barthann", "bartlett", "blackman", "blackmanharris", "bohman", "boxcar", "cosine",
                           "flattop", "hamming", "hann", "lanczos", "nuttall", "parzen", "taylor", "triang",
                           "tukey"})


def _check_window(name: str, window: str) -> None:
    if window in SCIPY_WINDOWS:
        return
    from scipy.signal import get_window

    try:
        get_window(window, 8)
    except Exception as exc:  # scipy raises ValueError/TypeError with little context
        raise ValueError(f"{name}={window!r} is not a scipy.signal window name (e.g. 'hann', 'taylor', 'boxcar'): {exc}") from None


PRESET_DIR = Path(__file__).with_name("defaults") / "radar"
PRESET_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_-]{0,63}")


def radar_presets() -> list[str]:
    """Names of the radar presets shipped inside the package (``xnlos_core/defaults/radar/*.toml``),
    usable as ``preset = "NAME"`` from any folder and from an installed package."""
    return sorted(p.stem for p in PRESET_DIR.glob("*.toml"))


def preset_path(preset, source: str, base_dir: str | Path) -> Path:
    """The preset file ``preset`` names: a shipped preset by name (no ``.toml`` suffix, e.g.
    ``"xband_default"``), else a ``.toml`` file relative to ``base_dir`` inside the config roots."""
    if isinstance(preset, str) and not preset.lower().endswith(".toml"):
        if not (PRESET_NAME.fullmatch(preset) and preset in radar_presets()):
            raise ConfigError(f"{source}: [radar.preset] unknown preset {preset[:200]!r}; shipped presets: "
                              f"{', '.join(radar_presets())} (or a path to a .toml file, relative to the config)")
        return PRESET_DIR / f"{preset}.toml"
    return resolve_config_path(preset, source=source, key="radar.preset", base_dir=base_dir, suffixes=(".toml",))


def load_radar(table: dict[str, Any], source: str, base_dir: str | Path) -> RadarConfig:
    """RadarConfig from a ``[radar]`` table: fields, or ``preset = NAME | "file.toml"`` plus overrides.

    ``preset`` is the name of a shipped preset (:func:`radar_presets`, e.g. ``"xband_default"``)
    or a file inside the config roots (:mod:`xnlos_core.files`) relative to ``base_dir`` (the
    config's folder); ``coupling_file`` is a file inside the config roots relative to the file
    that names it; the returned config holds the coupling file's resolved absolute path.
    """
    if not isinstance(table, dict):
        raise ConfigError(f"{source}: [radar] expected a table of RadarConfig fields, got {table!r}")
    table = dict(table)
    preset = table.pop("preset", None)
    coupling_dir = base_dir
    if preset is not None:
        path = preset_path(preset, source, base_dir)
        base = load_toml(path)
        base = base.get("radar", base)
        if not isinstance(base, dict):
            raise ConfigError(f"{path}: [radar] expected a table of RadarConfig fields, got {base!r}")
        if "coupling_file" in base and "coupling_file" not in table:
            coupling_dir = path.parent
        table = {**base, **table}
        source = f"{source} (preset {path})"
    if table.get("coupling_file") is not None:
        table["coupling_file"] = str(resolve_config_path(
            table["coupling_file"], source=source, key="radar.coupling_file", base_dir=coupling_dir,
            root_dir=base_dir, suffixes=(".npy", ".npz", ".csv")))
    try:
        return validate_model(RadarConfig, table, source=source, prefix="radar")
    except ConfigError:
        raise
    except ValueError as exc:
        raise ConfigError(f"{source}: [radar] {exc}") from None
