"""Record the bus to BLF / ASC and replay it as frames; damaged logs give clear errors."""
import numpy as np
import pytest

from hardware.faults import Fault
from hardware.recorder import BusRecorder
from hardware.replay import ReplayBackend, check_log
from hardware.testing import emulated_link, private_channel, small_radar
from hardware.link import BusSpec
from xnlos_core.errors import ConfigError, InputError

RADAR = small_radar()


def record(path, n=4, faults=None, **kw):
    channel = private_channel()
    with BusRecorder(path, BusSpec(channel=channel)) as rec:
        with emulated_link(RADAR, channel=channel, tx_faults=faults, seed=9, **kw) as (backend, _):
            live = list(backend.frames(n))
            stats = backend.stats
    assert path.is_file() and rec.messages > 0
    assert not path.with_name(f"{path.stem}.partial{path.suffix}").exists()
    return live, stats


def replay(path, radar=RADAR, n=None, **params):
    b = ReplayBackend({"file": str(path), **params})
    b.open(radar)
    return list(b.frames(n)), b.stats


@pytest.mark.parametrize("suffix", [".blf", ".asc"])
def test_record_and_replay_identically(tmp_path, suffix):
    path = tmp_path / f"run{suffix}"
    live, live_stats = record(path, faults=[Fault("drop", 1, "cf", 2)])
    frames, stats = replay(path)
    assert [f.index for f in live] == [0, 2, 3, 4]
    assert [f.index for f in frames] == [f.index for f in live]
    for a, b in zip(live, frames):
        assert np.array_equal(a.ra_map.data, b.ra_map.data) and a.timestamp == b.timestamp
        assert b.meta["source"] == "replay" and b.ra_map.radar == RADAR
    assert [(x.seq, x.kind) for x in stats.lost] == [(x.seq, x.kind) for x in live_stats.lost] == [(1, "incomplete")]
    assert (stats.frames_ok, stats.transfer_errors) == (4, 1)
    assert [f.index for f in replay(path, n=2)[0]] == [0, 2]


class _VirtualClock:
    """Stands in for python-can's player clock: sleeping advances virtual time, nothing waits, so
    the pacing is measured exactly and no CPU load can change it."""

    def __init__(self):
        self.now, self.slept = 0.0, 0.0

    def perf_counter(self):
        return self.now

    def sleep(self, seconds):
        self.now += seconds
        self.slept += seconds


def test_replay_at_recorded_speed(tmp_path, monkeypatch):
    import can.io.player

    path = tmp_path / "paced.blf"
    record(path, n=4, pace=True, frame_interval=0.1)
    with can.LogReader(str(path)) as reader:
        stamps = [m.timestamp for m in reader]
    log_span = stamps[-1] - stamps[0]  # the recorded bus time, which realtime replay waits out
    clock = _VirtualClock()
    monkeypatch.setattr(can.io.player, "time", clock)
    fast, _ = replay(path)
    assert clock.slept == 0.0  # as fast as the log reads
    slow, _ = replay(path, realtime=True)
    # paced at 0.1 s, four frames span three intervals (less only by the first frame's lateness);
    # the receiver's own clock is not compared: under load it lags the bus by a varying amount
    assert len(fast) == len(slow) == 4 and log_span > 0.2
    assert clock.slept == pytest.approx(log_span, abs=1e-3)  # every recorded gap waited out (< 0.1 ms skipped)


@pytest.mark.parametrize("suffix", [".blf", ".asc"])
def test_truncated_log_is_named(tmp_path, suffix):
    path = tmp_path / f"run{suffix}"
    record(path, n=2)
    blob = path.read_bytes()
    cut = tmp_path / f"cut{suffix}"
    cut.write_bytes(blob[: len(blob) * 2 // 3])
    b = ReplayBackend({"file": str(cut)})
    with pytest.raises(InputError, match=rf"cut{suffix}.*truncated"):
        b.open(RADAR)
    tiny = tmp_path / f"tiny{suffix}"
    tiny.write_bytes(blob[:40])
    with pytest.raises(InputError, match="truncated"):
        check_log(tiny)


def test_bad_logs_and_parameters(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        ReplayBackend({"file": str(tmp_path / "none.blf")}).open(RADAR)
    (tmp_path / "x.txt").write_text("hello")
    with pytest.raises(InputError, match=r"cannot read \.txt"):
        check_log(tmp_path / "x.txt")
    (tmp_path / "x.blf").write_bytes(b"NOPE" + b"\0" * 200)
    with pytest.raises(InputError, match="not a BLF file"):
        check_log(tmp_path / "x.blf")
    good = tmp_path / "good.asc"
    record(good, n=1)
    junk = tmp_path / "junk.asc"
    junk.write_text(good.read_text().replace(" 1 0 f 64 10 00 ", " 1 0 f 64 10 ZZ ", 1))
    with pytest.raises(InputError, match=r"junk\.asc: damaged log \(ValueError"):
        replay(junk)
    with pytest.raises(ConfigError, match="file"):
        ReplayBackend({})
    with pytest.raises(InputError, match="open"):
        next(ReplayBackend({"file": str(junk)}).frames())
    with pytest.raises(InputError, match="max_frames"):
        next(ReplayBackend({"file": str(junk)}).frames(-2))


def test_recording_of_another_radar_is_refused(tmp_path):
    path = tmp_path / "run.blf"
    record(path, n=1)
    other = RADAR.model_copy(update={"noise_figure_db": 3.0})
    with pytest.raises(InputError, match=r"run\.blf was recorded with radar configuration hash 0x"):
        replay(path, radar=other)
    frames, _ = replay(path, radar=other, check_config=False)
    assert len(frames) == 1 and frames[0].ra_map.radar == other


def test_adc_recording_replays_through_the_chain(tmp_path):
    path = tmp_path / "adc.blf"
    live, _ = record(path, n=2, payload="adc_int16")
    frames, _ = replay(path)
    assert [f.meta["payload_format"] for f in frames] == ["ADC_INT16"] * 2
    assert all(np.array_equal(a.ra_map.data, b.ra_map.data) for a, b in zip(live, frames))


@pytest.mark.parametrize("payload", ["auto", "ra_complex64"])
def test_replay_with_the_payload_format_given(tmp_path, payload):
    # An explicit payload crashed with AttributeError ('NoneType' object has no attribute 'on_header'):
    # the assembler was made only when the log announced its format.
    path = tmp_path / "given.blf"
    live, _ = record(path, n=2)
    frames, stats = replay(path, payload=payload)
    assert [f.index for f in frames] == [f.index for f in live] == [0, 1]
    assert all(np.array_equal(a.ra_map.data, b.ra_map.data) for a, b in zip(live, frames))
    assert stats.frames_ok == 2 and not stats.lost


def test_recorder_rejects_unknown_formats(tmp_path):
    with pytest.raises(InputError, match=r"cannot write \.xyz"):
        BusRecorder(tmp_path / "a.xyz", BusSpec(channel=private_channel()))
