"""Conformance kit: the checks a plugin author runs against a new component, in the spirit of
scikit-learn's ``check_estimator`` and ``parametrize_with_checks``. Each check raises AssertionError
naming the broken contract; :func:`check_component` returns a report of every check that passed.

    from xnlos_core.testing import check_component, parametrize_with_checks
    print(check_component("detector", "my_detector"))     # a registered name, a class or a plugin module
    check_detector(MyDetector())                           # one kind's check on an instance

    @parametrize_with_checks([("detector", MyDetector)])   # each check one pytest test
    def test_conformance(component, check):
        check(component)

Also the inputs the checks use (:func:`synthetic_frame`, :func:`small_radar`, :func:`kit_transient`)
and :func:`small_pipeline_table`, a fast pipeline config to try a new component end to end.
"""
# the reference page lists the names in this order
from .kit import (check_component, parametrize_with_checks, CheckReport, CheckResult, Check, ComponentSpec,  # noqa: I001
                  checks_for, resolve)
from .checks import (CHECKS, check_params, check_detector, check_wall_estimator, check_reconstructor, check_tracker,
                     check_forward_model, check_backend, check_scene_generator, check_nlos_solver,
                     check_transient_model, check_frame_state, passed, record_steps)
from .frames import small_pipeline_table, small_radar, synthetic_frame, kit_transient, KIT_WALL, KIT_HIDDEN

__all__ = [
    "check_component", "parametrize_with_checks", "CheckReport", "CheckResult", "Check", "ComponentSpec",
    "checks_for", "resolve", "CHECKS", "check_params", "check_detector", "check_wall_estimator",
    "check_reconstructor", "check_tracker", "check_forward_model", "check_backend", "check_scene_generator",
    "check_nlos_solver", "check_transient_model", "check_frame_state", "passed", "record_steps",
    "small_pipeline_table", "small_radar", "synthetic_frame", "kit_transient", "KIT_WALL", "KIT_HIDDEN",
]
