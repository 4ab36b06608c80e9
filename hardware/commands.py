"""``xnlos emulate``, ``xnlos recording inspect`` and ``xnlos calibrate``, added through the
``xnlos_add_commands`` hook."""
from __future__ import annotations

import argparse
import math
from pathlib import Path

from xnlos_core import hookimpl


@hookimpl
def xnlos_add_commands(subparsers) -> None:
    """``xnlos emulate`` (a radar device emulator on a CAN bus, hardware in the loop), ``xnlos recording
    inspect`` (a .bin's layout from its data) and ``xnlos calibrate`` (per-channel gains)."""
    e = subparsers.add_parser("emulate", help="run a radar device emulator on a CAN bus (hardware in the loop)")
    e.add_argument("--interface", default="virtual", help="python-can interface (default: virtual)")
    e.add_argument("--channel", default="xnlos0", help="interface channel (default: xnlos0)")
    e.add_argument("--sensor-id", type=int, default=0, help="radar sensor id 0-7 (identifier offset 0x10*id)")
    e.add_argument("--config", type=Path, help="pipeline TOML giving radar, scene, forward model, seed, frame period")
    e.add_argument("--frames", type=int, help="frames to stream (client) or to serve before exiting")
    e.add_argument("--duration", type=float, help="serve this many seconds, then exit")
    e.add_argument("--record", type=Path, help="record the bus to a python-can log (.blf, .asc)")
    e.add_argument("--client", action=argparse.BooleanOptionalAction, default=None,
                   help="also run a 'can' backend in this process that requests the frames "
                        "(default: on for the virtual interface, which other processes cannot reach)")
    e.add_argument("--payload", default="ra_complex64", choices=["ra_complex64", "adc_int16", "adc_complex64"],
                   help="what the client asks the radar to send")
    e.add_argument("--fast", action="store_true",
                   help="send frames as fast as the link allows, not at the frame period")
    e.set_defaults(func=cmd_emulate)
    r = subparsers.add_parser("recording", help="raw radar recordings (DCA1000 .bin)")
    rsub = r.add_subparsers(dest="recording_command", required=True)
    i = rsub.add_parser("inspect", help="tell a DCA1000 .bin's layout from its data: best and runner-up layouts "
                                        "with scores and a [recording]/[chirp] table to paste")
    i.add_argument("file", type=Path, help="the .bin capture")
    i.add_argument("--radar", type=Path, required=True,
                   help="TOML with [radar] n_tx, n_rx (and optionally [chirp] n_samples, [radar] n_chirps, "
                        "[recording]): a whole recording description or a partial one")
    i.set_defaults(func=cmd_recording_inspect)

    add_calibrate(subparsers)


def add_calibrate(subparsers) -> None:
    """``xnlos calibrate``: per-channel gains of a recording from a corner-reflector capture."""
    c = subparsers.add_parser("calibrate", help="measure a recording's per-channel gain and phase on a corner "
                                                "reflector; prints the [recording] calibration line")
    c.add_argument("recording", type=Path, help="TOML description of the corner-reflector capture")
    c.add_argument("--azimuth", type=float, default=0.0, help="the reflector's azimuth [deg] (default 0)")
    c.add_argument("--elevation", type=float, default=0.0, help="the reflector's elevation [deg] (default 0)")
    c.add_argument("--range", type=float, help="the reflector's range [m] (default: the strongest bin)")
    c.add_argument("--frames", type=int, default=1, help="frames averaged (default 1)")
    c.set_defaults(func=cmd_calibrate)


def cmd_calibrate(args: argparse.Namespace) -> int:
    print(calibrate_command(args.recording, args.azimuth, args.elevation, args.frames, args.range))
    return 0


def cmd_emulate(args: argparse.Namespace) -> int:
    from .emulate import run_emulate

    summary = run_emulate(interface=args.interface, channel=args.channel, sensor_id=args.sensor_id,
                          config=args.config, frames=args.frames, duration=args.duration, record=args.record,
                          client=args.client, payload=args.payload, pace=not args.fast, echo=print)
    print(f"{summary['frames_sent']} frame(s) sent in {summary['seconds']:.2f} s")
    return 0


def cmd_recording_inspect(args: argparse.Namespace) -> int:
    from .layout.inspect import inspect_file, report_text

    print(report_text(inspect_file(args.file, args.radar), str(args.file)), end="")
    return 0


def calibrate_command(recording_toml, azimuth_deg: float = 0.0, elevation_deg: float = 0.0, frames: int = 1,
                      range_m: float | None = None) -> str:
    """``xnlos calibrate``: the ``calibration = …`` line for ``[recording]`` measured on the corner-reflector
    capture ``recording_toml`` describes (reflector at ``azimuth_deg``, ``elevation_deg`` [deg]; at the
    range bin nearest ``range_m`` [m], else the strongest), after a comment naming where it was measured."""
    import numpy as np

    from .calibration import calibration_table, channel_profiles, estimate_calibration, reflector_bin
    from .recording import Recording

    rec = Recording.from_toml(recording_toml)
    x = channel_profiles(rec, frames)
    k = reflector_bin(rec, x) if range_m is None else int(np.argmin(np.abs(rec.radar.range_axis - range_m)))
    g = estimate_calibration(rec, math.radians(azimuth_deg), math.radians(elevation_deg), frames, range_bin=k)
    return (f"# corner reflector at {rec.radar.range_axis[k]:.4g} m (range bin {k}), azimuth {azimuth_deg:g}°, "
            f"elevation {elevation_deg:g}°, {min(frames, rec.n_frames)} frame(s); paste into [recording]\n"
            f"calibration = {calibration_table(g)}")
