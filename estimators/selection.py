"""Wall model order per wall from the data: model only what the scene requires.

Criteria (larger is better, both in nats so one margin serves both):

* ``evidence``: the Laplace log evidence log Z (:mod:`estimators.map_solver`). The proper prior
  κ ~ N(0, σ_κ²) makes the arc pay an Occam factor ≈ log(σ_κ/σ_κ|data) for its extra
  parameter, so a flat facade stays a line unless its points demand curvature.
* ``bic``: −BIC/2 = log p(x | θ̂) − (k/2) log N, k parameters (log s included), N points.

The simplest model (line first, :data:`xnlos_core.wall.MODEL_ORDER`) is kept unless a
more complex one beats the current choice by more than ``margin`` nats (default 1: a Bayes
factor above e ≈ 2.7, "positive" evidence); a model whose MAP failed to converge is not eligible
(and is reported as such).
"""
from __future__ import annotations

from typing import Literal

import numpy as np

from .map_solver import MapFit
from xnlos_core.wall import MODEL_ORDER


def criterion(fit: MapFit, n_points: int, kind: Literal["evidence", "bic"]) -> float:
    """The selection criterion of one MAP fit (module doc) [nats]."""
    if kind == "evidence":
        return float(fit.log_evidence)
    k = len(fit.theta)
    return float(fit.log_lik - 0.5 * k * np.log(max(n_points, 1)))


def select_model(fits: dict[str, MapFit], n_points: int, kind: Literal["evidence", "bic"] = "evidence",
                 margin: float = 1.0) -> tuple[str, dict]:
    """Choose among ``fits`` (model → MapFit). Returns (model, report) with report = {chosen,
    criterion, values {model: nats}, log_evidence, bic, converged, margin, reason}."""
    order = [m for m in MODEL_ORDER if m in fits]
    values = {m: criterion(fits[m], n_points, kind) for m in order}
    ok = [m for m in order if fits[m].success and np.isfinite(values[m])] or order[:1]
    chosen = ok[0]
    reason = f"{chosen}: simplest converged model"
    for m in ok[1:]:
        gain = values[m] - values[chosen]
        if gain > margin:
            reason = (f"{m}: {kind} {values[m]:.2f} beats {chosen} {values[chosen]:.2f} by {gain:.2f} nats "
                      f"(> margin {margin:g})")
            chosen = m
        else:
            reason = (f"{chosen}: {m} gains only {gain:.2f} nats of {kind} (≤ margin {margin:g}); "
                      f"the extra parameter is not needed")
    failed = [m for m in order if m not in ok]
    if failed:
        reason += "; not converged: " + ", ".join(f"{m} ({fits[m].status})" for m in failed)
    report = {
        "chosen": chosen, "criterion": kind, "values": values, "margin": margin,
        "log_evidence": {m: float(fits[m].log_evidence) for m in order},
        "bic": {m: float(-2 * criterion(fits[m], n_points, "bic")) for m in order},
        "converged": {m: bool(fits[m].success) for m in order}, "reason": reason,
    }
    return chosen, report
