"""Entry point ``xnlos-estimators``: registers the wall estimator lsq and the tracker nearest."""
from xnlos_core import hookimpl


@hookimpl
def xnlos_register_components(registry):
    from .lsq import LSQWallEstimator
    from .nearest import NearestTracker

    registry.add("wall_estimator", "lsq", LSQWallEstimator)
    registry.add("tracker", "nearest", NearestTracker)
