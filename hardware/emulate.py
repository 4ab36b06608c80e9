"""``xnlos emulate``: a :class:`~hardware.emulator.RadarEmulator` on a CAN bus, built from a pipeline
config, optionally with a ``can`` backend in this process as its client (hardware in the loop).

It uses both the emulator and the backend, so it lives apart from them: :mod:`hardware.can_backend`
imports :mod:`hardware.emulator` (its in-process emulator), never the other way round.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Callable

from xnlos_core.radar import RadarConfig

from .can_backend import CANBackend
from .emulator import RadarEmulator
from .link import BusSpec
from .recorder import BusRecorder


def emulator_from_config(config: str | Path | None, bus: BusSpec, *, sensor_id: int = 0, pace: bool = True,
                         seed: int | None = None) -> tuple[RadarEmulator, RadarConfig, float]:
    """(emulator, radar, frame period) from a pipeline TOML: its [radar], [scene], seed and
    run.frame_interval; the forward model is [forward_model], or a ``can`` backend's
    ``params.emulator.forward_model``, or ``image``. None: default radar, corner scene, image."""
    from xnlos_core.config import load_pipeline
    from xnlos_core.radar import load_radar
    from xnlos_core.registry import get_registry
    from xnlos_core.scene import load_scene

    reg = get_registry()
    if config is None:
        radar, interval, fm_name, fm_params = RadarConfig(), 0.1, "image", {}
        scene = load_scene({"builtin": "corner"}, "xnlos emulate")
        seed = 0 if seed is None else seed
    else:
        cfg = load_pipeline(config)
        radar = load_radar(cfg.radar, str(config), cfg.base_dir)
        interval = cfg.run.frame_interval
        scene_table = cfg.scene or {"builtin": "corner"}
        fm_name, fm_params = "image", {}
        if cfg.forward_model is not None:
            fm_name, fm_params = cfg.forward_model.name, cfg.forward_model.params
        elif cfg.backend is not None and cfg.backend.name == "can":
            spec = cfg.backend.params.get("emulator", {})
            fm_name, fm_params = spec.get("forward_model", "image"), spec.get("params", {})
            scene_table = spec.get("scene", scene_table)
            seed = spec.get("seed", cfg.seed) if seed is None else seed
        scene = load_scene(scene_table, str(config), cfg.base_dir)
        seed = cfg.seed if seed is None else seed
    fm = reg.create("forward_model", fm_name, fm_params, source=str(config or "xnlos emulate"))
    em = RadarEmulator(fm, scene, radar, bus, sensor_id=sensor_id, seed=seed, pace=pace)
    return em, radar, interval


def run_emulate(*, interface: str = "virtual", channel: str = "xnlos0", sensor_id: int = 0,
                config: str | Path | None = None, frames: int | None = None, duration: float | None = None,
                record: str | Path | None = None, client: bool | None = None, payload: str = "ra_complex64",
                pace: bool = True, bus_kwargs: dict | None = None,
                echo: Callable[[str], None] = lambda s: None) -> dict[str, Any]:
    """Run a device emulator on ``interface:channel`` (``xnlos emulate``); return a summary dict.

    Without ``client`` the emulator serves until ``frames`` frames were sent, ``duration`` s
    passed, or KeyboardInterrupt. With ``client`` (default on the in-process ``virtual``
    interface, where no other process can reach it) a ``can`` backend in this process requests
    ``frames`` frames (default 10) and the summary holds its link statistics. ``record``
    writes the bus to a python-can log (.blf, .asc, …) for the ``replay`` backend.
    """
    bus = BusSpec(interface=interface, channel=channel, kwargs=bus_kwargs or {})
    if client is None:
        client = interface == "virtual"
    em, radar, interval = emulator_from_config(config, bus, sensor_id=sensor_id, pace=pace)
    rec = BusRecorder(record, bus).start() if record else None
    summary: dict[str, Any] = {"bus": bus.describe(), "sensor_id": sensor_id}
    t0 = time.monotonic()
    try:
        em.start()
        echo(f"radar emulator (sensor {sensor_id}) on {bus.describe()}: "
             f"{radar.n_range_bins}x{radar.n_azimuth_bins} RA map, period {interval:g} s")
        if client:
            n = frames or 10
            params = {"interface": interface, "channel": channel, "sensor_id": sensor_id, "emulate": "never",
                      "frame_interval": interval, "payload": payload, "bus_kwargs": bus_kwargs or {}}
            with CANBackend(params) as backend:
                backend.open(radar)
                for f in backend.frames(n):
                    echo(f"frame {f.index:5d}  t={f.timestamp:8.3f} s  peak {f.ra_map.power_db().max():7.1f} dB")
                summary["link"] = backend.stats.as_dict()
                echo("link: " + backend.stats.summary())
        else:
            while True:
                if frames is not None and em.frames_sent >= frames:
                    break
                if duration is not None and time.monotonic() - t0 >= duration:
                    break
                time.sleep(0.05)
    finally:
        em.stop()
        if rec is not None:
            rec.stop()
            summary["recorded"] = {"file": str(record), "messages": rec.messages}
            echo(f"recorded {rec.messages} CAN messages to {record}")
    summary["frames_sent"] = em.frames_sent
    summary["seconds"] = round(time.monotonic() - t0, 3)
    return summary
