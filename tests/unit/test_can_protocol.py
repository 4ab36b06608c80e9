"""Radar CAN protocol: DBC declaration, cantools encode/decode, E2E, sensor offsets, payload codecs."""
import math
import re

import can
import numpy as np
import pytest

from hardware.protocol import (DEFAULT_DBC, PROTOCOL_VERSION, SEQ_PREFIX, E2EError, PayloadFormat, PayloadSpec,
                               Protocol, ProtocolError, UnknownMessageError, config_signals, crc8_j1850,
                               decode_payload, encode_payload, radar_from_signals, radar_hash)
from hardware.testing import small_radar
from hardware.adc import AdcLayout, adc_cube_to_ra_map, encode_adc_cube
from xnlos_core.registry import get_registry
from xnlos_core.scene import load_scene

RADAR = small_radar()


def test_dbc_declares_the_protocol_with_sensor_offsets():
    p0, p3 = Protocol.load(), Protocol.load(sensor_id=3)
    assert p0.ids == {"RadarCfg": 0x200, "RadarModeCfg": 0x204, "RadarState": 0x201, "RadarCtrl": 0x202,
                      "RadarError": 0x203, "FrameHeader": 0x300, "FrameData": 0x400, "FrameFlowControl": 0x401}
    assert all(p3.ids[k] == v + 0x30 for k, v in p0.ids.items())
    fd = {m.name: (m.length, m.is_fd) for m in p0.db.messages}
    assert fd["RadarCfg"] == (64, True) and fd["FrameHeader"] == (32, True) and fd["RadarCtrl"] == (8, False)
    assert p3.classify(0x330) == "signal" and p3.classify(0x430) == "data" and p3.classify(0x431) == "flow"
    assert p3.classify(0x300) == "other_sensor" and p3.classify(0x7FF) == "unknown"
    with pytest.raises(ProtocolError, match="sensor_id"):
        Protocol.load(sensor_id=8)


def test_crc8_sae_j1850_check_value():
    assert crc8_j1850(b"123456789") == 0x4B


def _examples():
    mode, cfg = config_signals(RADAR.model_copy(update={"mimo": False, "tx_steering": -0.25}),
                               PayloadFormat.ADC_INT16, 0.1, 7)
    return {
        "RadarModeCfg": mode, "RadarCfg": cfg,
        "RadarState": {"State": 2, "PayloadFormat": 1, "ConfigId": 7, "ConfigHash": 0xDEADBEEF, "NextSeq": 2**32 - 1,
                       "FramesRemaining": 5, "ErrorCode": 0, "RequestId": 9, "Uptime": 12.345, "Temperature": 45},
        "RadarCtrl": {"Command": 1, "NFrames": 100, "RequestId": 9},
        "RadarError": {"ErrorCode": 7, "Seq": 12345, "Detail": 3},
        "FrameHeader": {"PayloadFormat": 0, "ConfigId": 7, "Seq": 42, "Timestamp": 0.30000000000000004,
                        "Shape0": 81, "Shape1": 31, "PayloadBytes": 20088, "PayloadCrc32": 0x01234567, "Scale": 1.5},
    }


@pytest.mark.parametrize("name", list(_examples()))
def test_encode_decode_round_trip(name):
    p = Protocol.load(sensor_id=2)
    sig = _examples()[name]
    msg = p.encode(name, sig)
    assert msg.arbitration_id == p.ids[name] and not msg.is_extended_id
    got_name, got = p.decode(msg)
    assert got_name == name and got["ProtocolVersion"] == PROTOCOL_VERSION
    for k, v in sig.items():
        assert got[k] == pytest.approx(v, rel=0, abs=1e-9 if isinstance(v, float) and k == "Uptime" else 0), k


def test_doubles_travel_exactly():
    p = Protocol.load()
    _, got = p.decode(p.encode("FrameHeader", _examples()["FrameHeader"]))
    assert got["Timestamp"] == 0.30000000000000004
    radar = RADAR.model_copy(update={"carrier_frequency": 9.87654321e9, "field_of_view": math.radians(47.3)})
    mode, cfg = config_signals(radar, PayloadFormat.RA_COMPLEX64, 0.1, 1)
    _, c = p.decode(p.encode("RadarCfg", cfg))
    _, m = p.decode(p.encode("RadarModeCfg", mode))
    assert m["FrameInterval"] == 0.1
    rebuilt = radar_from_signals(RADAR, c, m)
    assert radar_hash(rebuilt) == radar_hash(radar) == c["ConfigHash"]


def test_e2e_and_length_and_version_checks():
    p = Protocol.load()
    msg = p.encode("RadarCtrl", {"Command": 1, "NFrames": 3, "RequestId": 1})
    bad = bytearray(msg.data)
    bad[4] ^= 0x10
    with pytest.raises(E2EError, match="RadarCtrl.*CRC-8"):
        p.decode(can.Message(arbitration_id=msg.arbitration_id, data=bytes(bad), is_extended_id=False))
    with pytest.raises(ProtocolError, match="7 data bytes, the DBC declares 8"):
        p.decode(can.Message(arbitration_id=msg.arbitration_id, data=bytes(msg.data[:7]), is_extended_id=False))
    v2 = bytearray(msg.data)
    v2[1] = (v2[1] & 0x0F) | (2 << 4)  # protocol version 2 in bits 12..15
    v2[0] = crc8_j1850(bytes(v2[1:]))
    with pytest.raises(ProtocolError, match="protocol version 2.*version 1"):
        p.decode(can.Message(arbitration_id=msg.arbitration_id, data=bytes(v2), is_extended_id=False))
    with pytest.raises(ProtocolError, match="RadarCtrl_NFrames|NFrames"):
        p.encode("RadarCtrl", {"Command": 1, "NFrames": -1, "RequestId": 1})
    with pytest.raises(ProtocolError, match="not a signal message"):
        p.encode("FrameData", {})


def test_unknown_identifiers_are_named():
    p = Protocol.load()
    with pytest.raises(UnknownMessageError, match="0x7FF is not in the protocol"):
        p.decode(can.Message(arbitration_id=0x7FF, data=b"\0" * 8, is_extended_id=False))
    with pytest.raises(UnknownMessageError, match="0x211 is a message of another sensor_id"):
        p.decode(can.Message(arbitration_id=0x211, data=b"\0" * 8, is_extended_id=False))
    with pytest.raises(UnknownMessageError, match="ISO-TP payload"):
        p.decode(can.Message(arbitration_id=0x400, data=b"\0" * 8, is_extended_id=False))
    with pytest.raises(UnknownMessageError, match="29-bit"):
        p.decode(can.Message(arbitration_id=0x201, data=b"\0" * 32, is_extended_id=True))


def test_dbc_mismatch_lists_every_difference(tmp_path):
    text = DEFAULT_DBC.read_text()
    text = text.replace(" SG_ FrameHeader_Seq : 32|32@1+", " SG_ FrameHeader_Seq : 32|16@1+")
    start = text.index("BO_ 513 RadarState")
    text = text[:start] + text[text.index("BO_ 514 RadarCtrl"):]
    text = re.sub(r'^(CM_ SG_ 513|BA_ "VFrameFormat" BO_ 513|BA_ "GenMsgCycleTime" BO_ 513|VAL_ 513|CM_ BO_ 513).*\n',
                  "", text, flags=re.M)
    bad = tmp_path / "vendor.dbc"
    bad.write_text(text)
    with pytest.raises(ProtocolError) as exc:
        Protocol.load(bad)
    msg = str(exc.value)
    assert str(bad) in msg and "RadarState (0x201) is missing" in msg and "FrameHeader_Seq" in msg
    (tmp_path / "junk.dbc").write_text("this is not a DBC file {")
    with pytest.raises(ProtocolError, match="junk.dbc"):
        Protocol.load(tmp_path / "junk.dbc")
    with pytest.raises(ProtocolError, match="does not exist"):
        Protocol.load(tmp_path / "missing.dbc")
    v2 = tmp_path / "v2.dbc"
    v2.write_text(DEFAULT_DBC.read_text().replace('BA_ "ProtocolVersion" 1;', 'BA_ "ProtocolVersion" 2;'))
    with pytest.raises(ProtocolError, match="ProtocolVersion is 2, expected 1"):
        Protocol.load(v2)


def test_radar_from_signals_rejects_inconsistent_values():
    _, cfg = config_signals(RADAR, PayloadFormat.RA_COMPLEX64, 0.1, 1)
    with pytest.raises(ProtocolError, match="NRangeBins"):
        radar_from_signals(RADAR, {**cfg, "NRangeBins": 999}, None)
    with pytest.raises(ProtocolError, match="valid radar configuration"):
        radar_from_signals(RADAR, {**cfg, "MaxRange": 1e5}, None)


def test_payload_spec_refuses_absurd_headers():
    spec = PayloadSpec.for_radar(RADAR, PayloadFormat.RA_COMPLEX64)
    assert spec.shape == (81, 31) and spec.nbytes == 81 * 31 * 8 and spec.item_bytes == spec.nbytes + 4
    good = {"PayloadFormat": 0, "Shape0": 81, "Shape1": 31, "PayloadBytes": spec.nbytes, "Scale": 1.0}
    assert spec.check_header(good) is None
    assert "4294967295 payload bytes" in spec.check_header({**good, "PayloadBytes": 2**32 - 1})
    assert "shape (65535, 65535)" in spec.check_header({**good, "Shape0": 65535, "Shape1": 65535})
    assert "format 1" in spec.check_header({**good, "PayloadFormat": 1})
    adc = PayloadSpec.for_radar(RADAR, PayloadFormat.ADC_INT16)
    assert adc.shape == (128, 32) and adc.nbytes == 128 * 32 * 4
    assert "scale" in adc.check_header({"PayloadFormat": 1, "Shape0": 128, "Shape1": 32, "PayloadBytes": adc.nbytes,
                                        "Scale": float("nan")})


def test_payload_codecs():
    fm = get_registry().create("forward_model", "image")
    cube, frame = fm.simulate_adc(load_scene({"builtin": "corner"}, "t"), RADAR, np.random.default_rng(0))
    data, scale = encode_payload(PayloadFormat.RA_COMPLEX64, RADAR, ra_map=frame.ra_map)
    spec = PayloadSpec.for_radar(RADAR, PayloadFormat.RA_COMPLEX64)
    ra = decode_payload(spec, {}, data, RADAR)
    assert scale == 1.0 and np.array_equal(ra.data, frame.ra_map.data) and ra.radar == RADAR
    assert not np.shares_memory(ra.data, np.frombuffer(data, np.uint8))  # a copy, not a view of the bus bytes
    for fmt in (PayloadFormat.ADC_INT16, PayloadFormat.ADC_COMPLEX64):
        data, scale = encode_payload(fmt, RADAR, cube=cube)
        spec = PayloadSpec.for_radar(RADAR, fmt)
        assert len(data) == spec.nbytes
        ra = decode_payload(spec, {"Scale": scale}, data, RADAR)
        if fmt == PayloadFormat.ADC_INT16:
            layout = AdcLayout(axes=("sample", "channel"), sample_format="iq", scale=scale)
            raw, clipped = encode_adc_cube(cube, layout, RADAR, dtype=np.int16)
            assert clipped == 0 and np.array_equal(ra.data, adc_cube_to_ra_map(raw, layout, RADAR).data)
        peak = np.abs(frame.ra_map.data).max()
        assert np.abs(ra.data - frame.ra_map.data).max() < 1e-3 * peak
    with pytest.raises(ProtocolError, match="payload of 3 bytes"):
        decode_payload(spec, {}, b"abc", RADAR)
    assert SEQ_PREFIX.size == 4
