"""The manoeuvre library's public names under their former module: a facade over
:mod:`estimators.trackers.library`, whose package docstring describes the method and says which file
holds what (equations: Eqs. 1–2 in ``library/selection.py``, Eqs. 3–4 in ``library/predict.py``).
``from estimators.trackers import motion_library as ml; ml.identify_batch(...)`` keeps working."""
from __future__ import annotations

from .library import (BETA_MAX, CV_BENT, CV_SURE, FULL, KINK_TIMES, LANE_ANGLES, LANE_CENTRES, LANE_MAX,  # noqa: F401
                      LANE_SCALES, LIBRARY, MIN_BEFORE, MIN_RADIAL, MIN_SAMPLES, MIN_WEIGHT, N_LINEAR, N_PARAMS,
                      OMEGA_GRID, RADIAL_SHARES, TURN_OVER_LANE, VECTORS, Entry, Envelope, LibraryFit, basis,
                      criteria, demote, fit_doppler, fit_group, forecast_basis, forecast_velocity_basis, hyper_grid,
                      identify_batch, line_direction, lr_threshold, pick, predict, predict_many, radial_rows,
                      readonly, select_fit, shared_designs, velocity_basis)
from .library import __all__  # noqa: F401
