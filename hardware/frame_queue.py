"""The bounded queue of complete frames between a CAN receive thread and the consumer.

The receive thread reassembles frames as their bytes arrive and :meth:`FrameQueue.put` s each
intact one here; the consumer :meth:`FrameQueue.get` s them at its own pace. When the consumer falls
behind and the queue is full, the overflow policy decides:

* ``drop_oldest`` – the oldest queued frame is dropped (the consumer always sees the newest data,
  as a live display wants);
* ``drop_newest`` – the arriving frame is dropped (the consumer sees an unbroken run, then a gap);
* ``block`` – nothing is dropped: ``put`` waits for room. The ``can`` backend never lets this wait
  happen on a live bus: under ``block`` it asks the radar for no more frames than the queue has
  room for, so the radar pauses while the consumer is behind (see :class:`~hardware.can_backend.CANParams`).

A dropped frame arrived intact: it is counted as *overrun* (``stats.frames_overrun``,
``stats.overrun_seqs``, and ``meta["overrun_before"]`` of the next frame the consumer gets), never as
*lost*. Every frame put is therefore either got exactly once or counted as overrun once. A
dropped frame's own ``meta["lost_before"]`` / ``["overrun_before"]`` move on to the frame that
follows it, so the consumer still hears of every loss.

Hand-written rather than ``queue.Queue``: that class can neither drop its oldest item atomically
nor carry a dropped item's reports over to its successor.
"""
from __future__ import annotations

import threading
from collections import deque
from typing import Literal

from xnlos_core.types import Frame

from .assembler import LinkStats

Overflow = Literal["drop_oldest", "drop_newest", "block"]
POLICIES = ("drop_oldest", "drop_newest", "block")


class FrameQueue:
    """Thread-safe FIFO of at most ``size`` frames with an overflow policy (see the module doc).

    stats: the link's counters; ``frames_overrun`` / ``overrun_seqs`` grow with every drop and
    ``frames_delivered`` with every frame got. ``taken`` counts frames got since construction.
    """

    def __init__(self, size: int, policy: Overflow, stats: LinkStats):
        if not isinstance(size, int) or size < 1:
            raise ValueError(f"FrameQueue size must be an integer ≥ 1, got {size!r}")
        if policy not in POLICIES:
            raise ValueError(f"FrameQueue policy must be one of {POLICIES}, got {policy!r}")
        self.size, self.policy, self.stats = size, policy, stats
        self.taken = 0
        self._q: deque[Frame] = deque()
        self._cond = threading.Condition()
        self._carry_lost: list[int] = []  # reports of dropped frames, for the next frame put (drop_newest)
        self._carry_overrun: list[int] = []

    def __len__(self) -> int:
        with self._cond:
            return len(self._q)

    @property
    def free(self) -> int:
        """Frames that fit without dropping or waiting."""
        with self._cond:
            return self.size - len(self._q)

    def put(self, frame: Frame, stop: threading.Event | None = None) -> bool:
        """Queue ``frame``; False when it was dropped (drop_newest, or ``stop`` set during a block wait;
        both count it as overrun)."""
        with self._cond:
            self._attach(frame, self._carry_lost, self._carry_overrun)
            self._carry_lost, self._carry_overrun = [], []
            if len(self._q) >= self.size:
                if self.policy == "block":
                    while len(self._q) >= self.size:
                        if stop is not None and stop.is_set():  # the consumer left: the frame is not kept
                            self._carry_lost, self._carry_overrun = self._reports(frame)
                            self._overrun(frame)
                            return False
                        self._cond.wait(0.05)
                elif self.policy == "drop_newest":
                    self._carry_lost, self._carry_overrun = self._reports(frame)
                    self._overrun(frame)
                    return False
                else:
                    old = self._q.popleft()
                    self._overrun(old)
                    lost, over = self._reports(old)
                    # the old frame's reports belong before the new head (or before ``frame``)
                    self._attach(self._q[0] if self._q else frame, lost, over)
            self._q.append(frame)
            self._cond.notify_all()
            return True

    def get(self, timeout: float = 0.0) -> Frame | None:
        """The oldest queued frame, waiting up to ``timeout`` seconds; None if none came."""
        with self._cond:
            if not self._q and timeout > 0:
                self._cond.wait(timeout)
            if not self._q:
                return None
            frame = self._q.popleft()
            self.taken += 1
            self.stats.frames_delivered += 1
            self._cond.notify_all()
            return frame

    def notify(self) -> None:
        """Wake a consumer waiting in :meth:`get` (the producer stopped or failed)."""
        with self._cond:
            self._cond.notify_all()

    # --- internals ------------------------------------------------------------------------
    def _overrun(self, frame: Frame) -> None:
        self.stats.frames_overrun += 1
        self.stats.overrun_seqs.append(frame.index)

    @staticmethod
    def _reports(frame: Frame) -> tuple[list[int], list[int]]:
        return (list(frame.meta.get("lost_before", [])),
                list(frame.meta.get("overrun_before", [])) + [frame.index])

    @staticmethod
    def _attach(frame: Frame, lost: list[int], over: list[int]) -> None:
        """Add earlier frames' loss / overrun reports to ``frame.meta`` (sequence numbers, sorted)."""
        for key, seqs in (("lost_before", lost), ("overrun_before", over)):
            if seqs:
                frame.meta[key] = sorted(set(seqs) | set(frame.meta.get(key, [])))
