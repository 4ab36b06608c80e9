"""Helpers for testing code against the CAN backends without hardware.

``emulated_link(radar, tx_faults=…)`` gives an opened ``can`` backend talking to a device
emulator (optionally behind a fault injector) on a private ``virtual`` channel.
``NoiseModel`` renders frames at next to no cost, for tests and benchmarks that stream many.
``make_recording(path)`` records a short hardware-in-the-loop session (emulated radar on a private
``virtual`` channel, ``can`` backend requesting the frames) to a python-can log, e.g. to run the
``replay`` backend through :func:`xnlos_core.testing.check_component`::

    from hardware.testing import make_recording
    check_component("backend", "replay", {"file": str(make_recording(tmp_path / "rec.blf"))})
"""
from __future__ import annotations

import itertools
import os
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from xnlos_core.interfaces import ForwardModel
from xnlos_core.radar import RadarConfig
from xnlos_core.types import Frame, RAMap

_counter = itertools.count()


def private_channel(prefix: str = "xnlos-test") -> str:
    """A virtual channel name no other bus in this process uses."""
    return f"{prefix}-{os.getpid()}-{next(_counter)}"


def make_recording(path: str | os.PathLike, radar: RadarConfig | None = None, frames: int = 3, seed: int = 0,
                   payload: str = "ra_complex64", frame_interval: float = 0.1) -> Path:
    """Record ``frames`` emulated frames of the built-in corner scene (``image`` model, ``seed``)
    for ``radar`` (default: RadarConfig()) to ``path`` (.blf, .asc, …) and return the path."""
    from .can_backend import CANBackend

    radar = radar or RadarConfig()
    params = {"channel": private_channel(), "emulate": "always", "record": str(path), "payload": payload,
              "frame_interval": frame_interval, "emulator": {"seed": seed, "pace": False}}
    with CANBackend(params) as backend:
        backend.open(radar)
        for _ in backend.frames(frames):
            pass
    return Path(path)


class NoiseModel(ForwardModel):
    """A forward model costing next to nothing: frame ``index`` is complex Gaussian noise (unit
    variance per component, complex64, shape (n_range_bins, n_azimuth_bins)) drawn from ``rng``,
    without ground truth. The emulator draws ``rng`` from the sequence number, so every frame is
    distinct and can be checked bit for bit (``NoiseModel().simulate(None, radar, rng_k)``)."""

    def simulate(self, scene, radar: RadarConfig, rng: np.random.Generator, timestamp: float = 0.0,
                 index: int = 0) -> Frame:
        shape = (radar.n_range_bins, radar.n_azimuth_bins)
        data = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)).astype(np.complex64)
        return Frame(RAMap(data, radar.range_axis, radar.azimuth_axis, radar), timestamp, None, index)


def small_radar(**overrides) -> RadarConfig:
    """A radar with small frames for fast link tests: 81 × 31 RA map (20 kB), 128 × 32 ADC samples."""
    kw = dict(n_samples=128, max_range=20.0, n_azimuth_bins=31)
    kw.update(overrides)
    return RadarConfig(**kw)


@contextmanager
def emulated_link(radar: RadarConfig, *, tx_faults=None, rx_faults=None, seed: int = 0, pace: bool = False,
                  status_period: float = 0.05, fc_timeout: float = 1.0, forward_model: str | ForwardModel = "image",
                  scene: dict | None = None, sensor_id: int = 0, channel: str | None = None,
                  emulator_radar: RadarConfig | None = None, **backend_params):
    """A ``can`` backend (opened) and a RadarEmulator on a private virtual channel.

    tx_faults: :class:`~hardware.faults.Fault` rules applied to what the radar sends;
    rx_faults: rules applied to what the host receives (e.g. ``bus_error``); forward_model: a
    registered name or an instance (e.g. :class:`NoiseModel` for fast streams). Backend parameters
    default to short waits (``response_timeout`` 0.2 s, ``frame_interval`` 0.05 s) but to the
    backend's own ``frame_timeout`` of 2 s, a ``timeout`` (no message at all) of 1.5 s and an
    ISO-TP flow-control wait (``fc_timeout``) of 1 s: one 20 kB transfer takes ≈ 0.08 s on an idle
    machine and over 0.5 s on a loaded one, and with the 0.3 s / 0.2 s these were before, a machine
    whose two cores ran four busy processes starved the link's threads long enough to reconnect and
    abort a frame in 11 of 12 runs of the early-stop test: shorter limits make exact-count tests
    depend on the machine's load. Tests of a timeout pass their own or outlast these. Yields
    (backend, emulator); both are closed afterwards.
    """
    from xnlos_core.registry import get_registry
    from xnlos_core.scene import load_scene

    from .can_backend import CANBackend
    from .emulator import RadarEmulator
    from .faults import wrapper
    from .link import BusSpec
    from .protocol import Protocol

    channel = channel or private_channel()
    proto = Protocol.load(None, sensor_id)
    fm = (forward_model if isinstance(forward_model, ForwardModel)
          else get_registry().create("forward_model", forward_model))
    em = RadarEmulator(fm, load_scene(scene or {"builtin": "corner"}, "emulated_link"), emulator_radar or radar,
                       BusSpec(channel=channel), sensor_id=sensor_id, seed=seed, pace=pace,
                       status_period=status_period, fc_timeout=fc_timeout,
                       bus_wrapper=wrapper(tx_faults, proto, "tx") if tx_faults else None)
    params = {"channel": channel, "sensor_id": sensor_id, "emulate": "never", "frame_interval": 0.05,
              "response_timeout": 0.2, "timeout": 1.5, "frame_timeout": 2.0, **backend_params}
    backend = CANBackend(params)
    if rx_faults:
        backend.bus_wrapper = wrapper(rx_faults, proto, "rx")
    try:
        em.start()
        backend.open(radar)
        yield backend, em
    finally:
        backend.close()
        em.stop()


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"no TOML form for {v!r}")


def write_dca1000_recording(folder: str | os.PathLike, chirp_cubes, radar: RadarConfig, *, scale: float,
                            name: str = "capture", sampling: str = "complex", lanes: int = 2,
                            encoding: str = "twos_complement", iq_order: str = "iq", iq_interleave: str = "lanes",
                            recording: dict | None = None, chirp: dict | None = None) -> Path:
    """Write frames as a DCA1000-style ``{name}_Raw_0.bin`` plus its description ``{name}.toml`` in
    ``folder``; return the TOML's path (for ``Recording.from_toml`` or the ``adc`` backend).

    chirp_cubes: per frame (n_samples, n_chirps, n_channels) complex [√W], channels tx-major (the
    layout of :func:`xnlos_core.signal.doppler.chirp_sequence_cube`); stored as round(cube/scale) int16 in
    transmission order (the real part only for ``sampling`` = "real"), in the words' ``encoding``,
    ``iq_order`` and ``iq_interleave`` (:mod:`hardware.raw_formats`). The description gives the
    waveform as a chip's profile ([chirp] slope = B/T, sample_rate = N/T) and every other field of
    ``radar`` in [radar]; ``recording`` / ``chirp`` add or replace keys of those tables.
    """
    from .raw_formats import encode_dca1000, offset_binary_words

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    n_rx = radar.n_channels // radar.n_tdm
    words = []
    for c in chirp_cubes:
        c = np.asarray(c) / scale
        slots = c.reshape(radar.n_samples, radar.n_chirps * radar.n_tdm, n_rx)  # (sample, loop·slot, rx)
        w = encode_dca1000(slots.real if sampling == "real" else slots, sampling, lanes, iq_order, iq_interleave)
        words.append(offset_binary_words(w) if encoding == "offset_binary" else w)
    data = folder / f"{name}_Raw_0.bin"
    np.concatenate(words).tofile(data)
    rec = {"file": data.name, "format": "dca1000", "sampling": sampling, "lanes": lanes, "encoding": encoding,
           "iq_order": iq_order, "iq_interleave": iq_interleave, "scale": scale, **(recording or {})}
    prof = {"slope": radar.chirp_slope, "sample_rate": radar.sample_rate, "n_samples": radar.n_samples,
            **(chirp or {})}
    skip = {"bandwidth", "chirp_duration", "n_samples"}
    rad = {k: v for k, v in radar.model_dump().items() if k not in skip and v is not None}
    text = "".join(f"[{t}]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in tab.items()) + "\n"
                   for t, tab in (("recording", rec), ("chirp", prof), ("radar", rad)))
    toml = folder / f"{name}.toml"
    toml.write_text(text, encoding="utf-8")
    return toml


def static_scene_cubes(radar: RadarConfig, frames: int = 1, seed: int = 0, amplitude: float = 1e-3,
                       noise: float = 1e-6) -> list[np.ndarray]:
    """Chirp cubes (n_samples, n_chirps, n_channels) [√W] of a static scene as a radar sees it: four
    point echoes between 15 % and 70 % of max_range at −35°, +20°, +40°, −10°, their amplitudes falling
    as R⁻² (``amplitude`` at 15 %), plus complex white noise of RMS ``noise`` [√W] per sample (seeded:
    ``seed`` + frame). For tests of layout checks and ``xnlos recording inspect``."""
    from xnlos_core.signal.doppler import chirp_sequence_cube

    frac = np.array([0.15, 0.3, 0.45, 0.7])
    r = frac * radar.max_range
    az = np.radians([-35.0, 20.0, 40.0, -10.0])
    amp = amplitude * (frac[0] / frac) ** 2 * np.exp(1j * np.arange(4))
    clean = chirp_sequence_cube(radar, r, az, amp, np.zeros(r.size))
    out = []
    for k in range(frames):
        rng = np.random.default_rng(seed + k)
        out.append(clean + noise * (rng.standard_normal(clean.shape) + 1j * rng.standard_normal(clean.shape))
                   / np.sqrt(2))
    return out


def make_adc_recording(folder: str | os.PathLike, radar: RadarConfig | None = None, frames: int = 2,
                       seed: int = 0) -> Path:
    """A small DCA1000 recording of static points (a wall's LOS returns and one farther echo) for
    ``radar`` (default: :func:`small_radar` with 2 chirp loops; frame_period 0.1 s unless ``radar``
    sets one): write it to ``folder`` and return its
    TOML description, e.g. ``check_component("backend", "adc", {"recording": str(make_adc_recording(tmp))})``."""
    from xnlos_core.signal.doppler import add_chirp_noise, chirp_sequence_cube

    radar = radar or small_radar(n_chirps=2)
    if radar.frame_period is None:  # a capture states its frame periodicity (FramePeriodWarning otherwise)
        radar = radar.model_copy(update={"frame_period": 0.1})
    xy = np.array([[17.0, 8.0], [20.0, 5.0], [23.0, 2.0], [26.0, -1.0], [30.0, 9.0]])
    r = np.hypot(xy[:, 0], xy[:, 1])
    keep = r < radar.max_range - 1.0
    clean = chirp_sequence_cube(radar, r[keep], np.arctan2(xy[keep, 1], xy[keep, 0]), np.full(keep.sum(), 1e-6),
                                np.zeros(keep.sum()))
    cubes = [add_chirp_noise(clean, radar, np.random.default_rng(seed + k)) for k in range(frames)]
    return write_dca1000_recording(folder, cubes, radar, scale=1e-6 / 2000)
