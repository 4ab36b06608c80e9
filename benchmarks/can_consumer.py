"""A consumer slower than the radar, and bursts: frames delivered, overrun and lost per overflow policy
of the ``can`` backend, over the python-can virtual bus against the device emulator.

    .venv/bin/python benchmarks/can_consumer.py [--frames 10] [--burst 1000] [--out benchmarks/can_consumer.md]

* ``slow``  – radar paced at 0.05 s per frame (20 kB RA maps, 81 × 31 complex64), the consumer
              spending 0, 0.1, 0.25 or 1 s on each of ``--frames`` frames, queue of 4 frames;
* ``burst`` – one START of ``--burst`` frames sent as fast as the link goes (1.2 kB RA maps), queue
              of 64 frames, the consumer taking ``--burst-delay`` (5 ms) per frame, slower than the link.

Frames are rendered by :class:`hardware.testing.NoiseModel` (no rendering cost: the emulator keeps
its rate). ``sent`` is what the emulator put on the bus; each sent frame ends as delivered, overrun
(dropped by the queue's policy) or lost (never arrived intact): ``ok`` checks sent = delivered +
overrun + lost with no frame in two classes. Writes a Markdown table (atomically) to ``--out``.
"""
from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hardware.testing import NoiseModel, emulated_link, small_radar  # noqa: E402
from xnlos_core.io import atomic_write_text  # noqa: E402

POLICIES = ("block", "drop_oldest", "drop_newest")



def made_by() -> str:
    """The line that says which command wrote the page (this script with its arguments)."""
    return "Made by `python " + " ".join([f"benchmarks/{Path(sys.argv[0]).name}", *sys.argv[1:]]) + "`."

def run_case(radar, n: int, delay: float, policy: str, queue: int, *, pace: bool, interval: float,
             chunk: int) -> dict:
    t0 = time.perf_counter()
    with emulated_link(radar, seed=0, pace=pace, frame_interval=interval, queue_size=queue, overflow=policy,
                       chunk=chunk, forward_model=NoiseModel()) as (backend, em):
        seqs = []
        for f in backend.frames(n):
            seqs.append(f.index)
            time.sleep(delay)
        st = backend.stats
    dt = time.perf_counter() - t0
    classes = set(seqs) | set(st.overrun_seqs) | set(st.lost_seqs())
    ok = (len(seqs) + st.frames_overrun + st.frames_lost == em.frames_sent == len(classes)
          and sorted(classes) == sorted(em.sent_log) and seqs == sorted(set(seqs)))
    return {"sent": em.frames_sent, "delivered": len(seqs), "overrun": st.frames_overrun, "lost": st.frames_lost,
            "ok": ok, "seconds": dt}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=10, help="frames taken per slow-consumer case")
    ap.add_argument("--burst", type=int, default=1000, help="frames in the burst")
    ap.add_argument("--burst-delay", type=float, default=0.005, help="consumer seconds per frame in the burst")
    ap.add_argument("--delays", default="0,0.1,0.25,1", help="consumer seconds per frame, comma-separated")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("can_consumer.md"))
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.ERROR)
    rows = []
    slow_radar, tiny = small_radar(), small_radar(max_range=5.0, n_azimuth_bins=7)
    for delay in (float(x) for x in args.delays.split(",")):
        for policy in POLICIES:
            r = run_case(slow_radar, args.frames, delay, policy, 4, pace=True, interval=0.05, chunk=16)
            rows.append(("slow", f"{delay:g} s/frame", policy, 4, args.frames, r))
            print(rows[-1][:5], r, flush=True)
    for policy in POLICIES:
        r = run_case(tiny, args.burst, args.burst_delay, policy, 64, pace=False, interval=0.0, chunk=min(4096, args.burst))
        rows.append(("burst", f"{args.burst_delay * 1e3:g} ms/frame", policy, 64, args.burst, r))
        print(rows[-1][:5], r, flush=True)
    lines = ["# `can` backend: slow consumers and bursts (benchmarks/can_consumer.py)", "", made_by(), "",
             "Device emulator on the python-can virtual bus, NoiseModel frames. slow: radar every 0.05 s, "
             "81 × 31 complex64 RA maps (20 kB); burst: one START of all frames, as fast as the link goes, "
             "9 × 7 maps (1.2 kB). Every frame sent ends as delivered, overrun (dropped by the queue's policy "
             "because the consumer was behind) or lost (never arrived intact); `ok`: sent = delivered + overrun "
             "+ lost, no frame counted twice. Before the receive thread a consumer taking 0.25 s per "
             "frame lost 11 of 51 frames as 'still incomplete 2 s after it was sent'.", "",
             "| case | consumer | overflow | queue | requested | sent | delivered | overrun | lost | ok | wall s |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|---|---:|"]
    for case, consumer, policy, queue, n, r in rows:
        lines.append(f"| {case} | {consumer} | {policy} | {queue} | {n} | {r['sent']} | {r['delivered']} | "
                     f"{r['overrun']} | {r['lost']} | {'yes' if r['ok'] else 'NO'} | {r['seconds']:.1f} |")
    lines += ["", "`block` asks the radar for no more frames than the queue holds: it pauses while the consumer "
              "is behind, so sent = delivered. The drop policies keep the radar at its own rate; what the queue "
              "cannot hold is overrun (re-requested, so the consumer still gets the frames it asked for).", ""]
    atomic_write_text(args.out, "\n".join(lines))
    print("\n".join(lines))
    return 0 if all(r["ok"] and r["lost"] == 0 for *_, r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
