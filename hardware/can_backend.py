"""Backend ``can``: frames from a radar on any python-can interface (protocol in :mod:`hardware.protocol`).

``open(radar)`` opens the bus (and, for hardware-in-the-loop, starts an in-process
:class:`~hardware.emulator.RadarEmulator`), sends RadarModeCfg + RadarCfg and waits for the radar's
RadarState to confirm the configuration (ConfigId echoed, same RadarConfig hash).
``frames(n)`` starts a receive thread that runs the link independent of the consumer: it asks for
frames in chunks (RadarCtrl START with a frame count), reassembles each frame as its bytes arrive
(a frame's transfer time ends when its last byte arrived, however long the consumer takes) and
puts each complete, checked frame into a bounded :class:`~hardware.frame_queue.FrameQueue` of
``queue_size`` frames; the generator yields from that queue, in sequence order, each frame once,
as a :class:`~xnlos_core.types.Frame` whose RAMap carries ``radar`` (ADC cubes go through the
shared signal chain). Lost frames are reported (``stats.lost``, the log, and ``meta["lost_before"]``
of the next delivered frame) and replaced by requesting more, so ``frames(n)`` yields n frames.

A consumer slower than the radar fills the queue; ``overflow`` says what then happens:
``block`` (default) asks the radar for no more frames than the queue has room for — the radar
pauses while the consumer is behind, nothing is dropped, delivered frames are consecutive;
``drop_oldest`` / ``drop_newest`` keep the radar streaming at its own rate and drop the oldest
queued / the arriving frame. Dropped frames arrived intact and are counted as *overrun*
(``stats.frames_overrun``, ``stats.overrun_seqs``, ``meta["overrun_before"]`` of the next
delivered frame), never as lost. Every frame the radar sent is delivered once, overrun or lost.

Frames from a real radar or a recording carry no ground truth; with the in-process emulator the
backend attaches the emulator's ground truth of each frame (a side channel in this process, not
part of the protocol), so hardware-in-the-loop runs are scored like simulated ones.

The link recovers by itself: a bus error, or a radar silent for ``timeout`` seconds, closes the
bus, reopens it, re-sends the configuration and continues the request — up to ``max_reconnects``
attempts in a row, then LinkError. Every wait is bounded. ``stats`` (:class:`LinkStats`) counts
frames ok / dropped / incomplete / corrupted / late / duplicate and link events.
"""
from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Iterator
from typing import Any, Callable, Literal

import can
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.errors import InputError
from xnlos_core.interfaces import Backend
from xnlos_core.radar import RadarConfig
from xnlos_core.types import Frame
from xnlos_core.param_paths import RELATIVE_TO_CONFIG, ConfigPath

from .assembler import FrameAssembler, LinkStats, LostFrame, on_radar_message
from .emulator import RadarEmulator
from .frame_queue import FrameQueue
from .link import BusSpec, CanLink, stop_quietly
from .protocol import (FORMAT_NAMES, Command, DeviceState, ErrorCode, LinkError, PayloadSpec, Protocol, code_name,
                       config_signals, radar_hash)

log = logging.getLogger(__name__)

RX_BACKLOG = 4096  # ISO-TP items waiting for the receive thread before new ones are discarded


class EmulatorSpec(BaseModel):
    """The in-process device emulator of hardware-in-the-loop runs."""

    model_config = ConfigDict(extra="forbid")
    forward_model: str = Field("image", description="forward model plugin that renders the frames")
    params: dict[str, Any] = Field(default_factory=dict, description="its parameters")
    scene: dict[str, Any] = Field(default_factory=lambda: {"builtin": "corner"},
                                  description="scene table as in a pipeline's [scene] (builtin or file)")
    seed: int = Field(0, ge=0, lt=2**63, description="frame k uses child k of SeedSequence(seed)")
    pace: bool = Field(True, description="send frames at frame_interval (False: as fast as the link allows)")


class CANParams(BaseModel):
    """Parameters of the ``can`` backend (times in seconds)."""

    model_config = ConfigDict(extra="forbid")
    interface: str = Field("virtual", min_length=1, description="python-can interface (socketcan, pcan, kvaser, "
                           "vector, virtual, …)")
    channel: str = Field("xnlos0", min_length=1, description="interface channel")
    bitrate: int = Field(500_000, ge=10_000, le=1_000_000, description="arbitration bit rate [bit/s]")
    data_bitrate: int = Field(5_000_000, ge=500_000, le=12_000_000, description="CAN FD data bit rate [bit/s]")
    bus_kwargs: dict[str, Any] = Field(default_factory=dict, description="extra can.Bus keyword arguments")
    sensor_id: int = Field(0, ge=0, le=7, description="identifiers are base + 0x10·sensor_id")
    dbc: ConfigPath | None = Field(None, description="DBC file (default: the packaged radar.dbc); checked on "
                                                     "open" + RELATIVE_TO_CONFIG)
    payload: Literal["ra_complex64", "adc_int16", "adc_complex64"] = Field(
        "ra_complex64", description="what the radar sends: the RA map, or the ADC cube (int16 I/Q or complex64)")
    frame_interval: float = Field(0.1, ge=0, le=3600, description="frame period requested [s]; 0 = as fast as possible")
    response_timeout: float = Field(0.5, gt=0, le=60, description="wait for RadarState after a request [s]")
    retries: int = Field(3, ge=0, le=100, description="repeats of an unanswered request")
    timeout: float = Field(2.0, gt=0, le=3600, description="radar silent this long → reconnect [s]")
    frame_timeout: float = Field(2.0, gt=0, le=3600, description="a sent frame still incomplete after this is lost [s]")
    cf_timeout: float = Field(1.0, gt=0, le=60, description="ISO-TP N_Cr: gap between consecutive frames [s]")
    max_reconnects: int = Field(5, ge=0, le=1000, description="reconnection attempts in a row before LinkError")
    chunk: int = Field(16, ge=1, le=4096, description="frames requested per START at most [frames]")
    queue_size: int = Field(16, ge=1, le=65536, description="complete frames held for a consumer that is behind "
                            "[frames] (memory: queue_size × one RA map)")
    overflow: Literal["block", "drop_oldest", "drop_newest"] = Field(
        "block", description="consumer behind and queue full: block = request no more than fits (the radar "
        "pauses; nothing dropped), drop_oldest / drop_newest = the radar keeps its rate and the oldest queued / "
        "the arriving frame is dropped and counted as overrun (never as lost)")
    record: ConfigPath | None = Field(None, description="record the bus to this python-can log (.blf, .asc) "
                                                        "while open" + RELATIVE_TO_CONFIG)
    emulate: Literal["auto", "always", "never"] = Field(
        "auto", description="run an in-process radar emulator on the bus (auto: only on the virtual interface)")
    emulator: EmulatorSpec = Field(default_factory=EmulatorSpec, description="the emulator (hardware in the loop)")


class CANBackend(Backend):
    """Frames from a radar over CAN FD (python-can + ISO-TP + DBC); emulated in-process on 'virtual'."""

    Params = CANParams

    def __init__(self, params=None):
        super().__init__(params)
        self.stats = LinkStats()
        self.bus_wrapper: Callable[[can.BusABC], can.BusABC] | None = None  # tests: fault injection
        self.emulator = None
        self.radar: RadarConfig | None = None
        self.protocol: Protocol | None = None
        self._link: CanLink | None = None
        self._recorder = None
        self._asm: FrameAssembler | None = None
        self._events: queue.Queue = queue.Queue()
        self._queued_items = 0
        self._queue = FrameQueue(self.params.queue_size, self.params.overflow, self.stats)
        self._worker: threading.Thread | None = None
        self._worker_stop = threading.Event()
        self._worker_error: BaseException | None = None
        self._lock = threading.Lock()
        self._config_id = 0
        self._request_id = 0
        self._streaming = False
        self._need_reconnect: str | None = None
        self._t_connected = 0.0
        self._protocol_problem: str | None = None
        self._unknown_logged: set[int] = set()
        self._last_progress = 0.0  # time.time() of the last header, item or advance of NextSeq
        self._streak = 0  # reconnections since the last delivered frame
        self._rx_total = 0  # radar messages seen by links already closed

    @property
    def bus_spec(self) -> BusSpec:
        p = self.params
        return BusSpec(interface=p.interface, channel=p.channel, bitrate=p.bitrate, data_bitrate=p.data_bitrate,
                       kwargs=p.bus_kwargs)

    @property
    def fmt(self):
        return FORMAT_NAMES[self.params.payload]

    def _where(self) -> str:
        return f"radar sensor {self.params.sensor_id} on {self.bus_spec.describe()}"

    # --- open / close -----------------------------------------------------------------------
    def open(self, radar: RadarConfig) -> None:
        """Connect and configure the radar for ``radar``; LinkError if it does not confirm."""
        if not isinstance(radar, RadarConfig):
            raise InputError(f"CANBackend.open: expected a RadarConfig, got {type(radar).__name__}")
        self.close()
        p = self.params
        self.radar = radar
        self.protocol = Protocol.load(p.dbc, p.sensor_id)
        self.stats = LinkStats()
        self._rx_total = 0
        self._streak = 0
        self._events = queue.Queue()
        self._queued_items = 0
        self._queue = FrameQueue(p.queue_size, p.overflow, self.stats)
        self._asm = FrameAssembler(radar, self.fmt, self.stats, p.frame_timeout, source="can", sensor_id=p.sensor_id)
        try:
            if p.record:
                from .recorder import BusRecorder

                self._recorder = BusRecorder(p.record, self.bus_spec).start()
            if p.emulate == "always" or (p.emulate == "auto" and p.interface == "virtual"):
                self._start_emulator(radar)
            self._connect(p.retries)
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Stop streaming, release the bus, stop the emulator and recorder; safe to call twice."""
        self._stop_worker()
        if self._link is not None:
            if self._streaming and self._link.is_open:  # best effort on the way out
                stop_quietly(lambda: self._send_ctrl(Command.STOP), "stop on close", log)
            self._drop_link()
        self._streaming = False
        if self.emulator is not None:
            self.emulator.stop()
            self.emulator = None
        if self._recorder is not None:
            self._recorder.stop()
            self._recorder = None

    def _start_emulator(self, radar: RadarConfig) -> None:
        from xnlos_core.registry import get_registry
        from xnlos_core.scene import load_scene

        spec = self.params.emulator
        fm = get_registry().create("forward_model", spec.forward_model, spec.params, source="can backend emulator")
        scene = load_scene(spec.scene, "can backend [emulator.scene]")
        self.emulator = RadarEmulator(fm, scene, radar, self.bus_spec, sensor_id=self.params.sensor_id,
                                      seed=spec.seed, pace=spec.pace, dbc=self.params.dbc).start()

    # --- link management -------------------------------------------------------------------
    def _connect(self, retries: int) -> None:
        p = self.params
        spec = PayloadSpec.for_radar(self.radar, self.fmt)
        self._need_reconnect = None
        self._link = CanLink(self.bus_spec, self.protocol, "host", max_item=spec.item_bytes, cf_timeout=p.cf_timeout,
                             fc_timeout=p.response_timeout, on_signal=self._on_signal, on_item=self._on_item,
                             on_event=self._on_event, bus_wrapper=self.bus_wrapper)
        self._link.open()
        self._t_connected = time.time()
        self._configure(retries)

    def _configure(self, retries: int) -> None:
        p = self.params
        self._config_id = (self._config_id + 1) & 0xFF
        cid = self._config_id
        mode, cfg = config_signals(self.radar, self.fmt, p.frame_interval, cid)
        want_hash = radar_hash(self.radar)
        self._protocol_problem = None
        for _ in range(retries + 1):
            self._link.send("RadarModeCfg", mode)
            self._link.send("RadarCfg", cfg)
            st = self._await_state(lambda s: s["ConfigId"] == cid and s["State"] != DeviceState.IDLE)
            if st is None:
                if self._need_reconnect:
                    break
                continue
            if st["State"] == DeviceState.ERROR:
                code = code_name(ErrorCode, st["ErrorCode"])
                extra = ""
                if st["ErrorCode"] == ErrorCode.CONFIG_MISMATCH:
                    extra = (f" (host RadarConfig hash 0x{want_hash:08X}, radar 0x{st['ConfigHash']:08X}: fields not "
                             "carried on the bus — windows, noise figure, calibration — differ)")
                raise LinkError(f"{self._where()} rejected the configuration: {code}{extra}")
            if st["ConfigHash"] != want_hash:
                raise LinkError(f"{self._where()} confirmed RadarConfig hash 0x{st['ConfigHash']:08X}, "
                                f"expected 0x{want_hash:08X}")
            self._streaming = False
            self._asm.known_sent(st["NextSeq"], time.time())
            return
        why = f"; {self._protocol_problem}" if self._protocol_problem else ""
        raise LinkError(f"no RadarState answer from {self._where()} within {p.response_timeout:g} s "
                        f"({retries + 1} attempt(s)){why}")

    def _reconnect(self, reason: str) -> None:
        p = self.params
        self._streak += 1
        if self._streak > max(1, p.max_reconnects):
            raise LinkError(f"{self._where()}: {self._streak - 1} reconnection(s) without a single frame "
                            f"delivered; giving up ({reason})")
        log.warning("%s: %s; reconnecting", self._where(), reason)
        self._streaming = False
        self._asm.cancel(time.time())
        last: Exception | None = None
        for attempt in range(p.max_reconnects):
            self._drop_link()
            time.sleep(min(1.0, 0.02 * 2 ** attempt))
            try:
                self._connect(retries=0)
            except LinkError as exc:
                last = exc
                log.info("%s: reconnect attempt %d failed: %s", self._where(), attempt + 1, exc)
                continue
            self.stats.reconnects += 1
            log.info("%s: reconnected (attempt %d)", self._where(), attempt + 1)
            return
        raise LinkError(f"{self._where()} lost ({reason}) and not recovered after {p.max_reconnects} "
                        f"reconnection attempt(s): {last}")

    def _drop_link(self) -> None:
        if self._link is not None:
            self._link.close()
            self._rx_total += self._link.rx_messages
            self._link = None

    def _send_ctrl(self, command: Command, n: int = 0) -> int:
        self._request_id = (self._request_id + 1) & 0xFF
        self._link.send("RadarCtrl", {"Command": int(command), "NFrames": n, "RequestId": self._request_id})
        return self._request_id

    def _request(self, n: int) -> bool:
        """START n frames; True once the radar confirms (the assembler then expects them)."""
        for _ in range(self.params.retries + 1):
            rid = self._send_ctrl(Command.START, n)
            st = self._await_state(lambda s: s["RequestId"] == rid)
            if self._need_reconnect:
                return False
            if st is None:
                continue
            if st["State"] == DeviceState.STREAMING:
                self._streaming = True
                self._last_progress = time.time()
                self._asm.expect(st["NextSeq"], n, time.time())
                return True
            log.warning("%s: START answered with state %s, error %s; reconfiguring", self._where(),
                        code_name(DeviceState, st["State"]), code_name(ErrorCode, st["ErrorCode"]))
            self._configure(self.params.retries)
        return False

    # --- events (link threads → queue) ------------------------------------------------------
    def _on_signal(self, name: str, sig: dict, t: float) -> None:
        self._events.put(("signal", name, sig, t))

    def _on_item(self, item: bytes, t: float) -> None:
        # The receive thread drains these events within milliseconds whatever the consumer does; the
        # cap only bounds memory should that thread itself be starved of CPU for long.
        with self._lock:
            if self._queued_items >= RX_BACKLOG:
                self.stats.rx_overflows += 1
                log.warning("%s: receive thread %d items behind; an item was discarded (its frame will be "
                            "reported lost)", self._where(), self._queued_items)
                return
            self._queued_items += 1
        self._events.put(("item", item, None, t))

    def _on_event(self, kind: str, detail: Any, t: float) -> None:
        self._events.put(("event", kind, detail, t))

    def _handle(self, ev) -> dict | None:
        """Apply one event; returns the RadarState signals when it was one."""
        what, a, b, t = ev
        asm, st = self._asm, self.stats
        if what == "item":
            with self._lock:
                self._queued_items -= 1
            self._last_progress = t
            asm.on_item(a, t)
            return None
        if what == "signal":
            if a == "FrameHeader" or (a == "RadarState" and (asm.sent_upto is None or b["NextSeq"] > asm.sent_upto)):
                self._last_progress = t
            on_radar_message(asm, st, a, b, t)
            if a == "RadarState":
                if self._streaming and b["State"] != DeviceState.STREAMING:
                    self._streaming = False
                    asm.cancel(t)
                return b
            if a == "RadarError":
                log.warning("%s reports error %s (frame %d)", self._where(), code_name(ErrorCode, b["ErrorCode"]),
                            b["Seq"])
            return None
        kind, detail = a, b
        st.count(kind)
        if kind == "protocol":
            self._protocol_problem = str(detail)
        if kind == "transfer_error":
            log.debug("%s: ISO-TP: %s", self._where(), detail)
        elif kind in ("e2e", "protocol"):
            log.warning("%s: %s", self._where(), detail)
        elif kind == "unknown_id":
            if detail not in self._unknown_logged and len(self._unknown_logged) < 64:
                self._unknown_logged.add(detail)
                log.warning("%s: ignoring CAN identifier 0x%03X, not in the protocol", self._where(), detail)
        elif kind == "bus_error":
            self._need_reconnect = f"bus error: {type(detail).__name__}: {detail}"
        return None

    def _step(self, timeout: float) -> dict | None:
        """Handle at most one event (waiting up to ``timeout``), then deadlines; returns a RadarState."""
        try:
            ev = self._events.get(timeout=timeout)
        except queue.Empty:
            ev = None
        state = self._handle(ev) if ev is not None else None
        # Deadlines run on arrival times: while events are still waiting, everything up to the one just
        # handled is known to have arrived, but not more (a frame whose last byte waits in the queue is
        # complete, however late this thread gets to it).
        now = ev[3] if ev is not None and not self._events.empty() else time.time()
        self._asm.poll(now)
        self.stats.messages = self._rx_total + (self._link.rx_messages if self._link is not None else 0)
        return state

    def _await_state(self, pred) -> dict | None:
        """Process events until a RadarState satisfying ``pred`` arrives or response_timeout passes."""
        deadline = time.monotonic() + self.params.response_timeout
        while (left := deadline - time.monotonic()) > 0:
            st = self._step(min(left, 0.05))
            if st is not None and pred(st):
                return st
            if self._need_reconnect:
                return None
        return None

    def _with_truth(self, frame: Frame) -> Frame:
        """Attach the in-process emulator's ground truth of this frame (never sent over the bus)."""
        if self.emulator is None:
            return frame
        gt = self.emulator.truth.pop(frame.index, None)
        if gt is None:
            return frame
        return Frame(frame.ra_map, frame.timestamp, gt, frame.index, {**frame.meta, "ground_truth": "emulator"})

    # --- frames -----------------------------------------------------------------------------
    def frames(self, max_frames: int | None = None) -> Iterator[Frame]:
        """Yield ``max_frames`` complete frames (None: until closed) in sequence order.

        The link runs in a receive thread meanwhile (see the module doc); time the consumer spends
        between two frames never counts against a frame's transfer. Frames queued but not taken
        when the generator is closed are the first of the next call.
        """
        self.check_max_frames(max_frames)
        if self._link is None:
            raise InputError("CANBackend.frames: call open(radar) first (the radar must be configured)")
        self._stop_worker()
        self._worker_stop.clear()
        self._worker_error = None
        start = self._queue.taken
        self._worker = threading.Thread(target=self._work, args=(max_frames, start), daemon=True,
                                        name=f"xnlos-can-rx-{self.params.channel}")
        self._worker.start()
        try:
            while max_frames is None or self._queue.taken - start < max_frames:
                frame = self._queue.get(timeout=0.05)
                if frame is not None:
                    yield self._with_truth(frame)
                    continue
                alive = self._worker.is_alive()  # read first: a thread that ended has set its error already
                if self._worker_error is not None:
                    raise self._worker_error
                if not alive:
                    raise LinkError(f"{self._where()}: the receive thread ended unexpectedly")
        finally:
            self._stop_worker()

    def _stop_worker(self) -> None:
        if self._worker is not None:
            self._worker_stop.set()
            self._queue.notify()
            if self._worker is not threading.current_thread():
                self._worker.join(timeout=10.0)
            self._worker = None

    def _work(self, max_frames: int | None, start: int) -> None:
        """The receive thread: link events → assembler → queue, requests, reconnection."""
        try:
            self._serve(max_frames, start)
        except BaseException as exc:  # handed to the consumer, which raises it
            self._worker_error = exc
        finally:
            if self._streaming and self._link is not None and self._link.is_open:
                try:
                    self._send_ctrl(Command.STOP)
                except LinkError as exc:
                    log.debug("stop: %s", exc)
                self._streaming = False
            if self._asm is not None:
                self._asm.cancel(time.time())
            self._queue.notify()

    def _want(self, max_frames: int | None, start: int) -> int:
        """Frames to request now: what the consumer still needs beyond what is queued or on its way,
        under ``block`` also no more than the queue has room for; at most ``chunk``."""
        p, q = self.params, self._queue
        queued = len(q)
        open_ = self._asm.open_count
        need = p.chunk if max_frames is None else max_frames - (q.taken - start) - queued
        want = need - open_
        if p.overflow == "block":
            want = min(want, p.queue_size - queued - open_)
        return min(p.chunk, want)

    def _hand_over(self) -> None:
        """Resolved frames from the assembler into the queue (by policy); lost ones are already counted."""
        while (out := self._asm.pop()) is not None:
            if isinstance(out, LostFrame):
                continue
            self._streak = 0
            if self._queue.free <= 0 and self.params.overflow == "block":
                # not reached on a working link (requests fit the queue); waiting here pauses reception
                log.info("%s: queue full, receive thread waits for the consumer", self._where())
                self._queue.put(out, self._worker_stop)
                self._last_progress = time.time()
            else:
                self._queue.put(out)

    def _serve(self, max_frames: int | None, start: int) -> None:
        p = self.params
        while not self._worker_stop.is_set():
            self._hand_over()
            if max_frames is not None and self._queue.taken - start >= max_frames:
                self._worker_stop.wait(0.05)
                continue
            if self._need_reconnect:
                self._reconnect(self._need_reconnect)
                continue
            now = time.time()
            if now - max(self._link.last_rx, self._t_connected) > p.timeout:
                self.stats.timeouts += 1
                self._reconnect(f"no message for {p.timeout:g} s")
                continue
            stall = p.timeout + p.frame_timeout + 2 * p.frame_interval
            if self._streaming and now - self._last_progress > stall:
                self.stats.timeouts += 1
                self._reconnect(f"streaming, but no frame data for {stall:g} s")
                continue
            if not self._streaming:
                want = self._want(max_frames, start)
                if want > 0 and not self._request(want):
                    if not self._need_reconnect:
                        self._need_reconnect = "START not confirmed"
                    continue
            self._step(0.05)
