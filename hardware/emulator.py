"""A radar device emulator that speaks the xnlos CAN protocol, driven by any forward model plugin.

:class:`RadarEmulator` sits on a python-can bus exactly where the FPGA radar would: it answers
RadarCfg/RadarModeCfg with RadarState, starts and stops measurements on RadarCtrl, sends
RadarState cyclically, and streams each frame as a FrameHeader followed by one ISO-TP transfer.
Frame ``seq`` is rendered with ``forward_model.simulate(scene, radar, rng_seq, seq · period, seq)``
where ``rng_seq`` is child ``seq`` of ``SeedSequence(seed)`` — the same frame the simulator
pipeline produces as frame ``seq`` with the same seed and period, so hardware-in-the-loop runs
can be compared bit for bit with simulated ones.

The emulator only accepts a configuration whose RadarConfig hash matches the radar it would build
(its own ``radar`` with the bus fields applied): fields the bus does not carry are device
properties. :func:`run_emulate` is the ``xnlos emulate`` command.
"""
from __future__ import annotations

import logging
import queue
import threading
import time
from pathlib import Path
from typing import Any, Callable

import can
import numpy as np

from xnlos_core.errors import ConfigError
from xnlos_core.interfaces import ForwardModel
from xnlos_core.radar import RadarConfig

from .link import BusSpec, CanLink, track, untrack
from .protocol import (CONTINUOUS, SEQ_PREFIX, Command, DeviceState, ErrorCode, LinkError, PayloadFormat,
                       PayloadSpec, Protocol, ProtocolError, encode_payload, payload_crc32, radar_from_signals,
                       radar_hash)

log = logging.getLogger(__name__)


class RadarEmulator:
    """An emulated radar on ``bus`` (a BusSpec) for sensor ``sensor_id``.

    forward_model: any ForwardModel plugin instance (ADC payloads need ``simulate_adc``);
    scene: an :class:`xnlos_core.scene.Scene`; radar: the device's RadarConfig (its properties
    not carried on the bus must match the host's); seed: frame k uses child k of
    ``SeedSequence(seed)``; pace: send frames at the configured period (False: as fast as the
    link allows, timestamps still k·period); status_period [s] of the cyclic RadarState;
    send_timeout [s] for one ISO-TP transfer; fc_timeout [s]: ISO-TP N_Bs, how long a transfer waits
    for the host's flow control; bus_wrapper: wraps the bus (fault injection).

    Use as a context manager or call :meth:`start` / :meth:`stop`. ``frames_sent`` counts frames
    whose transfer completed; :meth:`silence` makes the device stop answering for a while;
    ``truth`` maps the sequence numbers of recent frames to their GroundTruth (for an in-process
    host; ground truth never goes over the bus).
    """

    def __init__(self, forward_model: ForwardModel, scene, radar: RadarConfig, bus: BusSpec | None = None,
                 *, sensor_id: int = 0, seed: int = 0, pace: bool = True, status_period: float = 0.1,
                 send_timeout: float = 10.0, fc_timeout: float = 1.0, dbc: str | None = None,
                 bus_wrapper: Callable[[can.BusABC], can.BusABC] | None = None):
        if not isinstance(forward_model, ForwardModel):
            raise ConfigError(f"RadarEmulator: forward_model must be a ForwardModel plugin, got "
                              f"{type(forward_model).__name__}")
        self.forward_model = forward_model
        self.scene = scene
        self.base_radar = radar
        self.radar = radar
        self.bus_spec = bus or BusSpec()
        self.protocol = Protocol.load(dbc, sensor_id)
        self.seed = int(seed)
        self.pace = pace
        self.status_period = float(status_period)
        self.send_timeout = float(send_timeout)
        self.fc_timeout = float(fc_timeout)
        self.bus_wrapper = bus_wrapper

        self.state = DeviceState.IDLE
        self.error = ErrorCode.NONE
        self.config_id = 0
        self.config_hash = 0
        self.fmt = PayloadFormat.RA_COMPLEX64
        self.frame_interval = 0.1
        self.next_seq = 0
        self.remaining = 0
        self.frames_sent = 0
        self.frames_failed = 0
        self.request_id = 0
        self.sent_log: list[int] = []  # sequence numbers sent, in order (latest 10 000)
        self.on_frame: Callable[[int, Any], None] | None = None  # called after each frame with (seq, Frame)
        self.truth: dict[int, Any] = {}  # seq → GroundTruth of the latest frames (in-process side channel)

        self._pending_mode: dict[int, dict] = {}
        self._cmds: queue.Queue = queue.Queue()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._silent_until = 0.0
        self._needs_reset = False
        self._state_lock = threading.Lock()
        self._status: threading.Thread | None = None
        self._silence_after: tuple[int, float] | None = None
        self._t0 = time.monotonic()
        self._next_frame = 0.0
        self.link: CanLink | None = None

    # --- life cycle -----------------------------------------------------------------------
    def start(self) -> "RadarEmulator":
        """Open the bus and start the device thread."""
        if self._thread is not None:
            return self
        spec = PayloadSpec.for_radar(self.base_radar, PayloadFormat.RA_COMPLEX64)
        max_item = max(spec.item_bytes, SEQ_PREFIX.size + self.base_radar.n_samples * self.base_radar.n_channels * 8)
        self.link = CanLink(self.bus_spec, self.protocol, "device", max_item=max_item, fc_timeout=self.fc_timeout,
                            on_signal=self._on_signal, on_event=self._on_event, bus_wrapper=self.bus_wrapper)
        self.link.open()
        track(self)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"xnlos-emulator-{self.bus_spec.channel}", daemon=True)
        self._thread.start()
        self._status = threading.Thread(target=self._status_loop, name=f"xnlos-emulator-status-{self.bus_spec.channel}",
                                        daemon=True)
        self._status.start()
        log.info("radar emulator %d up on %s (%s)", self.protocol.sensor_id, self.bus_spec.describe(),
                 type(self.forward_model).__name__)
        return self

    def stop(self) -> None:
        """Stop the device thread and release the bus; safe to call twice."""
        untrack(self)
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=self.send_timeout + 2.0)
            self._thread = None
        if self._status is not None:
            self._status.join(timeout=2.0)
            self._status = None
        if self.link is not None:
            self.link.close()
            self.link = None

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()

    def silence(self, duration: float, after_seq: int | None = None) -> None:
        """Stop answering for ``duration`` s (now, or right after frame ``after_seq`` was sent).

        While silent the device sends nothing and ignores every request; afterwards it comes
        back like after a watchdog reset: IDLE, unconfigured, sequence numbering continued.
        """
        if after_seq is None:
            with self._state_lock:
                self._silent_until = time.monotonic() + duration
                self._needs_reset = True
        else:
            self._silence_after = (after_seq, duration)

    @property
    def silent(self) -> bool:
        return time.monotonic() < self._silent_until

    # --- link callbacks (link threads) ------------------------------------------------------
    def _on_signal(self, name: str, sig: dict, t: float) -> None:
        self._cmds.put((name, sig))

    def _on_event(self, kind: str, detail: Any, t: float) -> None:
        if kind in ("e2e", "protocol"):
            self._cmds.put(("_bad", (kind, detail)))

    # --- device thread ----------------------------------------------------------------------
    def _awake(self) -> bool:
        """False while silent; the first call after a silence performs the reset."""
        with self._state_lock:
            if time.monotonic() < self._silent_until:
                self._needs_reset = True
                return False
            if self._needs_reset:
                self._needs_reset = False
                self._reset()
            return True

    def _run(self) -> None:
        while not self._stop.is_set():
            wait = 0.05
            if self.state == DeviceState.STREAMING:
                wait = min(wait, max(0.0, self._next_frame - time.monotonic()))
            try:
                item = self._cmds.get(timeout=wait)
            except queue.Empty:
                item = None
            if not self._awake():
                continue  # requests are lost, nothing is sent
            try:
                if item is not None:
                    self._handle(*item)
                now = time.monotonic()
                if self.state == DeviceState.STREAMING and now >= self._next_frame and self._cmds.empty():
                    self._send_frame()
                    self._next_frame = (max(self._next_frame + self.frame_interval, now) if self.pace
                                        else time.monotonic())
            except LinkError as exc:
                log.warning("radar emulator: %s", exc)
                time.sleep(0.01)

    def _status_loop(self) -> None:
        """Cyclic RadarState, independent of frame transfers (as a radar's status task)."""
        while not self._stop.wait(self.status_period):
            if not self._awake():
                continue
            try:
                self._send_state()
            except LinkError as exc:
                log.debug("radar emulator status: %s", exc)

    def _reset(self) -> None:
        log.info("radar emulator %d: back after silence (reset: IDLE)", self.protocol.sensor_id)
        self.state, self.error, self.config_id, self.remaining = DeviceState.IDLE, ErrorCode.NONE, 0, 0
        self._pending_mode.clear()
        with self._cmds.mutex:
            self._cmds.queue.clear()

    def _handle(self, name: str, sig: Any) -> None:
        if name == "_bad":
            kind, exc = sig
            code = ErrorCode.PROTOCOL_VERSION if kind == "protocol" else ErrorCode.E2E
            self._send_error(code, 0)
            return
        if name == "RadarModeCfg":
            self._pending_mode[sig["ConfigId"]] = sig
            return
        if name == "RadarCfg":
            self._configure(sig)
            return
        if name == "RadarCtrl":
            self.request_id = sig["RequestId"]
            cmd = sig["Command"]
            if cmd == Command.START:
                if self.state not in (DeviceState.CONFIGURED, DeviceState.STREAMING):
                    self.error = ErrorCode.NOT_CONFIGURED
                    self._send_error(ErrorCode.NOT_CONFIGURED, self.next_seq)
                else:
                    n = int(sig["NFrames"])
                    self.remaining = CONTINUOUS if n == 0 else n
                    self.state = DeviceState.STREAMING
                    self.error = ErrorCode.NONE
                    self._next_frame = time.monotonic()
            elif cmd == Command.STOP and self.state == DeviceState.STREAMING:
                self.state, self.remaining = DeviceState.CONFIGURED, 0
            self._send_state()

    def _configure(self, sig: dict) -> None:
        cid = sig["ConfigId"]
        mode = self._pending_mode.pop(cid, None)
        self.config_id = cid
        if self.state == DeviceState.STREAMING:
            self.remaining = 0
        try:
            radar = radar_from_signals(self.base_radar, sig, mode)
            fmt = PayloadFormat(sig["PayloadFormat"])
        except (ProtocolError, ValueError) as exc:
            self._reject(ErrorCode.CONFIG_MISMATCH, f"invalid configuration: {exc}")
            return
        h = radar_hash(radar)
        if h != sig["ConfigHash"]:
            self.config_hash = h
            self._reject(ErrorCode.CONFIG_MISMATCH, f"host RadarConfig hash 0x{sig['ConfigHash']:08X} ≠ device "
                         f"0x{h:08X}")
            return
        if fmt != PayloadFormat.RA_COMPLEX64 and not hasattr(self.forward_model, "simulate_adc"):
            self._reject(ErrorCode.UNSUPPORTED_FORMAT, f"{type(self.forward_model).__name__} has no simulate_adc; "
                         f"{fmt.name} needs ADC cubes")
            return
        self.radar, self.fmt, self.config_hash = radar, fmt, h
        if mode is not None:
            self.frame_interval = float(mode["FrameInterval"])
        self.state, self.error = DeviceState.CONFIGURED, ErrorCode.NONE
        log.info("radar emulator %d: configured (id %d, %s, %dx%d, period %g s)", self.protocol.sensor_id, cid,
                 fmt.name, *PayloadSpec.for_radar(radar, fmt).shape, self.frame_interval)
        self._send_state()

    def _reject(self, code: ErrorCode, why: str) -> None:
        log.warning("radar emulator %d: configuration rejected: %s", self.protocol.sensor_id, why)
        self.state, self.error = DeviceState.ERROR, code
        self._send_state()
        self._send_error(code, self.next_seq)

    def _send_state(self) -> None:
        self.link.send("RadarState", {
            "State": int(self.state), "PayloadFormat": int(self.fmt), "ConfigId": self.config_id,
            "ConfigHash": self.config_hash, "NextSeq": self.next_seq & 0xFFFFFFFF,
            "FramesRemaining": min(self.remaining, CONTINUOUS), "ErrorCode": int(self.error),
            "RequestId": self.request_id, "Uptime": round(time.monotonic() - self._t0, 3) % 4294967.0,
            "Temperature": 45})

    def _send_error(self, code: ErrorCode, seq: int) -> None:
        self.link.send("RadarError", {"ErrorCode": int(code), "Seq": seq & 0xFFFFFFFF, "Detail": 0})

    def render(self, seq: int) -> tuple[bytes, dict, Any]:
        """(payload, FrameHeader signals, Frame) of frame ``seq`` under the current configuration."""
        rng = np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=(seq,)))
        t = seq * self.frame_interval
        cube = None
        if self.fmt == PayloadFormat.RA_COMPLEX64:
            frame = self.forward_model.simulate(self.scene, self.radar, rng, timestamp=t, index=seq)
        else:
            cube, frame = self.forward_model.simulate_adc(self.scene, self.radar, rng, timestamp=t, index=seq)
        payload, scale = encode_payload(self.fmt, self.radar, ra_map=frame.ra_map, cube=cube)
        spec = PayloadSpec.for_radar(self.radar, self.fmt)
        item = SEQ_PREFIX.pack(seq & 0xFFFFFFFF) + payload
        header = {"PayloadFormat": int(self.fmt), "ConfigId": self.config_id, "Seq": seq & 0xFFFFFFFF,
                  "Timestamp": float(t), "Shape0": spec.shape[0], "Shape1": spec.shape[1],
                  "PayloadBytes": len(payload), "PayloadCrc32": payload_crc32(item), "Scale": float(scale)}
        return item, header, frame

    def _send_frame(self) -> None:
        seq = self.next_seq
        item, header, frame = self.render(seq)
        if frame.ground_truth is not None:
            self.truth[seq] = frame.ground_truth
            while len(self.truth) > 256:
                self.truth.pop(next(iter(self.truth)))
        self.next_seq += 1
        if self.remaining != CONTINUOUS:
            self.remaining -= 1
        try:
            self.link.send("FrameHeader", header)
            self.link.send_item(item, timeout=self.send_timeout)
            self.frames_sent += 1
            self.sent_log.append(seq)
            if len(self.sent_log) > 10_000:
                del self.sent_log[:5_000]
        except LinkError as exc:
            self.frames_failed += 1
            log.warning("radar emulator %d: frame %d not delivered: %s", self.protocol.sensor_id, seq, exc)
            try:
                self._send_error(ErrorCode.FRAME_ABORTED, seq)
            except LinkError:
                pass
        if self.on_frame is not None:
            self.on_frame(seq, frame)
        if self.remaining == 0:
            self.state = DeviceState.CONFIGURED
            self._send_state()
        if self._silence_after is not None and seq >= self._silence_after[0]:
            with self._state_lock:
                self._silent_until = time.monotonic() + self._silence_after[1]
                self._needs_reset = True
            self._silence_after = None


# --- `xnlos emulate` --------------------------------------------------------------------------
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
    from .can_backend import CANBackend
    from .recorder import BusRecorder

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
