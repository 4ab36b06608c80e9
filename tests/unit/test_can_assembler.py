"""Frame reassembly rules with exact counts (no bus): order, gaps, duplicates, late, corrupt, deadlines."""
import numpy as np
import pytest

from hardware.assembler import FrameAssembler, LinkStats, LostFrame
from hardware.protocol import SEQ_PREFIX, PayloadFormat, PayloadSpec, payload_crc32
from hardware.testing import small_radar
from xnlos_core.types import Frame

RADAR = small_radar(max_range=5.0, n_azimuth_bins=7)
SPEC = PayloadSpec.for_radar(RADAR, PayloadFormat.RA_COMPLEX64)


def frame_parts(seq, scale=1.0):
    rng = np.random.default_rng(seq)
    data = (rng.standard_normal(SPEC.shape) + 1j * rng.standard_normal(SPEC.shape)).astype(np.complex64) * scale
    item = SEQ_PREFIX.pack(seq) + data.tobytes()
    header = {"Seq": seq, "PayloadFormat": 0, "ConfigId": 1, "Timestamp": 0.1 * seq, "Shape0": SPEC.shape[0],
              "Shape1": SPEC.shape[1], "PayloadBytes": SPEC.nbytes, "PayloadCrc32": payload_crc32(item), "Scale": 1.0}
    return header, item, data


def make(first=0, n=None, timeout=1.0):
    stats = LinkStats()
    asm = FrameAssembler(RADAR, PayloadFormat.RA_COMPLEX64, stats, frame_timeout=timeout)
    asm.expect(first, n, 0.0)
    return asm, stats


def drain(asm):
    out = []
    while (x := asm.pop()) is not None:
        out.append(x)
    return out


def outcome(outs):
    return [(x.index, "ok") if isinstance(x, Frame) else (x.seq, x.kind) for x in outs]


def test_in_order_and_reordered_headers_deliver_exact_data():
    asm, st = make(0, 3)
    parts = [frame_parts(s) for s in range(3)]
    asm.on_header(parts[0][0], 0.0)
    asm.on_item(parts[0][1], 0.0)
    asm.on_item(parts[1][1], 0.1)  # payload before its header
    asm.on_header(parts[1][0], 0.1)
    asm.on_header(parts[2][0], 0.2)
    asm.on_item(parts[2][1], 0.2)
    outs = drain(asm)
    assert outcome(outs) == [(0, "ok"), (1, "ok"), (2, "ok")]
    for f, (_, _, data) in zip(outs, parts):
        assert np.array_equal(f.ra_map.data, data) and f.meta["seq"] == f.index
    assert f.timestamp == 0.2 and st.frames_ok == 3 and st.bytes_ok == 3 * SPEC.nbytes and asm.idle


def test_gap_drop_incomplete_and_lost_before():
    asm, st = make(0, 5)
    p = [frame_parts(s) for s in range(5)]
    asm.on_header(p[0][0], 0)
    asm.on_item(p[0][1], 0)
    asm.on_header(p[2][0], 0)  # frame 1: nothing arrives; frame 2: header only
    asm.on_header(p[3][0], 0)
    asm.on_item(p[3][1], 0)  # completes 3: 1 and 2 can no longer complete
    asm.on_item(p[4][1], 0)  # 4: payload, never a header ...
    asm.poll(0.5)
    assert outcome(drain(asm)) == [(0, "ok"), (1, "dropped"), (2, "incomplete"), (3, "ok")]
    asm.poll(1.5)  # ... until the deadline
    out = drain(asm)
    assert outcome(out) == [(4, "incomplete")] and "header missing" in out[0].reason
    assert (st.frames_ok, st.frames_dropped, st.frames_incomplete, st.frames_lost) == (2, 1, 2, 3)
    assert st.lost_seqs() == [1, 2, 4]


def test_lost_before_is_attached_to_the_next_delivered_frame():
    asm, _ = make(0, 3)
    p = [frame_parts(s) for s in range(3)]
    asm.on_header(p[2][0], 0)
    asm.on_item(p[2][1], 0)
    out = drain(asm)
    assert outcome(out) == [(0, "dropped"), (1, "dropped"), (2, "ok")]
    assert out[2].meta["lost_before"] == [0, 1]


def test_duplicate_and_late_are_counted_never_delivered():
    asm, st = make(0, 3, timeout=0.2)
    p = [frame_parts(s) for s in range(3)]
    asm.on_header(p[0][0], 0)
    asm.on_item(p[0][1], 0)
    asm.on_item(p[0][1], 0.01)  # second copy after delivery
    asm.on_header(p[1][0], 0.02)
    asm.poll(0.5)  # frame 1 times out (header only) ...
    asm.on_item(p[1][1], 0.6)  # ... then its payload shows up: late
    asm.on_header(p[2][0], 0.7)
    asm.on_item(p[2][1], 0.7)
    asm.on_item(p[2][1], 0.71)
    assert outcome(drain(asm)) == [(0, "ok"), (1, "incomplete"), (2, "ok")]
    assert (st.frames_duplicate, st.frames_late, st.frames_ok) == (2, 1, 2)
    asm.on_item(frame_parts(3)[1], 0.8)  # beyond the request [0, 3)
    assert st.frames_late == 2 and drain(asm) == []


def test_corrupted_checksum_and_absurd_header():
    asm, st = make(0, 3)
    h0, i0, _ = frame_parts(0)
    bad = bytearray(i0)
    bad[100] ^= 1
    asm.on_header(h0, 0)
    asm.on_item(bytes(bad), 0)
    h1, i1, _ = frame_parts(1)
    asm.on_header({**h1, "PayloadBytes": 2**32 - 1, "Shape0": 65535}, 0)
    asm.on_item(i1, 0)
    h2, i2, _ = frame_parts(2)
    asm.on_header(h2, 0)
    asm.on_item(i2, 0)
    out = drain(asm)
    assert outcome(out) == [(0, "corrupted"), (1, "corrupted"), (2, "ok")]
    assert "CRC-32 mismatch" in out[0].reason and "65535" in out[1].reason
    assert st.frames_corrupted == 2


def test_conflicting_duplicate_headers_mark_the_frame_corrupted():
    asm, st = make(0, 1)
    h, i, _ = frame_parts(0)
    asm.on_header(h, 0)
    asm.on_header({**h, "Timestamp": 9.0}, 0)
    asm.on_item(i, 0)
    assert outcome(drain(asm)) == [(0, "corrupted")] and st.frames_corrupted == 1


def test_known_sent_frames_expire_and_unsent_ones_are_cancelled():
    asm, st = make(10, 5, timeout=0.2)
    asm.known_sent(12, 0.0)  # the radar says 10 and 11 went out
    asm.poll(0.3)
    assert outcome(drain(asm)) == [(10, "dropped"), (11, "dropped")]
    assert not asm.idle and asm.open_count == 3
    asm.cancel(0.3)  # the radar stopped: 12..14 will never be sent
    assert asm.idle and asm.open_count == 0 and st.frames_dropped == 2


def test_sequence_restart_and_corrupt_prefix():
    asm, st = make(100, 2)
    h, i, _ = frame_parts(100)
    asm.on_header(h, 0)
    asm.expect(0, 2, 0.1)  # the radar rebooted and numbers from 0
    out = drain(asm)
    assert outcome(out) == [(100, "incomplete")] and "restarted" in out[0].reason
    h0, i0, _ = frame_parts(0)
    asm.on_header(h0, 0.2)
    asm.on_item(i0, 0.2)
    assert outcome(drain(asm)) == [(0, "ok")]
    far = SEQ_PREFIX.pack(50_000) + b"\0" * SPEC.nbytes
    asm.on_item(far, 0.3)
    asm.on_item(b"\x01", 0.3)
    assert st.transfer_errors == 2 and drain(asm) == []


def test_open_ended_replay_mode_starts_at_the_first_frame():
    stats = LinkStats()
    asm = FrameAssembler(RADAR, PayloadFormat.RA_COMPLEX64, stats)
    asm.expect(None, None)
    for s in (7, 8):
        h, i, _ = frame_parts(s)
        asm.on_header(h, 0)
        asm.on_item(i, 0)
    assert outcome(drain(asm)) == [(7, "ok"), (8, "ok")]
    asm.on_header(frame_parts(9)[0], 1.0)
    asm.finish(1.0, "recording ended")
    out = drain(asm)
    assert isinstance(out[0], LostFrame) and out[0].reason == "recording ended"
    d = stats.as_dict()
    assert d["frames_ok"] == 2 and d["lost"][0]["seq"] == 9 and d["frames_lost"] == 1
    assert "ok=2" in stats.summary()


@pytest.mark.parametrize("n", [0, 1])
def test_expect_small_requests(n):
    asm, _ = make(5, n)
    assert asm.open_count == n and asm.idle == (n == 0)
