"""Frame reassembly from FrameHeader messages and ISO-TP items, with link statistics.

Rules (shared by the live ``can`` backend and ``replay``):

* A frame (sequence number s) is **delivered** when its header and its ISO-TP item have both
  arrived, the header announces the configured payload (format, shape, size) and the CRC-32 of
  the item matches. Frames leave strictly in sequence order, each at most once.
* The payload transfers of one radar are serialised on one ISO-TP channel, so when the item of
  frame t arrives, every earlier frame s < t that is still open can no longer complete: it is
  reported lost — ``incomplete`` if something of it arrived, ``dropped`` if nothing did.
  Headers may arrive out of order with respect to items (reordered CAN frames).
* A frame the radar is known to have sent (its header arrived, or RadarState.NextSeq passed
  it) that is still open ``frame_timeout`` seconds later is reported lost the same way: this
  catches a transfer cut off after the radar's last frame.
* ``corrupted``: complete but failing the checks (CRC-32, header contents). ``late``: a complete
  item for a frame already reported lost, or one outside what was requested. ``duplicate``: a
  second copy of an item already seen. None of these is ever passed on as data.

Nothing here allocates from untrusted sizes: the header is checked against the configured
:class:`~hardware.protocol.PayloadSpec` and the ISO-TP layer caps the item size.
"""
from __future__ import annotations

import logging
from collections import OrderedDict, deque
from dataclasses import asdict, dataclass, field
from typing import Any

from xnlos_core.radar import RadarConfig
from xnlos_core.types import Frame

from .protocol import SEQ_PREFIX, DeviceState, PayloadFormat, PayloadSpec, decode_payload, payload_crc32

log = logging.getLogger(__name__)

MAX_GAP = 4096  # a sequence number further than this from the expected one is a corrupt prefix


@dataclass(frozen=True)
class LostFrame:
    """A frame that was not delivered: its sequence number, the kind of loss and why."""

    seq: int
    kind: str  # "dropped" | "incomplete" | "corrupted"
    reason: str
    time: float = 0.0


# The LinkStats counter of each receive event (the kinds of CanLink's on_event): one table, so a
# replayed log counts what the live run counted.
EVENT_COUNTERS = {"error_frame": "error_frames", "unknown_id": "unknown_ids", "other_sensor": "other_sensor",
                  "e2e": "e2e_errors", "protocol": "e2e_errors", "transfer_error": "transfer_errors",
                  "bus_error": "bus_errors"}


@dataclass
class LinkStats:
    """Counters of one link (a backend instance). Frames counted once each, by outcome.

    frames_ok: arrived complete and intact (handed on to the consumer's queue); frames_delivered:
    taken by the consumer; frames_overrun: intact but dropped by the queue's overflow policy
    because the consumer fell behind (never counted as lost; their sequence numbers in
    ``overrun_seqs``, latest 10 000); frames_dropped: nothing of the frame arrived (sequence gap);
    frames_incomplete: header or item missing, transfer cut off; frames_corrupted: complete but
    failing CRC-32 or header checks; frames_late: arrived after being reported lost or outside the
    request (discarded); frames_duplicate: extra copies (discarded); bytes_ok: payload bytes of
    delivered frames; messages: CAN messages seen from the radar; transfer_errors: ISO-TP errors
    (wrong sequence number, timeout, interrupted, oversize); e2e_errors: signal messages failing
    CRC-8 or protocol version; unknown_ids: identifiers the protocol does not define;
    other_sensor: messages of other sensor ids (ignored); bus_errors: exceptions raised by the
    interface; error_frames: CAN error frames seen; device_errors: RadarError messages and
    ERROR states; timeouts: the radar fell silent; reconnects: successful reconnections;
    rx_overflows: ISO-TP items discarded because the receive thread itself fell behind (its
    frame is then lost, not overrun); lost: every lost frame (latest 10 000) with its sequence
    number. Once the consumer's queue is empty, every frame the radar sent is counted exactly once:
    sent = frames_delivered + frames_overrun + frames_lost.
    """

    frames_ok: int = 0
    frames_delivered: int = 0
    frames_overrun: int = 0
    frames_dropped: int = 0
    frames_incomplete: int = 0
    frames_corrupted: int = 0
    frames_late: int = 0
    frames_duplicate: int = 0
    bytes_ok: int = 0
    messages: int = 0
    transfer_errors: int = 0
    e2e_errors: int = 0
    unknown_ids: int = 0
    other_sensor: int = 0
    bus_errors: int = 0
    error_frames: int = 0
    device_errors: int = 0
    timeouts: int = 0
    reconnects: int = 0
    rx_overflows: int = 0
    lost: deque = field(default_factory=lambda: deque(maxlen=10_000))
    overrun_seqs: deque = field(default_factory=lambda: deque(maxlen=10_000))

    @property
    def frames_lost(self) -> int:
        return self.frames_dropped + self.frames_incomplete + self.frames_corrupted

    def lost_seqs(self) -> list[int]:
        return [x.seq for x in self.lost]

    def as_dict(self) -> dict[str, Any]:
        """Plain dict (JSON-ready); ``lost`` as a list of {seq, kind, reason, time}."""
        d = asdict(self)
        d["lost"] = [asdict(x) for x in self.lost]
        d["overrun_seqs"] = list(self.overrun_seqs)
        d["frames_lost"] = self.frames_lost
        return d

    def count(self, event: str) -> None:
        """Count one receive event (a :data:`EVENT_COUNTERS` kind) on its counter."""
        name = EVENT_COUNTERS[event]
        setattr(self, name, getattr(self, name) + 1)

    def summary(self) -> str:
        """One line: ok / delivered / overrun / dropped / incomplete / corrupted / late / duplicate, plus
        link events."""
        keys = ("frames_ok", "frames_delivered", "frames_overrun", "frames_dropped", "frames_incomplete", "frames_corrupted", "frames_late",
                "frames_duplicate", "transfer_errors", "e2e_errors", "bus_errors", "timeouts", "reconnects")
        return ", ".join(f"{k.removeprefix('frames_')}={getattr(self, k)}" for k in keys)


@dataclass
class _Slot:
    header: dict | None = None
    item: bytes | None = None
    first: float = 0.0  # time something of the frame (or knowledge that it was sent) arrived
    bad: str | None = None  # reason the header is unusable
    outcome: Any = None  # Frame or LostFrame once resolved
    t_rx: float = 0.0


class FrameAssembler:
    """Pairs headers with ISO-TP items and emits Frames / LostFrames in sequence order.

    radar: the configuration frames are decoded with; fmt: the configured payload format;
    frame_timeout [s, on the clock the caller passes as ``now``]; source / sensor_id: for
    Frame.meta. Call :meth:`expect` before a request (live) or let the first item set the start
    (replay, ``expect(None)``).
    """

    def __init__(self, radar: RadarConfig, fmt: PayloadFormat, stats: LinkStats, frame_timeout: float = 2.0,
                 source: str = "can", sensor_id: int = 0):
        self.radar = radar
        self.spec = PayloadSpec.for_radar(radar, fmt)
        self.stats = stats
        self.frame_timeout = float(frame_timeout)
        self.source = source
        self.sensor_id = sensor_id
        self.lo: int | None = None  # lowest unresolved sequence number
        self.hi: int | None = None  # end of the requested range (exclusive); None = open-ended
        self.sent_upto: int | None = None  # RadarState.NextSeq: frames below it were sent
        self._slots: dict[int, _Slot] = {}
        self._resolved: OrderedDict[int, bool] = OrderedDict()  # seq → delivered?
        self._ready: deque = deque()
        self._lost_pending: list[int] = []

    # --- requests -------------------------------------------------------------------------
    def expect(self, first: int | None, n: int | None, now: float = 0.0) -> None:
        """Open the request [first, first + n) (n None: open-ended). Earlier open frames stay
        open until they resolve; a ``first`` below the resolved range means the radar restarted
        its numbering: everything open is reported lost and counting starts again."""
        if first is not None and self.lo is not None and first < self.lo:
            self._restart(first, now, "radar restarted its sequence numbering")
        if self.lo is None:
            self.lo = first
        if first is not None:
            self.hi = None if n is None else first + n
            self.known_sent(first, now)
        else:
            self.hi = None

    def cancel(self, now: float = 0.0) -> None:
        """The request ended early (stop, reconnect): frames not known to be sent are forgotten."""
        if self.lo is None:
            return
        limit = self.sent_upto if self.sent_upto is not None else self.lo
        top = max([limit, self.lo] + [s + 1 for s in self._slots])
        self.hi = top

    @property
    def idle(self) -> bool:
        """True when every requested frame is resolved and handed out (nothing to wait for)."""
        if self._ready:
            return False
        if self.lo is None:
            return True
        return self.hi is not None and self.lo >= self.hi and not any(s >= self.lo for s in self._slots)

    @property
    def open_count(self) -> int:
        """Frames requested but not yet resolved."""
        if self.lo is None or self.hi is None:
            return 0
        return max(0, self.hi - self.lo)

    # --- inputs ---------------------------------------------------------------------------
    def known_sent(self, next_seq: int, now: float) -> None:
        """RadarState.NextSeq: every frame below ``next_seq`` has been sent (starts its deadline)."""
        if self.lo is None or next_seq <= self.lo:
            self.sent_upto = next_seq if self.sent_upto is None else max(self.sent_upto, next_seq)
            return
        top = min(next_seq, self.lo + MAX_GAP, self.hi if self.hi is not None else next_seq)
        for s in range(self.lo, top):
            slot = self._slots.get(s)
            if slot is None:
                self._slots[s] = _Slot(first=now)
        self.sent_upto = next_seq if self.sent_upto is None else max(self.sent_upto, next_seq)

    def on_header(self, header: dict[str, Any], now: float) -> None:
        """A FrameHeader (already E2E-checked) arrived at ``now``."""
        seq = int(header["Seq"])
        if self.lo is None:
            self.lo = seq
        if not self._in_range(seq, now, header_seq=True):
            return
        slot = self._slots.get(seq)
        if slot is None:
            slot = self._slots[seq] = _Slot(first=now)
        if slot.header is not None:
            if slot.header != header:
                slot.bad = "two different headers with the same sequence number"
            return
        slot.header = header
        slot.bad = slot.bad or self.spec.check_header(header)
        self._try(seq, now)
        self._flush()

    def on_item(self, item: bytes, now: float) -> None:
        """A complete ISO-TP item (4-byte sequence number + payload) arrived at ``now``."""
        if len(item) < SEQ_PREFIX.size:
            self.stats.transfer_errors += 1
            log.warning("%s: ISO-TP item of %d bytes is shorter than its sequence prefix; discarded",
                        self.source, len(item))
            return
        (seq,) = SEQ_PREFIX.unpack_from(item)
        if self.lo is None:
            self.lo = seq
        if not self._in_range(seq, now, header_seq=False):
            return
        slot = self._slots.get(seq)
        if slot is None:
            slot = self._slots[seq] = _Slot(first=now)
        if slot.item is not None:
            self.stats.frames_duplicate += 1
            return
        slot.item = bytes(item)
        slot.t_rx = now
        # transfers are serialised: earlier open frames can no longer complete
        for s in range(self.lo, seq):
            self._lose(s, now, "payload never completed (a later frame's payload arrived)")
        self._try(seq, now)
        self._flush()

    def poll(self, now: float) -> None:
        """Report frames known to be sent but still open after ``frame_timeout``."""
        if self.lo is None:
            return
        for s in sorted(self._slots):
            slot = self._slots[s]
            if s >= self.lo and slot.outcome is None and now - slot.first > self.frame_timeout:
                self._lose(s, now, f"still incomplete {self.frame_timeout:g} s after it was sent")
        self._flush()

    def finish(self, now: float, reason: str = "stream ended") -> None:
        """Report every open frame that something is known of as lost (end of a log, close)."""
        if self.lo is None:
            return
        for s in sorted(self._slots):
            if s >= self.lo and self._slots[s].outcome is None:
                self._lose(s, now, reason)
        self._flush()

    # --- outputs --------------------------------------------------------------------------
    def pop(self) -> Frame | LostFrame | None:
        """The next resolved frame in sequence order (Frame or LostFrame), or None."""
        return self._ready.popleft() if self._ready else None

    # --- internals ------------------------------------------------------------------------
    def _in_range(self, seq: int, now: float, header_seq: bool) -> bool:
        what = "header" if header_seq else "payload"
        if seq < self.lo:
            if self.lo - seq > MAX_GAP:
                if header_seq:
                    self._restart(seq, now, "radar restarted its sequence numbering")
                    return True
                self.stats.transfer_errors += 1
                return False
            if not header_seq:
                delivered = self._resolved.get(seq)
                if delivered:
                    self.stats.frames_duplicate += 1
                else:
                    self.stats.frames_late += 1
                    log.info("%s: frame %d arrived after it was reported lost; discarded", self.source, seq)
            return False
        if seq - self.lo > MAX_GAP:
            self.stats.transfer_errors += 1
            log.warning("%s: %s with sequence number %d far from the expected %d; discarded",
                        self.source, what, seq, self.lo)
            return False
        if self.hi is not None and seq >= self.hi:
            if not header_seq:
                self.stats.frames_late += 1
                log.info("%s: frame %d was not requested (request ends at %d); discarded", self.source, seq, self.hi)
            return False
        return True

    def _restart(self, first: int, now: float, reason: str) -> None:
        log.warning("%s: %s (expected %s, got %d)", self.source, reason, self.lo, first)
        self.finish(now, reason)
        self._slots.clear()
        self._resolved.clear()
        self.lo, self.sent_upto = first, None

    def _try(self, seq: int, now: float) -> None:
        slot = self._slots[seq]
        if slot.outcome is not None or slot.header is None or slot.item is None:
            return
        h, item = slot.header, slot.item
        reason = slot.bad
        if reason is None and len(item) - SEQ_PREFIX.size != self.spec.nbytes:
            reason = f"payload of {len(item) - SEQ_PREFIX.size} bytes, header announced {h['PayloadBytes']}"
        if reason is None and payload_crc32(item) != h["PayloadCrc32"]:
            reason = (f"CRC-32 mismatch (header 0x{h['PayloadCrc32']:08X}, payload "
                      f"0x{payload_crc32(item):08X})")
        if reason is not None:
            self._set_lost(seq, now, "corrupted", reason)
            return
        try:
            ra = decode_payload(self.spec, h, item[SEQ_PREFIX.size:], self.radar)
        except Exception as exc:  # a payload that passes CRC but not the signal chain's checks
            self._set_lost(seq, now, "corrupted", f"payload does not decode: {exc}")
            return
        meta = {"seq": seq, "sensor_id": self.sensor_id, "source": self.source, "rx_time": slot.t_rx,
                "payload_format": self.spec.fmt.name, "config_id": h["ConfigId"]}
        slot.outcome = Frame(ra, timestamp=float(h["Timestamp"]), index=seq, meta=meta)

    def _lose(self, seq: int, now: float, reason: str) -> None:
        slot = self._slots.get(seq)
        if slot is None:
            self._slots[seq] = _Slot(first=now)
            self._set_lost(seq, now, "dropped", "nothing of the frame arrived")
            return
        if slot.outcome is not None:
            return
        if slot.bad is not None:
            self._set_lost(seq, now, "corrupted", slot.bad)
        elif slot.header is None and slot.item is None:
            self._set_lost(seq, now, "dropped", "nothing of the frame arrived")
        elif slot.header is None:
            self._set_lost(seq, now, "incomplete", "header missing (payload arrived)")
        else:
            self._set_lost(seq, now, "incomplete", reason)

    def _set_lost(self, seq: int, now: float, kind: str, reason: str) -> None:
        self._slots[seq].outcome = LostFrame(seq, kind, reason, now)

    def _flush(self) -> None:
        while self.lo is not None and self.lo in self._slots and self._slots[self.lo].outcome is not None:
            out = self._slots.pop(self.lo).outcome
            if isinstance(out, Frame):
                self.stats.frames_ok += 1
                self.stats.bytes_ok += self.spec.nbytes
                if self._lost_pending:
                    out.meta["lost_before"] = list(self._lost_pending)
                    self._lost_pending.clear()
            else:
                setattr(self.stats, f"frames_{out.kind}", getattr(self.stats, f"frames_{out.kind}") + 1)
                self.stats.lost.append(out)
                self._lost_pending.append(out.seq)
                log.warning("%s: frame %d %s: %s", self.source, out.seq, out.kind, out.reason)
            self._resolved[self.lo] = isinstance(out, Frame)
            if len(self._resolved) > 2 * MAX_GAP:
                self._resolved.popitem(last=False)
            self._ready.append(out)
            self.lo += 1


def on_radar_message(asm: "FrameAssembler | None", stats: LinkStats, name: str, signals: dict, t: float) -> None:
    """Apply one decoded message of the radar (``name`` FrameHeader, RadarState or RadarError, its
    ``signals``, arrival time ``t`` [s]) to the assembler and the counters — the receive dispatch
    the live ``can`` backend and ``replay`` share. ``asm`` None: the payload format is not known yet
    (a log's first RadarState), so only the counters change. Other names are ignored."""
    if name == "FrameHeader":
        asm.on_header(signals, t)
    elif name == "RadarState":
        if asm is not None:
            asm.known_sent(signals["NextSeq"], t)
        if signals["State"] == DeviceState.ERROR:
            stats.device_errors += 1
    elif name == "RadarError":
        stats.device_errors += 1
