"""The radar's CAN protocol: messages declared in ``radar.dbc`` (encoded and decoded with cantools),
end-to-end protection of the signal messages, and the frame payload codecs.

Message layout (base identifiers; every identifier is ``base + 0x10 · sensor_id``, sensor_id
0…7, the way automotive radars such as the ARS 408 let several sensors share one bus):

=======  ================  =========  ==========================================================
base     message           direction  content
=======  ================  =========  ==========================================================
0x200    RadarCfg          host→radar waveform, array and output format, CRC-32 of the RadarConfig
0x204    RadarModeCfg      host→radar MIMO or steered TX beam, frame period (sent before RadarCfg)
0x201    RadarState        radar→host state, config id/hash echo, next sequence number (cyclic)
0x202    RadarCtrl         host→radar START n frames / STOP / STATUS, request id
0x203    RadarError        radar→host error code and the sequence number it concerns
0x300    FrameHeader       radar→host list header: seq, timestamp, format, shape, size, CRC-32
0x400    FrameData         radar→host ISO-TP N_PDUs: uint32 LE seq, then the payload bytes
0x401    FrameFlowControl  host→radar ISO-TP flow control
=======  ================  =========  ==========================================================

RadarCfg/RadarState are the configuration/state pair; FrameHeader followed by one ISO-TP transfer
is the "list header then items" pattern. Byte 0 of each signal message is a CRC-8 (SAE J1850)
over bytes 1…n−1 and bits 8…11 an alive counter (AUTOSAR E2E profile 1 style); bits 12…15 carry
the protocol version. The ISO-TP item (sequence number + payload) is covered by the header's
CRC-32 (``zlib.crc32``), so a frame is delivered only if every byte arrived intact.

Payload formats (little-endian, C order):

* ``RA_COMPLEX64``: the RA map, complex64 (n_range, n_azimuth) — bit-identical to the sender's map.
* ``ADC_INT16``: the ADC cube (n_samples, n_channels, 2) int16 I/Q, ``Scale`` √W per LSB.
* ``ADC_COMPLEX64``: the ADC cube (n_samples, n_channels) complex64 [√W].

ADC cubes become RA maps on the host through the shared chain (:mod:`hardware.adc`).
"""
from __future__ import annotations

import enum
import json
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import cantools
import numpy as np

from xnlos_core.errors import InputError, XnlosError
from xnlos_core.radar import RadarConfig
from xnlos_core.types import RAMap

PROTOCOL_VERSION = 1
SENSOR_ID_STRIDE = 0x10
MAX_SENSORS = 8
DEFAULT_DBC = Path(__file__).with_name("radar.dbc")
SEQ_PREFIX = struct.Struct("<I")
CONTINUOUS = 0xFFFFFFFF  # RadarState.FramesRemaining of a continuous measurement

SIGNAL_MESSAGES = ("RadarCfg", "RadarModeCfg", "RadarState", "RadarCtrl", "RadarError", "FrameHeader")
HOST_TO_RADAR = ("RadarCfg", "RadarModeCfg", "RadarCtrl")
TRANSPORT_MESSAGES = ("FrameData", "FrameFlowControl")


class PayloadFormat(enum.IntEnum):
    RA_COMPLEX64 = 0
    ADC_INT16 = 1
    ADC_COMPLEX64 = 2


class DeviceState(enum.IntEnum):
    IDLE = 0
    CONFIGURED = 1
    STREAMING = 2
    ERROR = 3


class Command(enum.IntEnum):
    STOP = 0
    START = 1
    STATUS = 2


class ErrorCode(enum.IntEnum):
    NONE = 0
    CONFIG_MISMATCH = 1
    UNSUPPORTED_FORMAT = 2
    PROTOCOL_VERSION = 3
    NOT_CONFIGURED = 4
    INTERNAL = 5
    E2E = 6
    FRAME_ABORTED = 7


def code_name(enum_cls, value: int) -> str:
    """The member name of ``value`` in ``enum_cls``, or the number for values the enum lacks."""
    try:
        return enum_cls(value).name
    except ValueError:
        return str(value)


FORMAT_NAMES = {"ra_complex64": PayloadFormat.RA_COMPLEX64, "adc_int16": PayloadFormat.ADC_INT16,
                "adc_complex64": PayloadFormat.ADC_COMPLEX64}


class ProtocolError(InputError):
    """A DBC file or a message on the bus does not follow the radar protocol."""


class UnknownMessageError(ProtocolError):
    """A CAN identifier that the protocol does not define (for this sensor)."""


class E2EError(ProtocolError):
    """A signal message failed its CRC-8 check (corrupted on the way)."""


class LinkError(XnlosError, ConnectionError):
    """The CAN link or the radar on it failed (interface missing, device silent, rejected config)."""


# --- checksums ------------------------------------------------------------------------------
def _crc8_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return table


_CRC8 = _crc8_table()


def crc8_j1850(data: bytes) -> int:
    """CRC-8 SAE J1850 (poly 0x1D, init 0xFF, final xor 0xFF), as AUTOSAR E2E profile 1 uses."""
    crc = 0xFF
    for b in data:
        crc = _CRC8[crc ^ b]
    return crc ^ 0xFF


def payload_crc32(item: bytes) -> int:
    """CRC-32 (zlib, IEEE 802.3) of an ISO-TP item: the 4-byte sequence prefix plus the payload."""
    return zlib.crc32(item) & 0xFFFFFFFF


def radar_hash(radar: RadarConfig) -> int:
    """CRC-32 of the canonical JSON of the complete RadarConfig: host and radar agree on every
    field, including those the bus does not carry (windows, noise figure, calibration)."""
    blob = json.dumps(radar.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))
    return zlib.crc32(blob.encode()) & 0xFFFFFFFF


# --- the DBC --------------------------------------------------------------------------------
def _signal_layout(sig) -> tuple:
    return (sig.start, sig.length, sig.byte_order, sig.is_signed, sig.is_float, float(sig.scale),
            float(sig.offset))


def _load_dbc(path: Path):
    if not path.is_file():
        raise ProtocolError(f"DBC file {str(path)!r} does not exist")
    try:
        return cantools.database.load_file(str(path), database_format="dbc", strict=True)
    except Exception as exc:  # cantools raises ParseError, UnsupportedDatabaseFormatError, ValueError …
        raise ProtocolError(f"{path}: not a valid DBC file ({type(exc).__name__}: {exc})") from None


_REFERENCE = None


def _reference_db():
    global _REFERENCE
    if _REFERENCE is None:
        _REFERENCE = _load_dbc(DEFAULT_DBC)
    return _REFERENCE


def check_dbc(db, source: str) -> None:
    """Raise ProtocolError listing every way ``db`` differs from the packaged protocol.

    Every message and signal of ``radar.dbc`` must exist with the same identifier, length,
    CAN FD flag and bit layout (start, length, byte order, signedness, float type, scale,
    offset), and the database attribute ProtocolVersion must match. Extra messages or signals
    (vendor extensions) are allowed.
    """
    ref = _reference_db()
    problems = []
    attrs = getattr(getattr(db, "dbc", None), "attributes", None) or {}
    version = attrs.get("ProtocolVersion")
    version = getattr(version, "value", version)
    if version != PROTOCOL_VERSION:
        problems.append(f"attribute ProtocolVersion is {version!r}, expected {PROTOCOL_VERSION}")
    for rm in ref.messages:
        try:
            m = db.get_message_by_name(rm.name)
        except KeyError:
            problems.append(f"message {rm.name} (0x{rm.frame_id:03X}) is missing")
            continue
        for what, got, want in (("identifier", m.frame_id, rm.frame_id), ("length", m.length, rm.length),
                                ("CAN FD flag", m.is_fd, rm.is_fd)):
            if got != want:
                fmt = (lambda v: f"0x{v:03X}") if what == "identifier" else repr
                problems.append(f"message {rm.name}: {what} {fmt(got)}, expected {fmt(want)}")
        have = {s.name: s for s in m.signals}
        for rs in rm.signals:
            s = have.get(rs.name)
            if s is None:
                problems.append(f"signal {rs.name} of {rm.name} is missing")
            elif _signal_layout(s) != _signal_layout(rs):
                problems.append(f"signal {rs.name}: layout (start, length, order, signed, float, scale, "
                                f"offset) {_signal_layout(s)}, expected {_signal_layout(rs)}")
    if problems:
        raise ProtocolError(f"{source}: DBC does not match the xnlos radar protocol v{PROTOCOL_VERSION} "
                            f"({DEFAULT_DBC.name}):\n  " + "\n  ".join(problems))


class Protocol:
    """The radar protocol for one sensor: identifiers with the sensor offset, encode/decode.

    ``Protocol.load(dbc=None, sensor_id=0)`` loads and checks a DBC (default: the packaged
    ``radar.dbc``). Signal names are given without the message prefix:
    ``encode("RadarCtrl", {"Command": 1, "NFrames": 5, "RequestId": 3})``.
    """

    def __init__(self, db, sensor_id: int = 0, source: str = str(DEFAULT_DBC)):
        if not isinstance(sensor_id, int) or not 0 <= sensor_id < MAX_SENSORS:
            raise ProtocolError(f"sensor_id must be an integer in 0…{MAX_SENSORS - 1}, got {sensor_id!r}")
        check_dbc(db, source)
        self.db = db
        self.source = source
        self.sensor_id = sensor_id
        self.offset = SENSOR_ID_STRIDE * sensor_id
        self._msgs = {name: db.get_message_by_name(name) for name in SIGNAL_MESSAGES + TRANSPORT_MESSAGES}
        self.ids = {name: m.frame_id + self.offset for name, m in self._msgs.items()}
        self._by_id = {self.ids[name]: name for name in SIGNAL_MESSAGES}
        base_ids = {m.frame_id for m in self._msgs.values()}
        self._other_sensor_ids = {b + SENSOR_ID_STRIDE * k for b in base_ids for k in range(MAX_SENSORS)
                                  if k != sensor_id}
        self._counters = {name: 0 for name in SIGNAL_MESSAGES}

    @classmethod
    def load(cls, dbc: str | Path | None = None, sensor_id: int = 0) -> "Protocol":
        """Load ``dbc`` (None: the packaged radar.dbc), check it against the protocol, bind ``sensor_id``."""
        if dbc is None:
            return cls(_reference_db(), sensor_id, str(DEFAULT_DBC))
        path = Path(dbc).expanduser()
        return cls(_load_dbc(path), sensor_id, str(path))

    @property
    def data_id(self) -> int:
        """ISO-TP identifier radar→host (frame payload)."""
        return self.ids["FrameData"]

    @property
    def flow_id(self) -> int:
        """ISO-TP identifier host→radar (flow control)."""
        return self.ids["FrameFlowControl"]

    def classify(self, arbitration_id: int, extended: bool = False) -> str:
        """'signal' (a DBC message of this sensor), 'data', 'flow', 'other_sensor' or 'unknown'.

        The protocol uses 11-bit identifiers: any 29-bit (``extended``) identifier is 'unknown'.
        """
        if extended:
            return "unknown"
        if arbitration_id in self._by_id:
            return "signal"
        if arbitration_id == self.data_id:
            return "data"
        if arbitration_id == self.flow_id:
            return "flow"
        if arbitration_id in self._other_sensor_ids:
            return "other_sensor"
        return "unknown"

    def encode(self, name: str, signals: dict[str, Any], counter: int | None = None) -> can.Message:
        """A CAN message ``name`` with ``signals`` (short names), version, alive counter and CRC-8.

        Raises ProtocolError for an unknown message name, a missing signal or a value outside
        the signal's range (cantools strict encoding).
        """
        if name not in self._by_id.values():
            raise ProtocolError(f"encode: {name!r} is not a signal message of the protocol; "
                                f"known: {', '.join(SIGNAL_MESSAGES)}")
        msg = self._msgs[name]
        if counter is None:
            counter = self._counters[name]
            self._counters[name] = (counter + 1) & 0xF
        full = {f"{name}_{k}": v for k, v in signals.items()}
        full.update({f"{name}_Crc": 0, f"{name}_Counter": counter & 0xF,
                     f"{name}_ProtocolVersion": PROTOCOL_VERSION})
        try:
            data = bytearray(msg.encode(full, scaling=True, padding=False, strict=True))
        except Exception as exc:  # cantools EncodeError/KeyError with the offending signal
            raise ProtocolError(f"encode {name}: {type(exc).__name__}: {exc}") from None
        data[0] = crc8_j1850(bytes(data[1:]))
        return can.Message(arbitration_id=self.ids[name], data=bytes(data), is_extended_id=False,
                           is_fd=msg.is_fd, bitrate_switch=msg.is_fd)

    def decode(self, message: can.Message) -> tuple[str, dict[str, Any]]:
        """(name, signals with short names) of a signal message of this sensor.

        Raises UnknownMessageError for an identifier the protocol does not define for this
        sensor, E2EError for a CRC-8 mismatch, ProtocolError for a wrong length or protocol
        version (e.g. a radar speaking another DBC revision).
        """
        aid = message.arbitration_id
        if message.is_extended_id:
            raise UnknownMessageError(f"CAN identifier 0x{aid:08X} is a 29-bit identifier; the radar protocol uses "
                                      f"11-bit identifiers (DBC {self.source})")
        name = self._by_id.get(aid)
        if name is None:
            kind = self.classify(aid)
            extra = {"data": "an ISO-TP payload identifier", "flow": "an ISO-TP flow-control identifier",
                     "other_sensor": "a message of another sensor_id"}.get(kind, "not in the protocol")
            raise UnknownMessageError(f"CAN identifier 0x{aid:03X} is {extra} (sensor_id {self.sensor_id}, "
                                      f"DBC {self.source})")
        msg = self._msgs[name]
        data = bytes(message.data)
        if len(data) != msg.length:
            raise ProtocolError(f"{name} (0x{aid:03X}): {len(data)} data bytes, the DBC declares {msg.length}")
        if crc8_j1850(data[1:]) != data[0]:
            raise E2EError(f"{name} (0x{aid:03X}): CRC-8 mismatch (got 0x{data[0]:02X}, "
                           f"computed 0x{crc8_j1850(data[1:]):02X}); message corrupted")
        raw = msg.decode(data, decode_choices=False, scaling=True)
        n = len(name) + 1
        out = {k[n:]: v for k, v in raw.items()}
        if out["ProtocolVersion"] != PROTOCOL_VERSION:
            raise ProtocolError(f"{name} (0x{aid:03X}): protocol version {out['ProtocolVersion']}, this host "
                                f"speaks version {PROTOCOL_VERSION} (DBC mismatch between host and radar)")
        return name, out


# --- configuration ↔ signals ----------------------------------------------------------------
def config_signals(radar: RadarConfig, fmt: PayloadFormat, frame_interval: float,
                   config_id: int) -> tuple[dict[str, Any], dict[str, Any]]:
    """(RadarModeCfg signals, RadarCfg signals) describing ``radar`` for the bus."""
    mode = {"ConfigId": config_id, "Mimo": int(radar.mimo), "TxSteering": float(radar.tx_steering),
            "FrameInterval": float(frame_interval)}
    cfg = {"ConfigId": config_id, "PayloadFormat": int(fmt), "NTx": radar.n_tx, "NRx": radar.n_rx,
           "NSamples": radar.n_samples, "NAzimuthBins": radar.n_azimuth_bins,
           "NRangeBins": radar.n_range_bins, "ConfigHash": radar_hash(radar),
           "CarrierFrequency": float(radar.carrier_frequency), "Bandwidth": float(radar.bandwidth),
           "ChirpDuration": float(radar.chirp_duration), "MaxRange": float(radar.max_range),
           "FieldOfView": float(radar.field_of_view)}
    return mode, cfg


def radar_from_signals(base: RadarConfig, cfg: dict[str, Any], mode: dict[str, Any] | None) -> RadarConfig:
    """The RadarConfig a radar built on ``base`` adopts from RadarCfg (+ RadarModeCfg) signals.

    Raises ProtocolError when the values do not form a valid RadarConfig or the derived
    range-bin count disagrees with the message.
    """
    upd = {"n_tx": int(cfg["NTx"]), "n_rx": int(cfg["NRx"]), "n_samples": int(cfg["NSamples"]),
           "n_azimuth_bins": int(cfg["NAzimuthBins"]), "carrier_frequency": float(cfg["CarrierFrequency"]),
           "bandwidth": float(cfg["Bandwidth"]), "chirp_duration": float(cfg["ChirpDuration"]),
           "max_range": float(cfg["MaxRange"]), "field_of_view": float(cfg["FieldOfView"])}
    if mode is not None:
        upd.update(mimo=bool(mode["Mimo"]), tx_steering=float(mode["TxSteering"]))
    try:
        radar = RadarConfig.model_validate({**base.model_dump(), **upd})
    except Exception as exc:
        raise ProtocolError(f"RadarCfg: values do not form a valid radar configuration: {exc}") from None
    if radar.n_range_bins != int(cfg["NRangeBins"]):
        raise ProtocolError(f"RadarCfg: NRangeBins {cfg['NRangeBins']} ≠ {radar.n_range_bins} derived from "
                            "MaxRange and Bandwidth")
    return radar


# --- payloads -------------------------------------------------------------------------------
@dataclass(frozen=True)
class PayloadSpec:
    """What a frame payload of ``fmt`` must look like for ``radar``: shape (Shape0, Shape1) and bytes."""

    fmt: PayloadFormat
    shape: tuple[int, int]
    nbytes: int

    @classmethod
    def for_radar(cls, radar: RadarConfig, fmt: PayloadFormat) -> "PayloadSpec":
        fmt = PayloadFormat(fmt)
        if fmt == PayloadFormat.RA_COMPLEX64:
            shape = (radar.n_range_bins, radar.n_azimuth_bins)
            per = 8
        else:
            shape = (radar.n_samples, radar.n_channels)
            per = 4 if fmt == PayloadFormat.ADC_INT16 else 8
        return cls(fmt, shape, shape[0] * shape[1] * per)

    @property
    def item_bytes(self) -> int:
        """Bytes of the ISO-TP item: sequence prefix + payload."""
        return SEQ_PREFIX.size + self.nbytes

    def check_header(self, header: dict[str, Any]) -> str | None:
        """None if a FrameHeader announces this payload, else the reason it does not (never allocates)."""
        fmt = header.get("PayloadFormat")
        if fmt != int(self.fmt):
            return f"header announces payload format {fmt}, configured {self.fmt.name} ({int(self.fmt)})"
        shape = (header.get("Shape0"), header.get("Shape1"))
        if shape != self.shape:
            return f"header announces shape {shape}, the configured radar gives {self.shape}"
        if header.get("PayloadBytes") != self.nbytes:
            return f"header announces {header.get('PayloadBytes')} payload bytes, expected {self.nbytes}"
        if self.fmt == PayloadFormat.ADC_INT16:
            scale = header.get("Scale")
            if not (isinstance(scale, float) and np.isfinite(scale) and scale > 0):
                return f"header announces ADC scale {scale!r} √W/LSB, expected a finite value > 0"
        return None


def encode_payload(fmt: PayloadFormat, radar: RadarConfig, ra_map: RAMap | None = None,
                   cube: np.ndarray | None = None) -> tuple[bytes, float]:
    """(payload bytes, scale [√W/LSB]) of a frame: the RA map for RA_COMPLEX64, else the ADC cube
    (n_samples, n_channels) complex [√W]. int16 I/Q use a per-frame scale (peak → 32767, float32)."""
    fmt = PayloadFormat(fmt)
    if fmt == PayloadFormat.RA_COMPLEX64:
        if ra_map is None:
            raise InputError("encode_payload: RA_COMPLEX64 needs the RA map")
        return np.ascontiguousarray(ra_map.data, dtype="<c8").tobytes(), 1.0
    if cube is None:
        raise InputError(f"encode_payload: {fmt.name} needs the ADC cube")
    c = np.asarray(cube)
    want = (radar.n_samples, radar.n_channels)
    if c.shape != want:
        raise InputError(f"encode_payload: ADC cube shape {c.shape}, expected (n_samples, n_channels) = {want}")
    if fmt == PayloadFormat.ADC_COMPLEX64:
        return np.ascontiguousarray(c, dtype="<c8").tobytes(), 1.0
    from hardware.adc import AdcLayout, encode_adc_cube

    peak = float(np.max(np.abs(np.concatenate([c.real.ravel(), c.imag.ravel()])))) if c.size else 0.0
    scale = float(np.nextafter(np.float32(peak / 32767.0), np.float32(np.inf))) if peak > 0 else 1.0
    layout = AdcLayout(axes=("sample", "channel"), sample_format="iq", scale=scale)
    raw, _ = encode_adc_cube(c, layout, radar, dtype=np.int16)
    return np.ascontiguousarray(raw, dtype="<i2").tobytes(), scale


def decode_payload(spec: PayloadSpec, header: dict[str, Any], payload: bytes, radar: RadarConfig) -> RAMap:
    """The RAMap a checked payload carries (ADC cubes through :func:`hardware.adc.adc_cube_to_ra_map`)."""
    if len(payload) != spec.nbytes:
        raise ProtocolError(f"payload of {len(payload)} bytes, expected {spec.nbytes}")
    if spec.fmt == PayloadFormat.RA_COMPLEX64:
        data = np.frombuffer(payload, dtype="<c8").reshape(spec.shape).astype(np.complex64, copy=True)
        return RAMap.from_radar(data, radar)
    from hardware.adc import AdcLayout, adc_cube_to_ra_map

    if spec.fmt == PayloadFormat.ADC_INT16:
        raw = np.frombuffer(payload, dtype="<i2").reshape(*spec.shape, 2)
        layout = AdcLayout(axes=("sample", "channel"), sample_format="iq", scale=float(header["Scale"]))
    else:
        raw = np.frombuffer(payload, dtype="<c8").reshape(spec.shape)
        layout = AdcLayout(axes=("sample", "channel"), sample_format="complex", scale=1.0)
    return adc_cube_to_ra_map(raw, layout, radar)
