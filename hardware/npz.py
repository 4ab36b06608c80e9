"""Replay backend: frames recorded with :func:`xnlos_core.io.save_frame` as ``*.npz`` files.

Files in ``directory`` matching ``*.npz`` are read in name order (zero-padded names such as
``frame_000012.npz`` sort chronologically). Each frame carries its own RadarConfig; ``open``'s
radar argument is not used. A missing directory or a corrupt file raises InputError naming it;
a frame is yielded only once its file has been read completely.
"""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.errors import InputError
from xnlos_core.interfaces import Backend
from xnlos_core.io import load_frame
from xnlos_core.types import Frame
from xnlos_core.param_paths import RELATIVE_TO_CONFIG, ConfigPath


class NPZParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    directory: ConfigPath = Field(..., min_length=1, description="folder holding the recorded *.npz frames"
                                                                 + RELATIVE_TO_CONFIG)


class NPZBackend(Backend):
    """Replays frames saved by xnlos_core.io.save_frame from a directory (files in name order)."""

    Params = NPZParams
    own_radar = True  # each saved frame carries its radar; compared frame by frame

    def files(self) -> list[Path]:
        """The ``*.npz`` files of ``directory`` sorted by name; InputError if it is not a directory."""
        d = Path(self.params.directory).expanduser()
        if not d.is_dir():
            raise InputError(f"NPZBackend: directory {str(d)!r} does not exist or is not a directory "
                             "(params.directory)")
        files = sorted((f for f in d.glob("*.npz") if f.is_file()), key=lambda f: f.name)
        if not files:  # an empty recording is a mistake, not a run of 0 frames
            raise InputError(f"NPZBackend: directory {str(d)!r} holds no *.npz frame files (params.directory; "
                             "expected frames written by xnlos_core.io.save_frame)")
        return files

    def check_source(self) -> None:
        """What ``xnlos check`` asks: the folder exists and holds frame files (:meth:`files`)."""
        self.files()

    def frames(self, max_frames: int | None = None) -> Iterator[Frame]:
        """Yield up to ``max_frames`` frames (all when None) in file-name order."""
        self.check_max_frames(max_frames)
        files = self.files()
        if max_frames is not None:
            files = files[:max_frames]
        for f in files:
            try:
                frame = load_frame(f)
            except InputError:
                raise
            except Exception as exc:  # anything else a damaged file can provoke
                raise InputError(f"{f}: not a readable xnlos frame file ({type(exc).__name__}: {exc})") from None
            yield frame
