"""CAN FD link throughput: frames/s and MB/s over the python-can virtual bus, next to the CAN FD
line-rate limit for the same frame size.

    .venv/bin/python benchmarks/can_throughput.py [--frames 20] [--arb 500000] [--data 5000000]

Rows per payload (default radar: 401×121 complex64 RA map, 388 168 B; 512 × 32 int16 I/Q ADC cube,
65 536 B; 512 × 32 complex64 ADC cube, 131 072 B):

* ``isotp``    – transport only: one ISO-TP endpoint sends pre-built items from this thread, the
                 other receives them on its Notifier/stack threads (no DBC, no checks);
* ``backend``  – the ``can`` backend against the device emulator in another thread serving a
                 cached frame (protocol, header, CRC-32 and reassembly; no rendering);
* ``hil``      – the ``can`` backend against the emulator rendering every frame with the
                 ``image`` forward model (hardware in the loop).

``line`` is the CAN FD limit: ISO CAN FD frames with 11-bit identifiers, 64 data bytes, arbitration
phase (SOF, ID, RRS, IDE, FDF, res, BRS; ACK, delimiter, EOF, IFS = 29 bits) at ``--arb`` and data
phase (ESI, DLC, 512 data bits, stuff count, CRC-21 with its fixed stuff bits, CRC delimiter = 550
bits) at ``--data``; "best" without dynamic stuff bits, "worst" with the maximum (1 per 4 bits).
An item of L bytes (4-byte sequence number + payload) takes 1 first frame (58 bytes, 32-bit length
escape), ⌈(L − 58)/63⌉ consecutive frames, 1 flow control and 1 FrameHeader.

Slow consumers and bursts (delivered / overrun / lost per overflow policy): benchmarks/can_consumer.py.
"""
from __future__ import annotations

import argparse
import logging
import math
import sys
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hardware.can_backend import CANBackend  # noqa: E402
from hardware.emulator import RadarEmulator  # noqa: E402
from hardware.link import BusSpec, CanLink  # noqa: E402
from hardware.protocol import SEQ_PREFIX, PayloadFormat, PayloadSpec, Protocol  # noqa: E402
from hardware.testing import private_channel  # noqa: E402
from xnlos_core.interfaces import ForwardModel  # noqa: E402
from xnlos_core.radar import RadarConfig  # noqa: E402
from xnlos_core.registry import get_registry  # noqa: E402
from xnlos_core.scene import load_scene  # noqa: E402

FORMATS = {"ra_complex64": PayloadFormat.RA_COMPLEX64, "adc_int16": PayloadFormat.ADC_INT16,
           "adc_complex64": PayloadFormat.ADC_COMPLEX64}


def can_fd_frame_time(arb: float, data: float, worst: bool = False) -> float:
    """Seconds on the wire for one ISO CAN FD frame, 11-bit id, 64 data bytes."""
    nominal = 17 + 12 + (3 if worst else 0)
    data_bits = 1 + 4 + 512 + 4 + 21 + 7 + 1 + (129 if worst else 0)
    return nominal / arb + data_bits / data


def line_rate(item_bytes: int, arb: float, data: float, worst: bool = False) -> tuple[float, int]:
    """(frames/s, CAN frames per radar frame) at the CAN FD line rate for an item of ``item_bytes``."""
    n_cf = math.ceil(max(0, item_bytes - 58) / 63)
    n_can = 1 + n_cf + 1 + 1  # FF, CFs, FC, header (FC and header counted as full frames: upper bound)
    return 1.0 / (n_can * can_fd_frame_time(arb, data, worst)), n_can


class CachedModel(ForwardModel):
    """Serves one pre-rendered frame (and its ADC cube): the emulator without rendering cost."""

    def __init__(self, frame, cube):
        super().__init__()
        self.frame, self.cube = frame, cube

    def simulate(self, scene, radar, rng, timestamp=0.0, index=0):
        return self.frame

    def simulate_adc(self, scene, radar, rng, timestamp=0.0, index=0):
        return self.cube, self.frame


def bench_isotp(radar: RadarConfig, fmt: PayloadFormat, n: int) -> tuple[float, float]:
    spec = PayloadSpec.for_radar(radar, fmt)
    proto = Protocol.load()
    bus = BusSpec(channel=private_channel("bench-isotp"))
    got = []
    done = threading.Event()

    def on_item(item, t):
        got.append(len(item))
        if len(got) >= n:
            done.set()

    host = CanLink(bus, proto, "host", max_item=spec.item_bytes, on_item=on_item).open()
    dev = CanLink(bus, proto, "device", max_item=spec.item_bytes).open()
    item = SEQ_PREFIX.pack(0) + bytes(np.random.default_rng(0).integers(0, 256, spec.nbytes, dtype=np.uint8))
    try:
        t0 = time.perf_counter()
        for _ in range(n):
            dev.send_item(item, timeout=60)
        done.wait(60)
        dt = time.perf_counter() - t0
    finally:
        dev.close()
        host.close()
    return len(got) / dt, len(got) * spec.nbytes / dt / 1e6


def bench_backend(radar: RadarConfig, fmt_name: str, n: int, render: bool) -> tuple[float, float, str]:
    fm = get_registry().create("forward_model", "image")
    scene = load_scene({"builtin": "corner"}, "benchmark")
    if not render:
        cube, frame = fm.simulate_adc(scene, radar, np.random.default_rng(0))
        fm = CachedModel(frame, cube)
    channel = private_channel("bench-backend")
    em = RadarEmulator(fm, scene, radar, BusSpec(channel=channel), pace=False).start()
    backend = CANBackend({"channel": channel, "emulate": "never", "payload": fmt_name, "frame_interval": 0.0,
                          "chunk": 64, "queue_size": 64, "timeout": 30, "frame_timeout": 30})
    try:
        backend.open(radar)
        it = backend.frames(n + 1)
        next(it)  # warm-up: first request round trip
        t0 = time.perf_counter()
        k = sum(1 for _ in it)
        dt = time.perf_counter() - t0
        stats = backend.stats
    finally:
        backend.close()
        em.stop()
    spec = PayloadSpec.for_radar(radar, FORMATS[fmt_name])
    return k / dt, k * spec.nbytes / dt / 1e6, f"lost {stats.frames_lost}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=20, help="frames per measurement (HIL rows use half)")
    ap.add_argument("--arb", type=float, default=500e3, help="CAN FD arbitration bit rate [bit/s]")
    ap.add_argument("--data", type=float, default=5e6, help="CAN FD data bit rate [bit/s]")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.ERROR)
    radar = RadarConfig()
    print(f"radar: {radar.n_range_bins}×{radar.n_azimuth_bins} RA map, {radar.n_samples} samples × "
          f"{radar.n_channels} channels; virtual bus, {args.frames} frames per row")
    t_best = can_fd_frame_time(args.arb, args.data)
    t_worst = can_fd_frame_time(args.arb, args.data, worst=True)
    print(f"CAN FD @ {args.arb / 1e3:g} kbit/s arbitration / {args.data / 1e6:g} Mbit/s data: one 64-byte frame "
          f"{t_best * 1e6:.0f}–{t_worst * 1e6:.0f} µs → "
          f"{63 / t_best / 1e3:.0f}–{63 / t_worst / 1e3:.0f} kB/s ISO-TP payload")
    print()
    hdr = f"{'payload':<14} {'bytes':>8} {'row':<8} {'frames/s':>9} {'MB/s':>7}  note"
    print(hdr)
    print("-" * len(hdr))
    for fmt_name, fmt in FORMATS.items():
        spec = PayloadSpec.for_radar(radar, fmt)
        fps, mbs = bench_isotp(radar, fmt, args.frames)
        print(f"{fmt_name:<14} {spec.nbytes:>8} {'isotp':<8} {fps:>9.2f} {mbs:>7.2f}  transport only")
        fps, mbs, note = bench_backend(radar, fmt_name, args.frames, render=False)
        print(f"{'':<14} {'':>8} {'backend':<8} {fps:>9.2f} {mbs:>7.2f}  emulator thread, cached frame, {note}")
        fps, mbs, note = bench_backend(radar, fmt_name, max(2, args.frames // 2), render=True)
        print(f"{'':<14} {'':>8} {'hil':<8} {fps:>9.2f} {mbs:>7.2f}  emulator thread rendering (image), {note}")
        for worst in (False, True):
            lfps, n_can = line_rate(spec.item_bytes, args.arb, args.data, worst)
            print(f"{'':<14} {'':>8} {'line':<8} {lfps:>9.2f} {lfps * spec.nbytes / 1e6:>7.3f}  CAN FD limit, "
                  f"{n_can} CAN frames/frame, {'worst-case' if worst else 'no'} stuffing")
    print()
    ra = PayloadSpec.for_radar(radar, PayloadFormat.RA_COMPLEX64)
    adc = PayloadSpec.for_radar(radar, PayloadFormat.ADC_INT16)
    print(f"On a real CAN FD bus at these rates the default complex64 RA map ({ra.nbytes / 1e3:.0f} kB) is limited to "
          f"≈{line_rate(ra.item_bytes, args.arb, args.data)[0]:.2f} frames/s; the int16 ADC cube "
          f"({adc.nbytes / 1e3:.0f} kB) to ≈{line_rate(adc.item_bytes, args.arb, args.data)[0]:.1f} frames/s, "
          "with the host running the shared signal chain.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
