"""Raw radar recordings described by a TOML file → chirp cubes and RA maps through the shared chain.

A recording description (``*.toml``) has three tables::

    [recording]                 # RecordingSpec: the file and its layout
    file = "capture_Raw_0.bin"  # relative to this TOML
    format = "dca1000"          # dca1000 | npy | npz | hdf5
    sampling = "complex"        # complex | real (real-only ADC; made analytic, half the range)
    lanes = 2                   # DCA1000 LVDS lane order: 2 (xWR16xx/18xx/68xx) or 4 (xWR12xx/14xx)
    encoding = "twos_complement"  # or "offset_binary" (16-bit codes, 32768 = 0)
    iq_order = "iq"             # or "qi": Q stored where I is expected
    iq_interleave = "lanes"     # DCA1000 groups I(n), I(n+1), Q(n), Q(n+1); "samples": I(n), Q(n), …
    scale = 1e-6                # √W per ADC count
    [chirp]                     # ChirpProfile: the chip's profile as its configuration states it
    slope = 29.982e12           # S [Hz/s]
    sample_rate = 10e6          # ADC rate f_s [Hz]
    n_samples = 256             # ADC samples per chirp
    ramp_time = 60e-6           # optional [s]; with idle_time gives the chirp period
    idle_time = 100e-6          # optional [s]
    tx_order = [0, 2, 1]        # optional: the transmitter (array position) of each TDM slot
    [radar]                     # RadarConfig fields or preset (carrier, n_tx, n_rx, n_chirps, spacing …)

The sweep seen by the ADC is the sampling window N/f_s, so the radar gets bandwidth B = S·N/f_s and
chirp_duration N/f_s (not S·T_ramp: that moves every range, see
:func:`hardware.recording_checks.check_bandwidth`). ``max_range`` defaults to the last unambiguous
range bin. DCA1000 chirps are in transmission order (loop m, TDM slot i), so the channel of RX j in
slot i is tx_order[i]·n_rx + j (tx-major, xnlos's order). Cubes (``.npy``/``.npz``/HDF5) are laid out
by ``axes`` (a permutation of sample, chirp, channel, with an optional frame axis),
``sample_format`` and ``channel_order`` as :class:`hardware.adc.AdcLayout` describes.

The data file is read as :mod:`xnlos_core.datafiles` reads every data file: a regular file only (a
FIFO or device is refused before a byte is read), an HDF5 file that reads no other file (external
links, external storage and virtual datasets are refused), declared sizes checked before memory is
allocated, damaged bytes an InputError naming the file. On opening, a cube must have the rank,
axis lengths and dtype the description and the radar give, and at least one frame (an empty
recording is refused, as is a DCA1000 file shorter than one frame), so that ``xnlos check``, which
opens the recording, refuses what a run would.
"""
from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from hardware.adc import AdcLayout, chirp_cube
from xnlos_core.datafiles import file_size, open_regular
from xnlos_core.errors import ConfigError, InputError
from xnlos_core.files import load_toml, resolve_config_path
from xnlos_core.radar import RadarConfig, load_radar
from xnlos_core.signal.chain import decouple, range_fft, ra_map_from_cube
from xnlos_core.signal.doppler import DopplerRAMaps, doppler_ra_maps
from xnlos_core.types import Frame, RAMap
from xnlos_core.validation import validate_model

from .calibration import calibration_gains
from .layout.candidates import MAX_WORDS, Layout
from .layout.checks import check_layout
from .raw_formats import analytic_signal, dca1000_frame_words, decode_dca1000, load_cube, signed_words, swap_iq
from .recording_checks import (RecordingWarning, check_bandwidth, check_channel_order, check_leakage,
                               check_single_receiver, check_spec, check_unsigned)

MAX_LEAKAGE_RANGE = 1000.0  # [m]: far beyond any radar's leakage, finite so that bin arithmetic stays exact
_SUFFIXES = {"dca1000": (".bin", ".dat", ".raw"), "npy": (".npy",), "npz": (".npz",),
             "hdf5": (".h5", ".hdf5")}


class RecordingSpec(BaseModel):
    """The ``[recording]`` table: which file, its format and how its samples are laid out."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    file: str = Field(..., min_length=1, description="the recording, relative to the TOML that names it")
    format: Literal["dca1000", "npy", "npz", "hdf5"] = Field(..., description="file format")
    sampling: Literal["complex", "real"] = Field("complex", description="complex (I/Q) or real-only ADC samples")
    lanes: Literal[2, 4] = Field(2, description="DCA1000 LVDS lane order: 2 (xWR16xx/18xx/68xx), 4 (xWR12xx/14xx)")
    encoding: Literal["twos_complement", "offset_binary"] = Field(
        "twos_complement", description="16-bit codes: signed two's complement (the DCA1000's), or offset binary "
                                       "(0 … 65535, 32768 = 0; TSW1400-style cards)")
    iq_order: Literal["iq", "qi"] = Field("iq", description="complex samples: I first (iq) or Q first (qi) in "
                                                            "each group of words, or in a cube's I/Q axis")
    iq_interleave: Literal["lanes", "samples"] = Field(
        "lanes", description="DCA1000 complex words: 'lanes' = I of each lane then Q of each lane (2 lanes: "
                            "I(n), I(n+1), Q(n), Q(n+1)); 'samples' = each I beside its Q (I(n), Q(n), …)")
    key: str = Field("adc", min_length=1, description="array name in a .npz, dataset in an HDF5 file")
    axes: tuple[str, ...] = Field(("frame", "sample", "chirp", "channel"),
                                  description="cube axes in order: sample, chirp, channel and optionally frame")
    sample_format: Literal["complex", "iq"] = Field(
        "complex", description="cubes: complex dtype, or a trailing axis of 2 holding I then Q")
    channel_order: Literal["tx_major", "rx_major"] = Field(
        "tx_major", description="tx_major: channel = slot·n_rx + rx (the DCA1000's order); rx_major: rx·n_tx + slot")
    scale: float = Field(1.0, gt=0, le=1e6, allow_inf_nan=False, description="amplitude per ADC count [√W]")
    adc_offset: float = Field(0.0, ge=-2.0**32, le=2.0**32, allow_inf_nan=False,
                              description="subtracted from every count after decoding `encoding` (e.g. the "
                                          "mid-scale 2048 of a 12-bit ADC stored unsigned)")
    remove_dc: bool = Field(False, description="subtract each channel's mean over a chirp's samples")
    leakage_range: float = Field(1.0, ge=0, le=MAX_LEAKAGE_RANGE, allow_inf_nan=False,
                                 description="near range [m] checked for TX→RX leakage (and skipped by the "
                                             "channel-order check), 0 … 1000 m")
    leakage_db: float = Field(30.0, gt=0, le=300, allow_inf_nan=False,
                              description="leakage warning threshold above the map's median [dB]")
    calibration: tuple[tuple[float, float], ...] | None = Field(
        None, description="each channel's gain as [amplitude, phase_deg] (tx-major by array position); the "
                          "samples are divided by it (hardware.calibration; estimate_calibration measures it "
                          "on a corner-reflector capture)")

    @field_validator("axes")
    @classmethod
    def _axes(cls, v):
        core = sorted(a for a in v if a != "frame")
        if core not in (["channel", "chirp", "sample"], ["channel", "sample"]) or v.count("frame") > 1:
            raise ValueError(f"axes must order sample, channel (and chirp, frame), each once; got {v}")
        return v

    def cube_shape(self, radar: RadarConfig) -> tuple[str, ...]:
        """The expected cube shape as text, one entry per axis of the file (``N ≥ 1`` where any
        length is allowed), e.g. ``("frame: N ≥ 1", "sample: 128", …, "I/Q: 2")``."""
        size = {"frame": "N ≥ 1", "sample": str(radar.n_samples), "chirp": "N ≥ 1",
                "channel": str(radar.n_channels)}
        iq = ("I/Q: 2",) if self.sample_format == "iq" and self.sampling == "complex" else ()
        return tuple(f"{a}: {size[a]}" for a in self.axes) + iq


class ChirpProfile(BaseModel):
    """The ``[chirp]`` table: the profile as the radar chip is configured (units SI)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    slope: float = Field(..., gt=0, description="frequency slope S [Hz/s]")
    sample_rate: float = Field(..., gt=0, description="ADC sampling rate f_s [Hz] (complex or real samples)")
    n_samples: int = Field(..., ge=16, le=16384, description="ADC samples per chirp N")
    ramp_time: float | None = Field(None, gt=0, description="ramp end time [s]; only for the chirp period")
    idle_time: float | None = Field(None, ge=0, description="idle time between chirps [s]")
    tx_order: tuple[int, ...] | None = Field(
        None, description="array position (0 … n_tx−1) of the transmitter firing in each TDM slot")


def recording_radar(table: dict[str, Any], source: str, base_dir: str | Path) -> tuple[RadarConfig, ChirpProfile | None]:
    """RadarConfig of a recording description: its ``[radar]`` table (fields or preset) with the
    waveform derived from ``[chirp]`` when present (B = S·N/f_s, T = N/f_s, T_c = idle + ramp,
    max_range = last unambiguous bin unless given; real sampling halves the range)."""
    radar_table = dict(table.get("radar", {}))
    if "chirp" not in table:
        return load_radar(radar_table, source, base_dir), None
    chirp = validate_model(ChirpProfile, table["chirp"], source=source, prefix="chirp")
    if radar_table.get("n_samples", chirp.n_samples) != chirp.n_samples:
        raise ConfigError(f"{source}: [radar] n_samples={radar_table['n_samples']} contradicts [chirp] "
                          f"n_samples={chirp.n_samples}; give it once, in [chirp]")
    given_b = radar_table.pop("bandwidth", None)
    radar_table.pop("chirp_duration", None)
    b = check_bandwidth(chirp.slope, chirp.sample_rate, chirp.n_samples, chirp.ramp_time, given_b, source)
    derived: dict[str, Any] = {"n_samples": chirp.n_samples, "bandwidth": b,
                               "chirp_duration": chirp.n_samples / chirp.sample_rate}
    if chirp.ramp_time is not None and chirp.idle_time is not None and "chirp_period" not in radar_table:
        derived["chirp_period"] = chirp.ramp_time + chirp.idle_time
    sampling = table.get("recording", {}).get("sampling", "complex")
    n_bins = chirp.n_samples // 2 if sampling == "real" else chirp.n_samples
    if "max_range" not in radar_table:
        derived["max_range"] = (n_bins - 1) * 299_792_458.0 / (2 * b)
    return load_radar({**radar_table, **derived}, source, base_dir), chirp


@dataclass
class Recording:
    """A raw recording opened through its description: frames → chirp cubes → RA maps.

    Use :meth:`from_toml`. ``path``: the data file; ``spec``, ``radar``, ``chirp`` as described.
    """

    spec: RecordingSpec
    radar: RadarConfig
    chirp: ChirpProfile | None
    path: Path
    source: str

    def __post_init__(self):
        radar, spec = self.radar, self.spec
        if spec.sampling == "real" and radar.max_range > radar.max_unambiguous_range / 2:
            raise ConfigError(f"{self.source}: real-only sampling resolves up to N/2 bins "
                              f"({radar.max_unambiguous_range / 2:.2f} m); radar.max_range={radar.max_range} m")
        order = self.chirp.tx_order if self.chirp is not None else None
        if order is not None and radar.mimo and sorted(order) != list(range(radar.n_tx)):
            raise ConfigError(f"{self.source}: [chirp] tx_order must be a permutation of 0 … {radar.n_tx - 1} "
                              f"(n_tx={radar.n_tx}), got {list(order)}")
        self._tx_order = None if order is None or not radar.mimo or list(order) == sorted(order) else np.array(order)
        check_spec(spec, radar, self.source)
        if spec.format == "dca1000":
            with open_regular(self.path, what=f"recording {self.path}") as f:
                self._size = file_size(f)
            words = self._size // 2
            self._frame_words = dca1000_frame_words(radar.n_samples, radar.n_chirps * radar.n_tdm,
                                                    radar.n_channels // radar.n_tdm, spec.sampling, spec.lanes)
            n, rest = divmod(words, self._frame_words)
            if n == 0:
                raise InputError(f"{self.path}: {words} int16 words, fewer than one frame ({self._frame_words}: "
                                 f"n_samples × n_chirps·n_tdm × n_rx{' × 2 (I/Q)' if spec.sampling == 'complex' else ''})")
            if rest or self._size % 2:
                import warnings

                warnings.warn(f"{self.path}: {rest} int16 words after the last whole frame ({n} frames of "
                              f"{self._frame_words}): a truncated capture, or n_samples/n_chirps/n_rx/lanes do not "
                              "match the recording; the partial frame is dropped", RecordingWarning, stacklevel=2)
            self._n_frames = n
            self._cube = None
        else:
            if spec.sampling == "real" and spec.sample_format == "iq":
                raise ConfigError(f"{self.source}: [recording] sampling = 'real' stores one real value per sample; "
                                  "sample_format = 'iq' (I/Q pairs) contradicts it: leave sample_format out")
            cube = load_cube(self.path, spec.format, spec.key)
            self._check_cube(cube)
            if "frame" not in spec.axes:
                cube, axes = cube[None], ("frame",) + spec.axes
            else:
                axes = spec.axes
                cube = np.moveaxis(cube, axes.index("frame"), 0)
            self._axes = tuple(a for a in axes if a != "frame")
            self._cube = cube
            self._n_frames = int(cube.shape[0])
        check_single_receiver(radar, self.source)
        self._gains = None if spec.calibration is None else \
            calibration_gains(spec.calibration, radar.n_channels, f"{self.source}: [recording] calibration")

    def _check_cube(self, cube: np.ndarray) -> None:
        """InputError naming the file unless ``cube`` has the rank, axis lengths and dtype that
        ``[recording]`` (axes, sample_format, sampling) and the radar (n_samples, n_channels)
        describe, and at least one frame and one chirp — checked once on opening, so that ``xnlos
        check`` refuses what a run would and a run never starts on a cube it cannot read."""
        spec, radar = self.spec, self.radar
        iq = spec.sample_format == "iq" and spec.sampling == "complex"
        want = spec.cube_shape(radar)
        where = (f"{self.path}: recording cube (key {spec.key!r}) " if spec.format != "npy"
                 else f"{self.path}: recording cube ")
        expected = f"expected shape ({', '.join(want)}) from [recording] axes {list(spec.axes)}"
        if cube.ndim != len(want):
            raise InputError(f"{where}has shape {cube.shape} ({cube.ndim}-D); {expected}")
        kinds, kind_text = (("iuf", "integer or float I/Q pairs") if iq else
                            ("iuf", "integer or float real samples") if spec.sampling == "real" else
                            ("c", "complex samples (or sample_format = 'iq' for integer I/Q pairs)"))
        if cube.dtype.kind not in kinds:
            raise InputError(f"{where}has dtype {cube.dtype}; expected {kind_text}")
        sizes = {"sample": radar.n_samples, "channel": radar.n_channels}
        for k, axis in enumerate(spec.axes):
            n = cube.shape[k]
            if axis in sizes and n != sizes[axis]:
                raise InputError(f"{where}has {n} entries on its '{axis}' axis (shape {cube.shape}); {expected} "
                                 f"(n_samples={radar.n_samples}, n_channels={radar.n_channels})")
            if n == 0:
                what = "no frames: an empty recording" if axis == "frame" else f"an empty '{axis}' axis"
                raise InputError(f"{where}has {what} (shape {cube.shape}); {expected}")
        if iq and cube.shape[-1] != 2:
            raise InputError(f"{where}has {cube.shape[-1]} entries on its trailing I/Q axis (shape {cube.shape}); "
                             f"{expected}")

    @classmethod
    def from_toml(cls, path: str | Path) -> "Recording":
        """Open the recording a TOML description names (ConfigError on a bad description)."""
        p = Path(path)
        table = load_toml(p)
        source = str(p)
        unknown = set(table) - {"recording", "chirp", "radar"}
        if unknown:
            raise ConfigError(f"{source}: unknown table(s) {sorted(unknown)}; expected [recording], [chirp], [radar]")
        return cls.from_table(table, source, p.parent)

    @classmethod
    def from_table(cls, table: dict[str, Any], source: str, base_dir: str | Path) -> "Recording":
        """Open a recording from an already parsed description; files are relative to ``base_dir``."""
        if "recording" not in table:
            raise ConfigError(f"{source}: missing the [recording] table (file, format, …)")
        spec = validate_model(RecordingSpec, table["recording"], source=source, prefix="recording")
        data = resolve_config_path(spec.file, source=source, key="recording.file", base_dir=base_dir,
                                   suffixes=_SUFFIXES[spec.format])
        radar, chirp = recording_radar(table, source, base_dir)
        return cls(spec, radar, chirp, data, source)

    @property
    def n_frames(self) -> int:
        """Whole frames in the file."""
        return self._n_frames

    def raw_frame(self, i: int) -> np.ndarray:
        """Frame ``i`` as stored: DCA1000 int16 words (1-D) or the cube's frame slice."""
        if not 0 <= i < self._n_frames:
            raise InputError(f"{self.path}: frame {i} out of range (the recording has {self._n_frames})")
        if self._cube is not None:
            try:
                return np.asarray(self._cube[i])
            except (OSError, ValueError) as exc:  # a memory-mapped .npy that shrank since it was opened
                raise InputError(f"{self.path}: frame {i} cannot be read ({type(exc).__name__}: {exc})") from None
        n = 2 * self._frame_words
        with open_regular(self.path, what=f"recording {self.path}") as f:
            try:
                f.seek(i * n)
                data = f.read(n)
            except OSError as exc:
                raise InputError(f"{self.path}: frame {i} cannot be read ({exc.strerror or exc})") from None
        if len(data) != n:
            raise InputError(f"{self.path}: frame {i} holds {len(data)} of its {n} bytes (the file shrank since "
                             "it was opened)")
        return np.frombuffer(data, dtype="<i2").copy()

    def chirp_cube(self, i: int) -> np.ndarray:
        """Frame ``i`` → (n_samples, n_chirps, n_channels) complex128 [√W], channels tx-major by array position."""
        with self._naming_frame(i):
            return self._chirp_cube(i)

    @contextlib.contextmanager
    def _naming_frame(self, i: int):
        """Prefix an InputError raised inside (the ADC layout's, the RA map's: NaN or infinite samples,
        e.g. 1e300 counts that overflow the FFT) with the file and frame, unless it names the file."""
        try:
            yield
        except InputError as exc:
            if str(self.path) in str(exc):
                raise
            raise InputError(f"{self.path}: frame {i}: {exc}") from None

    def _chirp_cube(self, i: int) -> np.ndarray:
        radar, spec = self.radar, self.spec
        raw = signed_words(self.raw_frame(i), spec.encoding)
        x = raw.astype(np.float64) - spec.adc_offset if spec.adc_offset else raw
        if spec.format == "dca1000":
            n_rx = radar.n_channels // radar.n_tdm
            z = decode_dca1000(x, radar.n_samples, radar.n_chirps * radar.n_tdm, n_rx, spec.sampling, spec.lanes,
                               spec.iq_order, spec.iq_interleave)
            if spec.sampling == "real":
                z = analytic_signal(z, axis=0)
            z = z.reshape(radar.n_samples, radar.n_chirps, radar.n_channels)  # slot-major channels
            layout = AdcLayout(channel_order=spec.channel_order, scale=spec.scale, remove_dc=spec.remove_dc)
        else:
            fmt = spec.sample_format
            if spec.sampling == "real":
                z, fmt = analytic_signal(x, axis=self._axes.index("sample")), "complex"
            else:
                z = swap_iq(x, fmt) if spec.iq_order == "qi" else x
            layout = AdcLayout(axes=self._axes, sample_format=fmt, channel_order=spec.channel_order,
                               scale=spec.scale, remove_dc=spec.remove_dc)
        cube = chirp_cube(z, layout, radar)
        if self._tx_order is not None:
            out = np.empty_like(cube)
            for slot, tx in enumerate(self._tx_order):
                out[:, :, tx * radar.n_rx:(tx + 1) * radar.n_rx] = cube[:, :, slot * radar.n_rx:(slot + 1) * radar.n_rx]
            cube = out
        return cube if self._gains is None else cube / self._gains

    def ra_map(self, i: int) -> RAMap:
        """Frame ``i``'s RA map: chirps integrated coherently, then the shared chain (no velocity)."""
        cube = self.chirp_cube(i).mean(axis=1)
        with self._naming_frame(i):
            return ra_map_from_cube(cube, self.radar)

    @property
    def has_doppler(self) -> bool:
        """Whether a frame holds enough chirps per transmitter (n_chirps ≥ 3) for Doppler maps."""
        return self.radar.n_chirps >= 3

    def doppler_maps(self, i: int) -> DopplerRAMaps:
        """Frame ``i``'s chirps through the Doppler chain (:func:`xnlos_core.signal.doppler.doppler_ra_maps`),
        as the simulator processes a simulated chirp sequence, with the noise measured in the frame's own
        range–Doppler spectrum (``noise="measured"``): velocity σ does not depend on ``[recording] scale``.
        InputError when the radar has fewer than 3 chirps per transmitter."""
        cube = self.chirp_cube(i)
        with self._naming_frame(i):
            return doppler_ra_maps(cube, self.radar, noise="measured")

    def doppler_ra_map(self, i: int) -> RAMap:
        """Frame ``i``'s RA map with velocity and velocity σ per cell: the strongest Doppler bin of each
        cell (``peak_power``, the map a simulated Doppler frame carries) from :meth:`doppler_maps`."""
        maps = self.doppler_maps(i)
        return dataclasses.replace(maps.ra_map("peak_power"), velocity=maps.velocity, velocity_std=maps.velocity_std)

    def check(self, i: int = 0) -> RAMap:
        """Run the data checks on frame ``i`` and return its RA map: the layout of DCA1000 words against
        the file's data (:func:`hardware.layout.checks.check_layout`), unsigned samples, leakage (advice
        from the data) and channel / TX order, each a :class:`RecordingWarning`."""
        src = f"{self.source} frame {i}"
        named = []
        if self.spec.format == "dca1000":
            named = check_layout(self._head_words(), self._declared_layout(), self.radar.n_channels // self.radar.n_tdm,
                                 self.radar.n_tdm, self.source, RecordingWarning)
        if self.spec.adc_offset == 0 and "recording.encoding" not in named:
            if check_unsigned(signed_words(self.raw_frame(i), self.spec.encoding), src, self.spec.format):
                named.append("recording.adc_offset")
        cube = self.chirp_cube(i).mean(axis=1)
        with self._naming_frame(i):
            ra = ra_map_from_cube(cube, self.radar)
        power = float((np.abs(cube) ** 2).sum())
        dc_share = float((np.abs(cube.mean(axis=0)) ** 2).sum() * cube.shape[0] / power) if power > 0 else None
        check_leakage(ra, src, self.spec.leakage_range, self.spec.leakage_db, dc_share, tuple(named))
        check_channel_order(decouple(range_fft(cube, self.radar), self.radar), self.radar, src,
                            skip_range=self.spec.leakage_range,
                            tx_order=None if self.chirp is None else self.chirp.tx_order)
        return ra

    def _declared_layout(self) -> Layout:
        s = self.spec
        return Layout(s.lanes, s.sampling, s.iq_order, s.iq_interleave, s.encoding, self.radar.n_samples)

    def _head_words(self) -> np.ndarray:
        """The first int16 words of a DCA1000 file (at most :data:`hardware.layout.candidates.MAX_WORDS`)."""
        with open_regular(self.path, what=f"recording {self.path}") as f:
            data = f.read(2 * min(MAX_WORDS, self._size // 2))
        return np.frombuffer(data[:len(data) // 2 * 2], dtype="<i2")

    def frames(self, start: int = 0, max_frames: int | None = None, doppler: bool | None = None) -> Iterator[Frame]:
        """Frames ``start`` … as :class:`Frame` (timestamp i·radar.frame_interval [s]); checks the first one.

        doppler: the RA maps carry velocity and its σ (:meth:`doppler_ra_map`); None: when the radar
        has ≥ 3 chirps per transmitter (:attr:`has_doppler`), else the chirp-averaged map
        (:meth:`ra_map`). True with fewer chirps is a ConfigError. A recording of more than one frame
        without ``[radar] frame_period`` warns (:func:`check_frame_period`): its frames would be stamped
        back to back, n_chirps·n_tdm·T_c apart, which a capture's frame periodicity rarely is.
        """
        if doppler is None:
            doppler = self.has_doppler
        elif doppler and not self.has_doppler:
            raise ConfigError(f"{self.source}: Doppler maps need n_chirps ≥ 3 chirps per transmitter in a frame, "
                              f"the recording's radar has n_chirps = {self.radar.n_chirps}; set doppler = false")
        stop = self._n_frames if max_frames is None else min(self._n_frames, start + max_frames)
        if stop - start > 1:
            check_frame_period(self.radar, self.source)
        for i in range(start, stop):
            ra = self.check(i) if i == start else None
            if doppler:
                ra = self.doppler_ra_map(i)
            elif ra is None:
                ra = self.ra_map(i)
            yield Frame(ra, timestamp=i * self.radar.frame_interval, index=i,
                        meta={"recording": str(self.path), "frame": i})


class FramePeriodWarning(RecordingWarning):
    """A recording's frames are stamped with a frame period that its description does not state."""


def check_frame_period(radar: RadarConfig, source: str) -> bool:
    """Warn (:class:`FramePeriodWarning`) when ``radar.frame_period`` is unset: the frames are then
    stamped back to back, n_chirps·n_tdm·T_c apart (``radar.frame_interval``), while a capture repeats
    its frames at the chip's frame periodicity, usually much longer (a 23.5 ms burst every 100 ms or
    2 s). Timestamps set the time step of every tracker and the velocities it reports, so a wrong one
    scales them silently. Returns True when it warned."""
    if radar.frame_period is not None:
        return False
    import warnings

    warnings.warn(f"{source}: [radar] frame_period is not set, so the frames are stamped back to back, "
                  f"n_chirps·n_tdm·T_c = {radar.frame_interval:.6g} s apart; a capture's frames repeat at the "
                  "frame periodicity its radar was configured with (e.g. frameCfg's periodicity), usually longer. "
                  "Set [radar] frame_period [s] to it: timestamps set a tracker's time step and the velocities it "
                  "reports", FramePeriodWarning, stacklevel=3)
    return True
