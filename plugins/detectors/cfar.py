"""2-D cell-averaging CFAR detector (plain: peaks are not classified, label UNCLASSIFIED).

Threshold on linear power |κ|²: P > a(N)·mean_train with a(N) = N·(Pfa^(−1/N) − 1), N the
number of valid training cells of each cell (see :mod:`plugins.detectors.peaks` for the edge
handling, sub-bin refinement, confidence and standard deviations).
"""
from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, model_validator

from xnlos_core.errors import ConfigError
from xnlos_core.interfaces import Detector
from xnlos_core.radar import RadarConfig
from xnlos_core.types import Detections, Frame

from .peaks import cfar_peaks, window_error

# Per-axis bound of the parameter alone; the window 2·(guard + train) + 1 must also fit the RA map,
# which the parameters do not know: checked against the radar (check_radar) and the map (detect).
Cells = Annotated[int, Field(ge=0, le=256)]


class CFARParams(BaseModel):
    """Parameters of CA-CFAR (shared by the CFAR family)."""

    model_config = ConfigDict(extra="forbid")
    pfa: float = Field(1e-5, gt=0, lt=1, description="false-alarm probability per cell (0 < pfa < 1)")
    guard_cells: tuple[Cells, Cells] = Field(
        (3, 4), description="guard cells on each side of the cell under test (range, azimuth) [bins]")
    train_cells: tuple[Cells, Cells] = Field(
        (4, 8), description="training cells beyond the guard cells on each side (range, azimuth) [bins]; "
                            "the window 2·(guard + train) + 1 must fit the RA map along each axis")
    min_range: float = Field(1.0, ge=0, le=1e4, description="cells nearer than this [m] (TX→RX leakage "
                                                           "around 0 m) are neither tested nor used for training")

    @model_validator(mode="after")
    def _some_training(self):
        if sum(self.train_cells) == 0:
            raise ValueError("train_cells: at least one axis needs ≥ 1 training cell, got (0, 0)")
        return self

    def check_radar(self, radar: RadarConfig) -> None:
        """ConfigError when the CFAR window does not fit the radar's RA map (n_range_bins × n_azimuth_bins)."""
        bad = window_error(self.guard_cells, self.train_cells, (radar.n_range_bins, radar.n_azimuth_bins),
                           f"the radar's RA map ({radar.n_range_bins} × {radar.n_azimuth_bins} bins)")
        if bad:
            raise ConfigError(bad)


class CFARDetector(Detector):
    """2-D cell-averaging CFAR on |κ|²; 3×3 local maxima over threshold, sub-bin refined, UNCLASSIFIED."""

    Params = CFARParams
    classifies = False  # every detection is UNCLASSIFIED

    def check_radar(self, radar: RadarConfig) -> None:
        """The CFAR window must fit the radar's RA map (:func:`.peaks.window_error`)."""
        self.params.check_radar(radar)

    def detect(self, frame: Frame) -> Detections:
        """Detections of ``frame.ra_map`` ordered by descending power (empty map → empty)."""
        self.check_frame(frame)
        p = self.params
        return cfar_peaks(frame.ra_map, p.pfa, tuple(p.guard_cells), tuple(p.train_cells), p.min_range)
