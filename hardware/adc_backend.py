"""``adc`` backend: frames of a raw radar recording (DCA1000 ``.bin``, ``.npy``/``.npz``/HDF5 cubes).

``params.recording`` names the TOML description (:mod:`hardware.recording`); one Frame per frame of
the file, its RA map formed by the shared signal chain with the radar the description gives (the
pipeline's radar passed to ``open`` is not used, as with the ``npz`` backend). A frame keeps its
chirps: with ≥ 3 chirps per transmitter (or ``doppler = true``) its RA map is the Doppler chain's
(:meth:`hardware.recording.Recording.doppler_ra_map`), with a radial velocity and its σ per cell, so
detections from a recording carry velocity as simulated ones do. The first frame
yielded is checked for the known mistakes (:mod:`hardware.recording_checks`), each a
``RecordingWarning``.
"""
from __future__ import annotations

from collections.abc import Iterator

from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.errors import ConfigError, InputError
from xnlos_core.interfaces import Backend
from xnlos_core.types import Frame
from xnlos_core.param_paths import RELATIVE_TO_CONFIG, ConfigPath

from .recording import Recording


class ADCParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    recording: ConfigPath = Field(..., min_length=1, description="TOML description of the recording ([recording], "
                                                                 "[chirp], [radar])" + RELATIVE_TO_CONFIG)
    start: int = Field(0, ge=0, description="first frame of the file to yield")
    doppler: bool | None = Field(None, description="RA maps with radial velocity and its σ per cell from the "
                                                   "frame's chirps (Doppler processing); unset: when the "
                                                   "recording has ≥ 3 chirps per transmitter")


class ADCBackend(Backend):
    """Yields the frames of a raw recording in file order (frame ``start`` first)."""

    Params = ADCParams
    own_radar = True

    def __init__(self, params=None):
        super().__init__(params)
        self._rec: Recording | None = None

    @property
    def recording(self) -> Recording:
        """The opened recording (opened on first use; ConfigError/InputError name the file)."""
        if self._rec is None:
            self._rec = Recording.from_toml(self.params.recording)
        return self._rec

    @property
    def n_frames(self) -> int:
        return max(self.recording.n_frames - self.params.start, 0)

    def source_radar(self):
        """The recording description's radar: the maps' radar, whatever the pipeline's ``[radar]`` says."""
        return self.recording.radar

    def check_source(self) -> None:
        """Open the recording (its description, file, header and cube shape) and check that ``start``
        is one of its frames and that ``doppler = true`` has the chirps it needs; ConfigError /
        InputError name the file."""
        n = self.recording.n_frames
        if self.params.start >= n:
            raise InputError(f"{self.recording.path}: params.start = {self.params.start}, but the recording has "
                             f"{n} frame(s) (0 … {n - 1}); expected a start inside it")
        if self.params.doppler and not self.recording.has_doppler:
            raise ConfigError(f"{self.recording.source}: params.doppler = true needs n_chirps ≥ 3 chirps per "
                              f"transmitter in a frame; the recording's radar has n_chirps = "
                              f"{self.recording.radar.n_chirps} (leave doppler unset or false)")

    def frames(self, max_frames: int | None = None) -> Iterator[Frame]:
        self.check_max_frames(max_frames)
        self.check_source()
        yield from self.recording.frames(self.params.start, max_frames, doppler=self.params.doppler)
