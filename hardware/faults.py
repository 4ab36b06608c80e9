"""Fault injection on the CAN bus for tests and benchmarks: a python-can bus wrapper.

:class:`FaultyBus` wraps any bus and applies :class:`Fault` rules to the messages it sends
(``direction="tx"``, e.g. the emulated radar's bus) or receives (``"rx"``, e.g. the host's).
Rules address protocol positions, not raw message counts, so a test states exactly what it
breaks: ``Fault("drop", seq=2, part="cf", index=3)`` drops the 4th consecutive frame of frame 2's
ISO-TP transfer. The wrapper follows frames by decoding each FrameHeader's sequence number and
each ISO-TP first frame's length.

Parts: ``header`` (the FrameHeader), ``ff`` (ISO-TP first frame), ``cf`` (consecutive frame
``index``, 0-based), ``last`` (the last consecutive frame). Kinds:

* ``drop`` – the message disappears;  ``duplicate`` – it is delivered twice;
* ``reorder`` – it swaps places with the next message;
* ``corrupt`` – one payload bit flips (data byte 8 of a CF; byte 20 of a header, so its CRC-8 fails);
* ``checksum`` – the header's PayloadCrc32 is wrong but the header itself is valid (E2E recomputed);
* ``oversize`` – the header announces an absurd payload (65535 × 65535, 4 GiB), validly encoded;
* ``truncate`` – the message and the rest of its transfer vanish (transfer cut off mid-frame);
* ``error_frame`` – a CAN error frame is delivered just before the message;
* ``bus_error`` – receiving the message raises ``can.CanOperationError`` (``rx`` only).

Each rule fires once. ``fired`` lists the rules that did, in order.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Literal, Optional

import can

from .protocol import Protocol

KINDS = ("drop", "duplicate", "reorder", "corrupt", "checksum", "oversize", "truncate", "error_frame", "bus_error")
PARTS = ("header", "ff", "cf", "last")


@dataclass
class Fault:
    """One fault: ``kind`` applied to ``part`` (``index`` for ``cf``) of frame ``seq``."""

    kind: Literal["drop", "duplicate", "reorder", "corrupt", "checksum", "oversize", "truncate", "error_frame",
                  "bus_error"]
    seq: int
    part: Literal["header", "ff", "cf", "last"] = "cf"
    index: int = 0
    done: bool = field(default=False, compare=False)

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"Fault.kind must be one of {KINDS}, got {self.kind!r}")
        if self.part not in PARTS:
            raise ValueError(f"Fault.part must be one of {PARTS}, got {self.part!r}")
        if self.kind in ("checksum", "oversize") and self.part != "header":
            raise ValueError(f"Fault kind {self.kind!r} applies to part 'header' only")


class FaultyBus(can.BusABC):
    """Wrap ``inner`` and apply ``faults`` on ``direction`` ("tx" or "rx") for the radar ``protocol``."""

    def __init__(self, inner: can.BusABC, faults: list[Fault], protocol: Protocol, direction: str = "tx"):
        if direction not in ("tx", "rx"):
            raise ValueError(f"FaultyBus direction must be 'tx' or 'rx', got {direction!r}")
        self.inner = inner
        self.faults = faults
        self.radar_protocol = protocol
        self.direction = direction
        self.fired: list[Fault] = []
        self.channel_info = f"faulty({getattr(inner, 'channel_info', '?')})"
        self._lock = threading.Lock()
        self._seq: int | None = None  # frame whose transfer is on the bus
        self._n_cf = 0  # consecutive frames in the current transfer
        self._cf = -1  # index of the last consecutive frame seen
        self._truncating = False
        self._held: can.Message | None = None  # reorder: waits for the next message
        self._out: list = []  # rx: messages queued for delivery
        self._header_msg = protocol._msgs["FrameHeader"]
        super().__init__(channel=getattr(inner, "channel", None))

    # --- protocol tracking -----------------------------------------------------------------
    def _position(self, msg: can.Message) -> str | None:
        aid = msg.arbitration_id
        if aid == self.radar_protocol.ids["FrameHeader"]:
            self._seq = int.from_bytes(bytes(msg.data[4:8]), "little")
            return "header"
        if aid != self.radar_protocol.data_id or not msg.data:
            return None
        pci = msg.data[0] >> 4
        if pci == 1:  # first frame: learn the transfer length
            d = bytes(msg.data)
            length = ((d[0] & 0xF) << 8) | d[1]
            ff_data = len(d) - 2
            if length == 0:
                length = int.from_bytes(d[2:6], "big")
                ff_data = len(d) - 6
            per_cf = len(d) - 1
            self._n_cf = max(0, -(-(length - ff_data) // per_cf))
            self._cf = -1
            self._truncating = False
            return "ff"
        if pci == 2:
            self._cf += 1
            return "cf"
        return None

    def _match(self, pos: str | None) -> list[Fault]:
        if pos is None or self._seq is None:
            return []
        hits = []
        for f in self.faults:
            if f.done or f.seq != self._seq:
                continue
            if f.part == pos and (pos != "cf" or f.index == self._cf):
                hits.append(f)
            elif f.part == "last" and pos == "cf" and self._cf == self._n_cf - 1:
                hits.append(f)
        return hits

    def _apply(self, msg: can.Message) -> tuple[list[can.Message], bool]:
        """Messages to pass on in place of ``msg`` and whether to raise a bus error."""
        with self._lock:
            pos = self._position(msg)
            if self._truncating and pos == "cf":
                return self._release([]), False
            hits = self._match(pos)
            out = [msg]
            bus_error = False
            for f in hits:
                f.done = True
                self.fired.append(f)
                if f.kind == "drop":
                    out = []
                elif f.kind == "duplicate":
                    out = out + [_copy(msg)]
                elif f.kind == "corrupt":
                    out = [_flip(m, 20 if pos == "header" else 8) for m in out]
                elif f.kind in ("checksum", "oversize"):
                    out = [self._rewrite_header(m, f.kind) for m in out]
                elif f.kind == "truncate":
                    self._truncating = True
                    out = []
                elif f.kind == "error_frame":
                    out = [can.Message(is_error_frame=True, timestamp=msg.timestamp)] + out
                elif f.kind == "bus_error":
                    out, bus_error = [], True
                elif f.kind == "reorder":
                    held, self._held = self._held, (out[0] if out else None)
                    return ([held] if held is not None else []) + out[1:], bus_error
            return self._release(out), bus_error

    def _release(self, out: list[can.Message]) -> list[can.Message]:
        if self._held is not None and out:
            held, self._held = self._held, None
            return [out[0], held] + out[1:]
        return out

    def _rewrite_header(self, msg: can.Message, kind: str) -> can.Message:
        sig = self._header_msg.decode(bytes(msg.data), decode_choices=False)
        short = {k.removeprefix("FrameHeader_"): v for k, v in sig.items()}
        counter = short.pop("Counter")
        for k in ("Crc", "ProtocolVersion"):
            short.pop(k)
        if kind == "checksum":
            short["PayloadCrc32"] ^= 0x1
        else:
            short.update(Shape0=65535, Shape1=65535, PayloadBytes=0xFFFFFFFF)
        new = self.radar_protocol.encode("FrameHeader", short, counter=counter)
        new.timestamp = msg.timestamp
        return new

    # --- BusABC -----------------------------------------------------------------------------
    def send(self, msg: can.Message, timeout: Optional[float] = None) -> None:
        if self.direction == "rx":
            self.inner.send(msg, timeout)
            return
        out, _ = self._apply(msg)
        for m in out:
            self.inner.send(m, timeout)

    def _recv_internal(self, timeout: Optional[float]) -> tuple[Optional[can.Message], bool]:
        if self._out:
            return self._out.pop(0), False
        msg = self.inner.recv(timeout)
        if msg is None or self.direction == "tx":
            return msg, False
        out, bus_error = self._apply(msg)
        if bus_error:
            self._out.extend(out)
            raise can.CanOperationError("injected bus error (FaultyBus)")
        if not out:
            return None, False
        self._out.extend(out[1:])
        return out[0], False

    def flush(self, timeout: Optional[float] = None) -> None:
        """Deliver a message held back by ``reorder`` (nothing followed it)."""
        with self._lock:
            held, self._held = self._held, None
        if held is not None and self.direction == "tx":
            self.inner.send(held, timeout)
        elif held is not None:
            self._out.append(held)

    def shutdown(self) -> None:
        try:
            self.flush()
        finally:
            self.inner.shutdown()
            super().shutdown()


def _copy(msg: can.Message) -> can.Message:
    return can.Message(arbitration_id=msg.arbitration_id, data=bytes(msg.data), is_extended_id=msg.is_extended_id,
                       is_fd=msg.is_fd, bitrate_switch=msg.bitrate_switch, timestamp=msg.timestamp,
                       is_error_frame=msg.is_error_frame)


def _flip(msg: can.Message, byte: int) -> can.Message:
    m = _copy(msg)
    data = bytearray(m.data)
    data[min(byte, len(data) - 1)] ^= 0x40
    m.data = data
    return m


def wrapper(faults: list[Fault], protocol: Protocol, direction: str = "tx"):
    """A ``bus_wrapper`` callable for CanLink/RadarEmulator/CANBackend that shares ``faults``
    across reconnections (each rule still fires once); the last wrapped bus is ``.last``."""

    def wrap(bus: can.BusABC) -> FaultyBus:
        fb = FaultyBus(bus, faults, protocol, direction)
        wrap.last = fb
        wrap.all.append(fb)
        return fb

    wrap.last = None
    wrap.all = []
    return wrap
