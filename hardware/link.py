"""One node on the radar bus: a python-can bus whose ``Notifier`` feeds both a DBC listener and a
can-isotp ``NotifierBasedCanStack`` (CAN FD, 64-byte N_PDUs, normal 11-bit addressing).

The host role receives frame items on FrameData and sends flow control on FrameFlowControl; the
device role is the mirror image. Every wait is bounded: bus sends take a timeout, ISO-TP
reception gives up after ``cf_timeout`` without a consecutive frame (N_Cr), the sender after
``fc_timeout`` without flow control (N_Bs), and blocking sends after their own timeout.
"""
from __future__ import annotations

import atexit
import logging
import threading
import time
import weakref
from typing import Any, Callable

import can
import isotp
from pydantic import BaseModel, ConfigDict, Field

from .protocol import HOST_TO_RADAR, E2EError, LinkError, Protocol, ProtocolError

log = logging.getLogger(__name__)

ISOTP_LOGGER = "hardware.link.isotp"
# can-isotp logs every stray consecutive frame of a broken transfer at WARNING; the link counts
# them instead. Raise this logger's level back to see them.
if logging.getLogger(ISOTP_LOGGER).level == logging.NOTSET:
    logging.getLogger(ISOTP_LOGGER).setLevel(logging.ERROR)

# ISO-TP errors that end (or refuse) a transfer; UnexpectedConsecutiveFrameError only reports
# the stray remainder of one already counted.
SIGNIFICANT_ERRORS = (isotp.errors.WrongSequenceNumberError, isotp.errors.ConsecutiveFrameTimeoutError,
                isotp.errors.ReceptionInterruptedWithFirstFrameError,
                isotp.errors.ReceptionInterruptedWithSingleFrameError, isotp.errors.FrameTooLongError,
                isotp.errors.InvalidCanDataError, isotp.errors.ChangingInvalidRXDLError,
                isotp.errors.InvalidCanFdFirstFrameRXDL, isotp.errors.MissingEscapeSequenceError,
                isotp.errors.FlowControlTimeoutError, isotp.errors.OverflowError)


_LIVE: "weakref.WeakSet" = weakref.WeakSet()  # open links and running emulators


def _close_all() -> None:
    """At interpreter exit, stop what an abandoned generator or test left running (emulators first)."""
    for obj in sorted(list(_LIVE), key=lambda o: not hasattr(o, "forward_model")):
        try:
            obj.stop() if hasattr(obj, "forward_model") else obj.close()
        except Exception:  # exit path: nothing useful to report
            pass


atexit.register(_close_all)


def stop_quietly(step: Callable[[], Any], what: str, logger: logging.Logger) -> None:
    """Run one teardown ``step``; what it raises is logged at DEBUG on ``logger`` as ``what``, not
    raised: a close must release everything else however this step fails."""
    try:
        step()
    except Exception as exc:
        logger.debug("%s: %s", what, exc)


def track(obj) -> None:
    """Register an open link or a running emulator for shutdown at interpreter exit."""
    _LIVE.add(obj)


def untrack(obj) -> None:
    _LIVE.discard(obj)


class BusSpec(BaseModel):
    """Which python-can interface to open. The radar protocol needs CAN FD.

    interface: any python-can interface name (socketcan, pcan, kvaser, vector, virtual, …);
    channel: the interface's channel (``can0``, ``PCAN_USBBUS1``, a virtual channel name);
    bitrate / data_bitrate: nominal (arbitration) and data-phase bit rates [bit/s], ignored
    by ``virtual``; kwargs: extra keyword arguments for ``can.Bus`` (e.g. PCAN timing).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)
    interface: str = Field("virtual", min_length=1, description="python-can interface name")
    channel: str = Field("xnlos0", min_length=1, description="interface channel")
    bitrate: int = Field(500_000, ge=10_000, le=1_000_000, description="arbitration bit rate [bit/s]")
    data_bitrate: int = Field(5_000_000, ge=500_000, le=12_000_000, description="CAN FD data bit rate [bit/s]")
    kwargs: dict[str, Any] = Field(default_factory=dict, description="extra can.Bus keyword arguments")

    def describe(self) -> str:
        return f"{self.interface}:{self.channel}"


def open_bus(spec: BusSpec) -> can.BusABC:
    """Open ``spec`` as a CAN FD bus; LinkError naming the interface and channel on failure."""
    try:
        if spec.interface == "virtual":
            return can.Bus(interface="virtual", channel=spec.channel, protocol=can.CanProtocol.CAN_FD,
                           **spec.kwargs)
        return can.Bus(interface=spec.interface, channel=spec.channel, fd=True, bitrate=spec.bitrate,
                       data_bitrate=spec.data_bitrate, **spec.kwargs)
    except can.CanInterfaceNotImplementedError as exc:
        raise LinkError(f"CAN interface {spec.interface!r} is not available ({exc}); python-can knows "
                        f"{', '.join(sorted(can.VALID_INTERFACES))}") from None
    except (can.CanError, OSError, ValueError, TypeError, ImportError) as exc:
        raise LinkError(f"cannot open CAN bus {spec.describe()}: {type(exc).__name__}: {exc}") from None


def isotp_params(max_item: int, cf_timeout: float, fc_timeout: float) -> dict[str, Any]:
    """can-isotp parameters of the frame channel: CAN FD with bit-rate switch, 64-byte N_PDUs,
    no block limit (BS = 0, STmin = 0), ``max_item`` bytes at most (larger first frames are
    refused with an overflow flow control, nothing allocated), N_Cr / N_Bs timeouts [s]."""
    return dict(can_fd=True, bitrate_switch=True, tx_data_length=64, tx_data_min_length=8, blocksize=0,
                stmin=0, max_frame_size=int(max_item), blocking_send=True, tx_padding=0,
                rx_consecutive_frame_timeout=max(1, int(round(cf_timeout * 1000))),
                rx_flowcontrol_timeout=max(1, int(round(fc_timeout * 1000))), logger_name=ISOTP_LOGGER)


class _Listener(can.Listener):
    def __init__(self, link: "CanLink"):
        self.link = link

    def on_message_received(self, msg: can.Message) -> None:
        self.link._on_message(msg)

    def on_error(self, exc: Exception) -> None:
        self.link._on_bus_error(exc)

    def stop(self) -> None:
        pass


class CanLink:
    """A host or device endpoint of the radar protocol on one bus.

    Callbacks run on the link's threads and must be quick: ``on_signal(name, signals, t)`` for
    decoded signal messages from the peer, ``on_item(bytes, t)`` for complete ISO-TP items
    (host role), ``on_event(kind, detail, t)`` for ``unknown_id``, ``other_sensor``, ``e2e``,
    ``protocol``, ``error_frame``, ``bus_error`` and ``transfer_error``. ``t`` is ``time.time()``.
    ``bus_wrapper`` (tests, benchmarks) wraps the opened bus, e.g. in a fault injector.
    """

    def __init__(self, spec: BusSpec, protocol: Protocol, role: str, *, max_item: int,
                 cf_timeout: float = 1.0, fc_timeout: float = 1.0,
                 on_signal: Callable[[str, dict, float], None] | None = None,
                 on_item: Callable[[bytes, float], None] | None = None,
                 on_event: Callable[[str, Any, float], None] | None = None,
                 bus_wrapper: Callable[[can.BusABC], can.BusABC] | None = None):
        if role not in ("host", "device"):
            raise ValueError(f"CanLink role must be 'host' or 'device', got {role!r}")
        self.spec, self.protocol, self.role = spec, protocol, role
        self.max_item, self.cf_timeout, self.fc_timeout = max_item, cf_timeout, fc_timeout
        self.on_signal, self.on_item, self.on_event = on_signal, on_item, on_event
        self.bus_wrapper = bus_wrapper
        self.bus: can.BusABC | None = None
        self.notifier: can.Notifier | None = None
        self.stack: isotp.NotifierBasedCanStack | None = None
        self._pump: threading.Thread | None = None
        self._stop = threading.Event()
        self._bus_failed = False
        self._send_lock = threading.Lock()
        self.last_rx = 0.0  # time.time() of the last message from the peer
        self.rx_messages = 0
        self._peer_ids = ({protocol.ids[n] for n in ("RadarState", "RadarError", "FrameHeader")} | {protocol.data_id}
                          if role == "host" else {protocol.ids[n] for n in HOST_TO_RADAR} | {protocol.flow_id})

    # --- life cycle -----------------------------------------------------------------------
    def open(self) -> "CanLink":
        """Open the bus, start the Notifier, the ISO-TP stack and (host) the item pump."""
        if self.bus is not None:
            return self
        bus = open_bus(self.spec)
        if self.bus_wrapper is not None:
            bus = self.bus_wrapper(bus)
        self.bus = bus
        track(self)
        self._stop.clear()
        self._bus_failed = False
        try:
            self.notifier = can.Notifier(bus, [_Listener(self)], timeout=0.05)
            p = self.protocol
            tx, rx = (p.flow_id, p.data_id) if self.role == "host" else (p.data_id, p.flow_id)
            addr = isotp.Address(isotp.AddressingMode.Normal_11bits, txid=tx, rxid=rx)
            self.stack = isotp.NotifierBasedCanStack(
                bus, self.notifier, address=addr, error_handler=self._on_isotp_error,
                params=isotp_params(self.max_item, self.cf_timeout, self.fc_timeout), read_timeout=0.02)
            self.stack.start()
            if self.role == "host":
                self._pump = threading.Thread(target=self._pump_items, name=f"xnlos-isotp-pump-{self.spec.channel}",
                                              daemon=True)
                self._pump.start()
        except Exception:
            self.close()
            raise
        return self

    def close(self) -> None:
        """Stop threads and release the bus; safe to call twice."""
        untrack(self)
        self._stop.set()
        if self._pump is not None:
            self._pump.join(timeout=1.0)
            self._pump = None
        if self.stack is not None:
            stop_quietly(self.stack.stop, "isotp stack stop", log)
            self.stack = None
        if self.notifier is not None:
            stop_quietly(lambda: self.notifier.stop(timeout=1.0), "notifier stop", log)
            self.notifier = None
        if self.bus is not None:
            stop_quietly(self.bus.shutdown, "bus shutdown", log)
            self.bus = None

    @property
    def is_open(self) -> bool:
        return self.bus is not None and not self._bus_failed

    # --- sending --------------------------------------------------------------------------
    def send(self, name: str, signals: dict[str, Any], timeout: float = 0.2) -> None:
        """Encode and send one signal message; LinkError when the bus refuses it."""
        if self.bus is None:
            raise LinkError(f"{self.spec.describe()}: link is closed")
        try:
            with self._send_lock:
                msg = self.protocol.encode(name, signals)
                self.bus.send(msg, timeout=timeout)
        except (can.CanError, OSError) as exc:
            raise LinkError(f"{self.spec.describe()}: sending {name} failed: {exc}") from None

    def send_raw(self, msg: can.Message, timeout: float = 0.2) -> None:
        """Send a prepared CAN message (tests: unknown identifiers, hand-made frames)."""
        if self.bus is None:
            raise LinkError(f"{self.spec.describe()}: link is closed")
        with self._send_lock:
            self.bus.send(msg, timeout=timeout)

    def send_item(self, item: bytes, timeout: float) -> None:
        """Send one ISO-TP item and wait until its last consecutive frame left (device role).

        Raises LinkError when the receiver does not answer with flow control or the transfer
        does not finish within ``timeout`` seconds.
        """
        if self.stack is None:
            raise LinkError(f"{self.spec.describe()}: link is closed")
        try:
            self.stack.send(item, send_timeout=timeout)
        except isotp.errors.BlockingSendFailure as exc:
            raise LinkError(f"{self.spec.describe()}: ISO-TP transfer of {len(item)} bytes failed: "
                            f"{type(exc).__name__}: {exc}") from None

    # --- receiving (link threads) ---------------------------------------------------------
    def _on_message(self, msg: can.Message) -> None:
        now = time.time()
        aid = msg.arbitration_id
        if msg.is_error_frame:
            self._event("error_frame", msg, now)
            return
        if msg.is_extended_id:
            self._event("unknown_id", aid, now)
            return
        if aid in self._peer_ids:
            self.last_rx = now
            self.rx_messages += 1
            if aid == self.protocol.data_id or aid == self.protocol.flow_id:
                return  # ISO-TP: the stack has its own listener on the same Notifier
        elif aid == self.protocol.data_id or aid == self.protocol.flow_id:
            return  # our own direction of the ISO-TP channel
        kind = self.protocol.classify(aid)
        if kind != "signal":
            self._event(kind if kind in ("other_sensor",) else "unknown_id", aid, now)
            return
        try:
            name, sig = self.protocol.decode(msg)
        except E2EError as exc:
            self._event("e2e", exc, now)
            return
        except ProtocolError as exc:
            self._event("protocol", exc, now)
            return
        if (name in HOST_TO_RADAR) == (self.role == "host"):
            return  # another node of our own role (or our own message echoed)
        if self.on_signal is not None:
            self.on_signal(name, sig, now)

    def _on_bus_error(self, exc: Exception) -> None:
        if not self._bus_failed:
            self._bus_failed = True
            self._event("bus_error", exc, time.time())
        time.sleep(0.02)  # a dead bus raises on every recv: do not spin until the owner reconnects

    def _on_isotp_error(self, exc: Exception) -> None:
        if isinstance(exc, SIGNIFICANT_ERRORS):
            self._event("transfer_error", exc, time.time())

    def _event(self, kind: str, detail: Any, t: float) -> None:
        if self.on_event is not None:
            self.on_event(kind, detail, t)

    def _pump_items(self) -> None:
        stack = self.stack
        while not self._stop.is_set() and stack is not None:
            data = stack.recv(block=True, timeout=0.05)
            if data is not None and self.on_item is not None:
                self.on_item(bytes(data), time.time())
