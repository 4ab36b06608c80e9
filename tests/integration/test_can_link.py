"""`can` backend against the device emulator on the in-process virtual bus: configuration, streaming,
bit-identical payloads, the fault matrix with exact counts, reconnection, and bad input."""
import threading
import time

import can
import numpy as np
import pytest

from hardware.can_backend import CANBackend
from hardware.emulator import RadarEmulator
from hardware.faults import Fault, FaultyBus
from hardware.link import BusSpec, CanLink, open_bus
from hardware.protocol import LinkError, PayloadFormat, Protocol, crc8_j1850
from hardware.testing import emulated_link, private_channel, small_radar
from hardware.adc import AdcLayout, adc_cube_to_ra_map, encode_adc_cube
from xnlos_core.errors import InputError
from xnlos_core.registry import get_registry
from xnlos_core.scene import load_scene

RADAR = small_radar()
SCENE = load_scene({"builtin": "corner"}, "test")


def test_stream_is_bit_identical_to_the_forward_model(emulated_reference):
    with emulated_link(RADAR, seed=7) as (backend, em):
        frames = list(backend.frames(5))
        st = backend.stats
    assert [f.index for f in frames] == [0, 1, 2, 3, 4]
    for k, f in enumerate(frames):
        ref = emulated_reference(7, k)
        assert np.array_equal(f.ra_map.data, ref.ra_map.data)  # exact complex64 equality
        assert f.timestamp == ref.timestamp and f.ra_map.radar == RADAR
        assert np.array_equal(f.ra_map.range_axis, RADAR.range_axis)
        assert f.ground_truth is None and f.meta["seq"] == k and f.meta["payload_format"] == "RA_COMPLEX64"
    assert (st.frames_ok, st.frames_lost, st.frames_late, st.frames_duplicate) == (5, 0, 0, 0)
    assert st.bytes_ok == 5 * RADAR.n_range_bins * RADAR.n_azimuth_bins * 8 and em.frames_sent == 5


def test_frames_continue_across_calls_and_early_stop():
    with emulated_link(RADAR, seed=1, pace=True) as (backend, em):
        it = backend.frames(10)
        first = [next(it).index for _ in range(2)]
        it.close()  # consumer stops early: the radar is told to stop
        rest = [f.index for f in backend.frames(3)]
    assert first == [0, 1] and rest[0] >= 2 and rest == list(range(rest[0], rest[0] + 3))


@pytest.mark.parametrize("payload", ["adc_int16", "adc_complex64"])
def test_adc_payloads_go_through_the_shared_chain(payload, emulated_reference):
    with emulated_link(RADAR, seed=3, payload=payload) as (backend, _):
        frames = list(backend.frames(2))
    for k, f in enumerate(frames):
        cube, ref = emulated_reference(3, k, adc=True)
        if payload == "adc_int16":
            peak = float(np.max(np.abs(np.concatenate([cube.real.ravel(), cube.imag.ravel()]))))
            scale = float(np.nextafter(np.float32(peak / 32767.0), np.float32(np.inf)))
            layout = AdcLayout(axes=("sample", "channel"), sample_format="iq", scale=scale)
            raw, _ = encode_adc_cube(cube, layout, RADAR, dtype=np.int16)
        else:
            layout = AdcLayout(axes=("sample", "channel"), sample_format="complex")
            raw = cube.astype(np.complex64)
        assert np.array_equal(f.ra_map.data, adc_cube_to_ra_map(raw, layout, RADAR).data)
        assert np.abs(f.ra_map.data - ref.ra_map.data).max() < 1e-3 * np.abs(ref.ra_map.data).max()
        assert f.meta["payload_format"] == payload.upper()


def test_fault_matrix(fault_case, fault_matrix, emulated_reference):
    faults, want_seq, want_lost, counters = fault_matrix[fault_case]
    with emulated_link(RADAR, tx_faults=faults, seed=2) as (backend, _):
        frames = list(backend.frames(6))
        st = backend.stats
    assert all(f.done for f in faults), "every fault fired"
    assert [f.index for f in frames] == want_seq
    assert [(x.seq, x.kind) for x in st.lost] == want_lost
    kinds = [k for _, k in want_lost]
    assert st.frames_ok == 6
    assert (st.frames_dropped, st.frames_incomplete, st.frames_corrupted) == (
        kinds.count("dropped"), kinds.count("incomplete"), kinds.count("corrupted"))
    assert (st.frames_late, st.bus_errors, st.reconnects) == (0, 0, 0)
    for name, value in counters.items():
        assert getattr(st, name) == value, name
    for f in frames:  # what is delivered is exactly what the model produced
        assert np.array_equal(f.ra_map.data, emulated_reference(2, f.index).ra_map.data)
    if want_lost:
        nxt = next(f for f in frames if f.index > want_lost[0][0])
        assert want_lost[0][0] in nxt.meta["lost_before"]


def test_bus_error_reconnects_and_reports_the_frame():
    # One frame per START (chunk = 1): the radar sends frame 3 only when the reconnected host asks for
    # it. With a streaming radar, frame 3 went out while the host's bus was closed whenever the
    # reconnection took longer than one frame period (a loaded machine): [0, 1, 4, 5, 6].
    faults = [Fault("bus_error", 2, "cf", 3)]
    with emulated_link(RADAR, rx_faults=faults, seed=4, chunk=1) as (backend, _):
        frames = list(backend.frames(5))
        st = backend.stats
    assert faults[0].done
    assert [f.index for f in frames] == [0, 1, 3, 4, 5]
    assert [(x.seq, x.kind) for x in st.lost] == [(2, "incomplete")]
    assert (st.bus_errors, st.reconnects, st.frames_ok, st.frames_lost) == (1, 1, 5, 1)


def test_silent_device_times_out_reconnects_and_resumes():
    with emulated_link(RADAR, seed=5, pace=True, frame_interval=0.05) as (backend, em):
        em.silence(3.0, after_seq=1)  # twice emulated_link's 1.5 s timeout: one timeout, on a loaded machine too
        frames = list(backend.frames(4))
        st = backend.stats
    assert [f.index for f in frames] == [0, 1, 2, 3]
    assert (st.timeouts, st.reconnects, st.frames_lost) == (1, 1, 0)


def test_device_that_never_comes_back_raises_link_error():
    with emulated_link(RADAR, pace=True, max_reconnects=2) as (backend, em):
        em.silence(60.0, after_seq=0)  # longer than the test: only giving up after 2 reconnects ends it
        with pytest.raises(LinkError, match=r"radar sensor 0 on virtual:.*not recovered after 2"):
            list(backend.frames(3))


def test_no_device_gives_a_clear_error_without_hanging():
    b = CANBackend({"channel": private_channel(), "emulate": "never", "response_timeout": 0.1, "retries": 1})
    with pytest.raises(LinkError, match=r"no RadarState answer from radar sensor 0 on virtual:xnlos-test.*2 attempt"):
        b.open(RADAR)  # bounded by the attempts counted in the message, not by a clock
    b.close()
    with pytest.raises(InputError, match="open"):
        next(CANBackend({"emulate": "never"}).frames(1))
    with pytest.raises(InputError, match="max_frames"):
        next(CANBackend({"emulate": "never"}).frames(-1))


def test_configuration_mismatch_is_rejected_with_both_hashes():
    other = RADAR.model_copy(update={"noise_figure_db": 12.0})
    with pytest.raises(LinkError, match=r"rejected the configuration: CONFIG_MISMATCH \(host RadarConfig hash 0x"):
        with emulated_link(RADAR, emulator_radar=other):
            pass


def test_unknown_identifiers_and_other_sensors_are_counted_and_ignored():
    channel = private_channel()
    with emulated_link(RADAR, channel=channel, seed=6) as (backend, _):
        intruder = open_bus(BusSpec(channel=channel))
        try:
            other = Protocol.load(sensor_id=1)
            intruder.send(can.Message(arbitration_id=0x7FF, data=b"\1" * 8, is_extended_id=False))
            intruder.send(can.Message(arbitration_id=0x2F0, data=b"\2" * 8, is_extended_id=False))
            intruder.send(can.Message(arbitration_id=0x201, data=b"\3" * 8, is_extended_id=True))
            intruder.send(other.encode("RadarError", {"ErrorCode": 5, "Seq": 0, "Detail": 0}))
            frames = list(backend.frames(3))
        finally:
            intruder.shutdown()
        st = backend.stats
    assert [f.index for f in frames] == [0, 1, 2]
    assert (st.unknown_ids, st.other_sensor, st.frames_lost, st.device_errors) == (3, 1, 0, 0)


def test_first_frame_announcing_an_absurd_size_is_refused_without_allocation():
    channel = private_channel()
    with emulated_link(RADAR, channel=channel, seed=6) as (backend, _):
        rogue = open_bus(BusSpec(channel=channel))
        try:
            ff = bytes([0x10, 0x00, 0xFF, 0xFF, 0xFF, 0xFF]) + b"\0" * 58  # ISO-TP FF, length 4 GiB - 1
            rogue.send(can.Message(arbitration_id=Protocol.load().data_id, data=ff, is_fd=True,
                                   is_extended_id=False))
            # Stream only once the host has refused the rogue transfer (its overflow flow control is
            # on the bus): a refusal that reached the radar mid-transfer would rightly abort frame 0.
            t_end, refused = time.monotonic() + 5.0, False
            while not refused and time.monotonic() < t_end:
                msg = rogue.recv(timeout=0.1)
                refused = msg is not None and msg.arbitration_id == Protocol.load().flow_id
            assert refused, "the host never answered the oversized first frame with flow control"
            frames = list(backend.frames(2))
        finally:
            rogue.shutdown()
        st = backend.stats
    assert [f.index for f in frames] == [0, 1] and st.transfer_errors == 1 and st.frames_lost == 0


def test_radar_speaking_another_protocol_version_is_named():
    channel = private_channel()
    proto = Protocol.load()
    stop = threading.Event()

    def old_radar():
        bus = open_bus(BusSpec(channel=channel))
        try:
            while not stop.is_set():
                msg = proto.encode("RadarState", {"State": 1, "PayloadFormat": 0, "ConfigId": 1, "ConfigHash": 0,
                                                  "NextSeq": 0, "FramesRemaining": 0, "ErrorCode": 0, "RequestId": 0,
                                                  "Uptime": 0.0, "Temperature": 40})
                data = bytearray(msg.data)
                data[1] = (data[1] & 0x0F) | (2 << 4)
                data[0] = crc8_j1850(bytes(data[1:]))
                bus.send(can.Message(arbitration_id=msg.arbitration_id, data=bytes(data), is_fd=True,
                                     is_extended_id=False))
                stop.wait(0.02)
        finally:
            bus.shutdown()

    t = threading.Thread(target=old_radar, daemon=True)
    t.start()
    try:
        b = CANBackend({"channel": channel, "emulate": "never", "response_timeout": 0.15, "retries": 0})
        with pytest.raises(LinkError, match="protocol version 2, this host speaks version 1"):
            b.open(RADAR)
        assert b.stats.e2e_errors >= 1
    finally:
        stop.set()
        t.join(2)


def test_two_radars_share_one_bus(emulated_reference):
    channel = private_channel()
    fm = get_registry().create("forward_model", "image")
    ems = [RadarEmulator(fm, SCENE, RADAR, BusSpec(channel=channel), sensor_id=s, seed=10 + s, pace=False,
                         status_period=0.05).start() for s in (0, 1)]
    backends = [CANBackend({"channel": channel, "sensor_id": s, "emulate": "never", "frame_interval": 0.05})
                for s in (0, 1)]
    try:
        for b in backends:
            b.open(RADAR)
        got = {s: list(b.frames(2)) for s, b in enumerate(backends)}
    finally:
        for b in backends:
            b.close()
        for em in ems:
            em.stop()
    for s in (0, 1):
        assert [f.meta["sensor_id"] for f in got[s]] == [s, s]
        assert np.array_equal(got[s][1].ra_map.data, emulated_reference(10 + s, 1).ra_map.data)
    assert backends[0].stats.other_sensor > 0 and backends[0].stats.frames_lost == 0


def test_faulty_bus_and_link_reject_bad_arguments():
    proto = Protocol.load()
    with pytest.raises(ValueError, match="kind"):
        Fault("explode", 1)
    with pytest.raises(ValueError, match="header"):
        Fault("checksum", 1, "cf")
    bus = open_bus(BusSpec(channel=private_channel()))
    with pytest.raises(ValueError, match="direction"):
        FaultyBus(bus, [], proto, "sideways")
    bus.shutdown()
    with pytest.raises(ValueError, match="role"):
        CanLink(BusSpec(), proto, "observer", max_item=10)
    with pytest.raises(LinkError, match="'nosuchcan' is not available"):
        open_bus(BusSpec(interface="nosuchcan"))
    assert PayloadFormat.ADC_INT16 == 1


def test_radar_that_streams_nothing_is_detected():
    with emulated_link(RADAR, max_reconnects=2, timeout=0.2, frame_timeout=0.2) as (backend, em):
        em._send_frame = lambda: None  # alive, acknowledges START, never sends a frame
        with pytest.raises(LinkError, match="without a single frame delivered"):
            list(backend.frames(2))
        st = backend.stats
    assert st.timeouts >= 2 and st.reconnects == 2
