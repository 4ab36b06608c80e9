"""Entry point ``xnlos-estimators``: registers the wall estimators lsq, casadi_map, laplace_is and emcee and
the trackers nearest, kalman and sindy, and the optical NLOS solvers lct and fk."""
from xnlos_core import hookimpl


@hookimpl
def xnlos_register_components(registry):
    from .casadi_map import CasadiMapWallEstimator
    from .emcee_wall import EmceeWallEstimator
    from .laplace_is import LaplaceISWallEstimator
    from .lsq import LSQWallEstimator
    from .nlos.fk import FKSolver
    from .nlos.lct import LCTSolver
    from .trackers.kalman import KalmanTracker
    from .trackers.nearest import NearestTracker
    from .trackers.sindy import SindyTracker

    registry.add("wall_estimator", "lsq", LSQWallEstimator)
    registry.add("wall_estimator", "casadi_map", CasadiMapWallEstimator)
    registry.add("wall_estimator", "laplace_is", LaplaceISWallEstimator)
    registry.add("wall_estimator", "emcee", EmceeWallEstimator)
    registry.add("tracker", "nearest", NearestTracker)
    registry.add("tracker", "kalman", KalmanTracker)
    registry.add("tracker", "sindy", SindyTracker)
    registry.add("nlos_solver", "lct", LCTSolver)
    registry.add("nlos_solver", "fk", FKSolver)
