"""Backend ``replay``: frames from a recorded CAN log (BLF, ASC, or any format python-can reads).

The log is decoded exactly as the live ``can`` backend decodes the bus — same DBC, same ISO-TP
reassembly (can-isotp's transport logic, driven message by message), same frame checks and loss
reporting — so a recording replays into the frames the live run delivered, bit for bit. Time is
the log's: deadlines use recorded timestamps, and ``realtime = true`` paces the messages at
their recorded speed (python-can ``MessageSync``); otherwise they are read as fast as possible.

Damaged input gives an InputError naming the file: a BLF whose header disagrees with its size
(truncated or never finalised), an ASC without its ``End TriggerBlock`` trailer, a log that does
not parse, or one recorded with a different radar configuration than the pipeline's.
"""
from __future__ import annotations

import logging
import struct
from collections import deque
from collections.abc import Iterator
from pathlib import Path
from typing import Literal

import can
import isotp
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.errors import InputError
from xnlos_core.interfaces import Backend
from xnlos_core.radar import RadarConfig
from xnlos_core.types import Frame
from xnlos_core.param_paths import RELATIVE_TO_CONFIG, ConfigPath

from .assembler import FrameAssembler, LinkStats, LostFrame, on_radar_message
from .link import SIGNIFICANT_ERRORS, isotp_params, stop_quietly
from .protocol import (FORMAT_NAMES, DeviceState, E2EError, PayloadFormat, PayloadSpec, Protocol, ProtocolError,
                       radar_hash)

log = logging.getLogger(__name__)

_BLF_HEADER = struct.Struct("<4sLBBBBBBBBQQLL8H8H")


def readable_formats() -> list[str]:
    """Log suffixes python-can can read."""
    from can.io.player import MESSAGE_READERS

    return sorted(MESSAGE_READERS)


def check_log(path: str | Path) -> Path:
    """The log's path if it exists, has a readable format and (BLF, ASC) is complete; else InputError."""
    p = Path(path).expanduser()
    if not p.is_file():
        raise InputError(f"replay: recording {str(p)!r} does not exist (params.file)")
    suffix = p.suffix.lower()
    if suffix not in readable_formats():
        raise InputError(f"replay: {p}: python-can cannot read {suffix or 'files without suffix'}; "
                         f"use one of {', '.join(readable_formats())}")
    size = p.stat().st_size
    if suffix == ".blf":
        with p.open("rb") as fh:
            head = fh.read(_BLF_HEADER.size)
        if len(head) < _BLF_HEADER.size:
            raise InputError(f"replay: {p}: truncated BLF file ({size} bytes, shorter than its "
                             f"{_BLF_HEADER.size}-byte header)")
        fields = _BLF_HEADER.unpack(head)
        if fields[0] != b"LOGG":
            raise InputError(f"replay: {p}: not a BLF file (signature {fields[0]!r}, expected b'LOGG')")
        if fields[10] != size:
            raise InputError(f"replay: {p}: truncated or unfinished BLF file: its header records "
                             f"{fields[10]} bytes, the file has {size}")
    elif suffix == ".asc":
        with p.open("rb") as fh:
            fh.seek(max(0, size - 256))
            tail = fh.read()
        lines = [ln.strip() for ln in tail.decode("latin-1").splitlines() if ln.strip()]
        if not tail.endswith(b"\n") or not lines or lines[-1] != b"End TriggerBlock".decode():
            raise InputError(f"replay: {p}: truncated ASC file (it does not end with 'End TriggerBlock')")
    return p


class ReplayParams(BaseModel):
    """Parameters of the ``replay`` backend."""

    model_config = ConfigDict(extra="forbid")
    file: ConfigPath = Field(..., min_length=1, description="python-can log to replay (.blf, .asc, …)" + RELATIVE_TO_CONFIG)
    realtime: bool = Field(False, description="play at recorded speed (False: as fast as possible)")
    sensor_id: int = Field(0, ge=0, le=7, description="which radar of the recording (identifier offset 0x10·id)")
    dbc: ConfigPath | None = Field(None, description="DBC file (default: the packaged radar.dbc)" + RELATIVE_TO_CONFIG)
    payload: Literal["auto", "ra_complex64", "adc_int16", "adc_complex64"] = Field(
        "auto", description="payload format; auto: as the radar's first RadarState or FrameHeader says")
    frame_timeout: float = Field(2.0, gt=0, le=3600, description="a frame still incomplete this long (log "
                                 "time) after it was sent is reported lost [s]")
    check_config: bool = Field(True, description="require the recording's RadarConfig hash to match the pipeline's")


class ReplayBackend(Backend):
    """Replays a recorded CAN log (BLF/ASC) as frames, at recorded speed or as fast as possible."""

    Params = ReplayParams

    def __init__(self, params=None):
        super().__init__(params)
        self.stats = LinkStats()
        self.radar: RadarConfig | None = None

    def open(self, radar: RadarConfig) -> None:
        """Remember the radar frames are decoded with and check the file (InputError if unusable)."""
        if not isinstance(radar, RadarConfig):
            raise InputError(f"ReplayBackend.open: expected a RadarConfig, got {type(radar).__name__}")
        self.radar = radar
        check_log(self.params.file)

    def frames(self, max_frames: int | None = None) -> Iterator[Frame]:
        """Yield up to ``max_frames`` frames (None: all) in sequence order."""
        self.check_max_frames(max_frames)
        if self.radar is None:
            raise InputError("ReplayBackend.frames: call open(radar) first (the radar frames are decoded with)")
        if max_frames == 0:
            return
        path = check_log(self.params.file)
        self.stats = LinkStats()
        session = _Session(self, path)
        try:
            yield from session.run(max_frames)
        finally:
            session.close()


class _Session:
    """One pass over a log."""

    def __init__(self, backend: ReplayBackend, path: Path):
        p = backend.params
        self.path, self.params, self.radar, self.stats = path, p, backend.radar, backend.stats
        self.protocol = Protocol.load(p.dbc, p.sensor_id)
        self.fmt = None if p.payload == "auto" else FORMAT_NAMES[p.payload]
        self.asm: FrameAssembler | None = None
        self.early: list[tuple] = []  # headers/items seen before the format was known
        self.rx: deque = deque()
        max_item = max(PayloadSpec.for_radar(self.radar, f).item_bytes for f in PayloadFormat)
        self.tl = isotp.TransportLayerLogic(rxfn=self._rxfn, txfn=lambda msg: None,
                                            address=isotp.Address(isotp.AddressingMode.Normal_11bits,
                                                                  txid=self.protocol.flow_id,
                                                                  rxid=self.protocol.data_id),
                                            error_handler=self._isotp_error,
                                            params=isotp_params(max_item, 3600.0, 3600.0))
        self.checked_config = not p.check_config
        self.reader = None
        self.now = 0.0
        if self.fmt is not None:  # the format is given: assemble from the first message on
            self._set_format(self.fmt)

    def _rxfn(self, timeout):
        return self.rx.popleft() if self.rx else None

    def _isotp_error(self, exc):
        if isinstance(exc, SIGNIFICANT_ERRORS):
            self.stats.count("transfer_error")

    def _messages(self):
        try:
            self.reader = can.LogReader(str(self.path))
        except Exception as exc:
            raise InputError(f"replay: {self.path}: cannot open the log ({type(exc).__name__}: {exc})") from None
        it = iter(can.MessageSync(self.reader, timestamps=True, skip=3600.0) if self.params.realtime else self.reader)
        while True:
            try:
                msg = next(it)
            except StopIteration:
                return
            except Exception as exc:  # parsers raise struct.error, ValueError, zlib.error, BLFParseError …
                raise InputError(f"replay: {self.path}: damaged log ({type(exc).__name__}: {exc})") from None
            yield msg

    def run(self, max_frames: int | None) -> Iterator[Frame]:
        n = 0
        for msg in self._messages():
            self.now = float(msg.timestamp)
            self._handle(msg)
            for out in self._drain():
                yield out
                n += 1
                if max_frames is not None and n >= max_frames:
                    return
        if self.asm is None and self.early:
            self._set_format(PayloadFormat.RA_COMPLEX64)
        if self.asm is not None:
            self.asm.finish(self.now, "recording ended before the frame was complete")
        for out in self._drain():
            yield out
            n += 1
            if max_frames is not None and n >= max_frames:
                return

    def _drain(self) -> Iterator[Frame]:
        if self.asm is None:
            return
        self.asm.poll(self.now)
        while (out := self.asm.pop()) is not None:
            if not isinstance(out, LostFrame):
                out.meta["source"] = "replay"
                out.meta["file"] = str(self.path)
                self.asm.stats.frames_delivered += 1  # a log has no overflow: delivered = ok
                yield out

    def _set_format(self, fmt: PayloadFormat) -> None:
        self.fmt = PayloadFormat(fmt)
        self.asm = FrameAssembler(self.radar, self.fmt, self.stats, self.params.frame_timeout, source="replay",
                                  sensor_id=self.params.sensor_id)
        self.asm.expect(None, None, self.now)
        for kind, value, t in self.early:
            (self.asm.on_header if kind == "header" else self.asm.on_item)(value, t)
        self.early.clear()

    def _handle(self, msg: can.Message) -> None:
        st = self.stats
        if msg.is_error_frame:
            st.count("error_frame")
            return
        kind = self.protocol.classify(msg.arbitration_id, msg.is_extended_id)
        if kind == "data":
            st.messages += 1
            self.rx.append(isotp.CanMessage(arbitration_id=msg.arbitration_id, data=bytes(msg.data),
                                            extended_id=msg.is_extended_id, is_fd=msg.is_fd,
                                            bitrate_switch=msg.bitrate_switch))
            self.tl.process()
            while (item := self.tl.recv()) is not None:
                self._item(bytes(item))
            return
        if kind == "flow":
            return
        if kind in ("other_sensor", "unknown"):
            st.count("other_sensor" if kind == "other_sensor" else "unknown_id")
            return
        try:
            name, sig = self.protocol.decode(msg)
        except E2EError:
            st.count("e2e")
            return
        except ProtocolError as exc:
            st.count("protocol")
            log.warning("replay: %s: %s", self.path, exc)
            return
        if name in ("RadarState", "RadarError", "FrameHeader"):
            st.messages += 1
        configured = name == "RadarState" and sig["State"] in (DeviceState.CONFIGURED, DeviceState.STREAMING)
        if configured:
            self._check_config(sig)
        if self.fmt is None and (configured or name == "FrameHeader"):  # the first to announce the format sets it
            self._set_format(sig["PayloadFormat"])
        on_radar_message(self.asm, st, name, sig, self.now)

    def _item(self, item: bytes) -> None:
        if self.asm is None:
            self.early.append(("item", item, self.now))
        else:
            self.asm.on_item(item, self.now)

    def _check_config(self, state: dict) -> None:
        if self.checked_config:
            return
        want = radar_hash(self.radar)
        if state["ConfigHash"] != want:
            raise InputError(f"replay: {self.path} was recorded with radar configuration hash "
                             f"0x{state['ConfigHash']:08X}; the pipeline's radar has 0x{want:08X}. Use the "
                             "[radar] the recording was made with (or params.check_config = false)")
        self.checked_config = True

    def close(self) -> None:
        if self.reader is not None:
            stop_quietly(self.reader.stop, "reader stop", log)
            self.reader = None
