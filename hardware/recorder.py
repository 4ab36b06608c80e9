"""Record the radar bus to a python-can log file (BLF, ASC, or any format python-can writes).

:class:`BusRecorder` opens its own handle on the bus — as a hardware bus logger would — so it
records both directions (configuration, state, headers, ISO-TP data and flow control) without
touching the nodes it watches. That needs an interface that allows a second handle on the same
channel (virtual, socketcan, vector/kvaser application channels). The log is written to
``NAME.partial.SUFFIX`` and renamed to the final name when recording stops, so a log under its
final name is always complete (the ``replay`` backend also rejects truncated BLF/ASC files).
"""
from __future__ import annotations

import logging
import os
import threading
import time
from pathlib import Path

import can

from xnlos_core.errors import InputError

from .link import BusSpec, open_bus

log = logging.getLogger(__name__)


def writable_formats() -> list[str]:
    """Log suffixes python-can can write (".asc", ".blf", ".csv", …)."""
    from can.io.logger import MESSAGE_WRITERS

    return sorted(MESSAGE_WRITERS)


class BusRecorder:
    """Record every message seen on ``bus`` to ``path`` (format from the suffix) until :meth:`stop`.

    ``messages`` counts the messages written. Use as a context manager or call start/stop.
    """

    def __init__(self, path: str | os.PathLike, bus: BusSpec):
        self.path = Path(path)
        suffix = self.path.suffix.lower()
        if suffix not in writable_formats():
            raise InputError(f"record file {str(self.path)!r}: python-can cannot write "
                             f"{suffix or 'files without suffix'}; use one of {', '.join(writable_formats())}")
        self.partial = self.path.with_name(f"{self.path.stem}.partial{self.path.suffix}")
        self.spec = bus
        self.messages = 0
        self._last = 0.0
        self._bus = None
        self._writer = None
        self._notifier = None
        self._lock = threading.Lock()

    def _count(self, msg: can.Message) -> None:
        self.messages += 1
        self._last = time.monotonic()

    def start(self) -> "BusRecorder":
        """Open the bus handle and the writer; InputError if the file cannot be created."""
        if self._notifier is not None:
            return self
        self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            self._writer = can.Logger(str(self.partial))
        except (OSError, ValueError) as exc:
            raise InputError(f"record file {str(self.path)!r}: cannot write ({exc})") from None
        try:
            self._bus = open_bus(self.spec)
            self._notifier = can.Notifier(self._bus, [self._writer, self._count], timeout=0.05)
        except Exception:
            self._writer.stop()
            self.partial.unlink(missing_ok=True)
            if self._bus is not None:
                self._bus.shutdown()
            raise
        log.info("recording %s to %s", self.spec.describe(), self.path)
        return self

    def stop(self, drain: float = 2.0) -> None:
        """Write out what is still queued (waits until the bus is quiet for 0.1 s, ≤ ``drain`` s),
        close the file and move it to its final name. Safe to call twice."""
        with self._lock:
            if self._notifier is None:
                return
            t_end = time.monotonic() + drain
            pending = getattr(self._bus, "queue", None)  # the virtual interface exposes its queue
            while time.monotonic() < t_end:
                if pending is not None and pending.empty():
                    time.sleep(0.02)  # the message being written
                    break
                if pending is None and time.monotonic() - self._last > 0.1:
                    break
                time.sleep(0.01)
            self._notifier.stop(timeout=1.0)  # also stops (flushes, closes) the writer
            self._notifier = None
            self._bus.shutdown()
            self._bus = None
            os.replace(self.partial, self.path)
            log.info("recorded %d CAN messages to %s", self.messages, self.path)

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()
