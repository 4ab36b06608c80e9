"""``xnlos emulate`` and ``xnlos recording inspect``, added through the ``xnlos_add_commands`` hook."""
from __future__ import annotations

import argparse
from pathlib import Path

from xnlos_core import hookimpl


@hookimpl
def xnlos_add_commands(subparsers) -> None:
    """``xnlos emulate``: a radar device emulator on a CAN bus (hardware in the loop)."""
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
