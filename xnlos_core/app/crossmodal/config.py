"""The cross-modality study's config file (:mod:`xnlos_core.app.crossmodal.study`): modalities, the
distance grid and the bisection bounds, scoring gates, the bootstrap, the range ratios, the scene
whose hidden object is moved. Strict: unknown keys are a ConfigError naming the file and key."""
from __future__ import annotations

import difflib
import hashlib
import json
from pathlib import Path
from typing import Annotated, Any, Literal, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from xnlos_core.config import expect_kind
from xnlos_core.files import load_toml
from xnlos_core.validation import validate_model

class StageTable(BaseModel):
    """A component by registered name with its parameters."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(description="registered component name")
    params: dict[str, Any] = Field(default_factory=dict, description="the component's parameters")


class RadarModality(BaseModel):
    """A radar row: the project's pipeline (detector → wall estimator → mirror reconstructor)."""

    model_config = ConfigDict(extra="forbid")
    type: Literal["radar"]
    label: str = Field(description="row name in the table and figures")
    radar: dict[str, Any] = Field(description="[radar] table of a pipeline (preset and/or fields)")
    forward_model: StageTable = Field(default_factory=lambda: StageTable(name="image"))
    detector: StageTable
    wall_estimator: StageTable = Field(default_factory=lambda: StageTable(name="lsq"))
    reconstructor: StageTable = Field(default_factory=lambda: StageTable(name="mirror"))


class SpadModality(BaseModel):
    """A SPAD row per solver: a transient model scans the relay wall; NLOS solvers reconstruct."""

    model_config = ConfigDict(extra="forbid")
    type: Literal["spad"]
    label: str = Field(description="row name prefix (rows '<label>/<solver>')")
    transient_model: StageTable = Field(description="registered transient_model (e.g. spad) and params")
    solvers: list[str] = Field(default_factory=lambda: ["lct"], min_length=1,
                               description="registered nlos_solver names (lct, fk)")
    window: int = Field(5, ge=1, le=1000, description="detection window [time bins]")
    n_sigma: float = Field(5.0, gt=0, le=100, description="detection threshold [Poisson σ of the background]")
    background_subtract: bool = Field(True, description="before the solver: subtract each scan point's median "
                                      "count over time (the flat dark + ambient floor), clip at 0")
    first_bounce_gate: float = Field(0.5, ge=0, le=100, description="reconstruction peak search starts at this "
                                     "depth z [m] from the relay wall: gates the first bounce (the wall's own "
                                     "return) and the solvers' artefacts at t = 0 (crossmodal_score)")
    placement: Literal["facing", "fixed"] = Field(
        "facing", description="facing: per distance, the scan patch (transient_model grid_offset) goes where the "
        "relay wall faces the hidden object most nearly head-on among the positions the sensor sees "
        "(sims/spad/placement.py); fixed: the transient_model's own grid_offset")


class Bisection(BaseModel):
    """Bounds [m] and final bracket width of the per-seed bisection to failure (crossmodal.bisect)."""

    model_config = ConfigDict(extra="forbid")
    lower: float = Field(0.5, gt=0, le=1000, description="nearest distance tested [m]")
    upper: float = Field(150.0, gt=0, le=1000, description="farthest distance tested [m] (the radar maps are made "
                                                           "to cover the hidden object's image there)")
    rel_tol: float = Field(0.03, gt=0, le=1, description="bisection ends when the bracket hi/lo ≤ 1 + rel_tol")

    @model_validator(mode="after")
    def _order(self):
        if not self.lower < self.upper:
            raise ValueError(f"bisection: expected lower < upper, got {self.lower} and {self.upper}")
        return self


class Bootstrap(BaseModel):
    """Percentile bootstrap of the mean range over seeds and of the range ratios (crossmodal.bisect)."""

    model_config = ConfigDict(extra="forbid")
    level: float = Field(0.95, gt=0, lt=1, description="confidence level of the intervals")
    resamples: int = Field(2000, ge=100, le=100_000, description="bootstrap resamples")


Modality = Annotated[Union[RadarModality, SpadModality], Field(discriminator="type")]


class StudyConfig(BaseModel):
    """A cross-modality study file (see the module docstring)."""

    model_config = ConfigDict(extra="forbid")
    name: str = "crossmodal"
    seed: int = Field(0, ge=0, lt=2**63, description="root seed of every trial")
    distances: list[Annotated[float, Field(gt=0, le=1000)]] = Field(
        min_length=1, description="distance grid behind the corner [m] of the F1 table and range curve")
    seeds: int = Field(3, ge=1, le=1000, description="trial seeds per modality: each seed is one trial at every "
                                                     "grid distance and one bisection to failure")
    bisection: Bisection = Field(default_factory=Bisection)
    bootstrap: Bootstrap = Field(default_factory=Bootstrap)
    hidden_object: str = Field(description="name of the scene object that is moved")
    relay_wall: str = Field(description="name of the relay wall (radar truth image; SPAD scan)")
    corner: tuple[float, float] = Field(description="a point on the occluder's front line [m]")
    direction: tuple[float, float] = Field(description="along the hidden street, away from the corner")
    gate: float = Field(2.0, gt=0, le=100, description="detection gate [m]")
    tolerance: float = Field(1.5, gt=0, le=100, description="reconstruction tolerance [m]")
    threshold: float = Field(0.5, gt=0, le=1, description="F1 at which a distance counts as in range")
    panel_distance: float = Field(3.0, gt=0, le=1000, description="distance of the Fig. 5-style panel [m]")
    ratios: list[tuple[str, str]] = Field(default_factory=list, description="(reference, baseline) row pairs whose "
                                          "range ratio (mean range of reference / of baseline) is reported")
    scene: dict[str, Any] = Field(description="inline scene (walls, objects): the hidden object's "
                                              "centre is replaced per distance")
    modality: list[Modality] = Field(min_length=1)

    @model_validator(mode="after")
    def _check(self):
        if np.hypot(*self.direction) < 1e-9:
            raise ValueError("direction: expected a non-zero vector")
        labels = [m.label for m in self.modality]
        if len(set(labels)) != len(labels):
            raise ValueError(f"modality: labels must be unique, got {labels}")
        rows = [r for m in self.modality
                for r in ([m.label] if isinstance(m, RadarModality) else [f"{m.label}/{s}" for s in m.solvers])]
        for pair in self.ratios:
            for value in pair:
                if value not in rows:
                    close = difflib.get_close_matches(value, rows, n=1)
                    hint = f" (did you mean {close[0]!r}?)" if close else ""
                    raise ValueError(f"ratios: {value!r} names no row of the study{hint}; rows: {', '.join(rows)}")
        return self

    def digest(self) -> str:
        """sha256 of the canonical JSON (decides whether saved cells are current); ``panel_distance``
        is left out: it changes only the panel."""
        dump = self.model_dump(exclude={"panel_distance"})
        return hashlib.sha256(json.dumps(dump, sort_keys=True, default=str).encode()).hexdigest()


def load_study(path: str | Path) -> tuple[StudyConfig, Path]:
    """Validate a study TOML; unknown or bad keys are a ConfigError naming the file and key."""
    path = Path(path)
    table = load_toml(path)
    expect_kind(table, "cross-modality study", str(path))
    return validate_model(StudyConfig, table, source=str(path)), path.resolve().parent
