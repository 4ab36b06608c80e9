"""Variance floors and tie rules (xnlos_core.numerics), and their promise: perturbing the inputs of a
discrete choice by a few ulps gives the same outcome wherever the choice's margin is above the
stated tolerance (motion model, corner pieces, CFAR peak count, association)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from scipy import ndimage
from hypothesis import strategies as st

from estimators.corners import split_corners
from estimators.trackers.sindy_model import identify_motion
from plugins.detectors.peaks import local_maxima
from xnlos_core.numerics import (CRITERION_TOL, EPS, criterion_tolerance, data_scale, gated_assignment,
                                 simplest_within, snap, variance_floor)

pytestmark = pytest.mark.kernels


def ulps(x: np.ndarray, rng: np.random.Generator, most: int = 4) -> np.ndarray:
    """x with each element moved by −most … most units in the last place."""
    x = np.array(x, dtype=np.float64)
    steps = rng.integers(-most, most + 1, x.shape)
    out = x.copy()
    for k in range(1, most + 1):
        out = np.where(steps >= k, np.nextafter(out, np.inf), out)
        out = np.where(steps <= -k, np.nextafter(out, -np.inf), out)
    return out


# --- the rules ------------------------------------------------------------------------------------

def test_simplest_within_prefers_fewer_parameters_within_the_tolerance():
    assert simplest_within([10.0, 10.0 + 0.5 * CRITERION_TOL, 5.0], [1, 2, 3]) == 2
    assert simplest_within([5.0 + 0.5 * CRITERION_TOL, 5.0, 9.0], [1, 2, 3]) == 0   # tie → simpler
    assert simplest_within([5.0 + 2 * CRITERION_TOL, 5.0, 9.0], [1, 2, 3]) == 1     # beyond it → better
    assert simplest_within([3.0, 3.0, 3.0], [2, 1, 1]) == 1                          # equals: the first
    assert simplest_within([-1.0, -1.0 - 0.5 * CRITERION_TOL], [1, 2], larger_is_better=True) == 0
    assert simplest_within([np.nan, np.inf, 7.0], [0, 0, 5]) == 2
    assert simplest_within([np.nan, np.nan], [1, 0]) == 0
    with pytest.raises(ValueError, match="K ≥ 1"):
        simplest_within([], [])


def test_floors_and_tolerances_follow_the_data_scale():
    assert data_scale([1.0, -30.0, np.nan], [2.0]) == 30.0
    assert data_scale([np.nan]) > 0
    assert variance_floor(30.0) == pytest.approx(EPS * 900.0)
    assert variance_floor(30.0, 10) == pytest.approx(10 * EPS * 900.0)
    assert criterion_tolerance([1e6, -2.0, np.inf]) == pytest.approx(CRITERION_TOL + 1e-3)


def test_snap_makes_values_equal_up_to_rounding_equal():
    a = np.array([1.0, 1.0 + 1e-15, 2.0, np.inf])
    s = snap(a)
    assert s[0] == s[1] and s[2] == 2.0 and s[3] == np.inf


def test_gated_assignment_keeps_gated_pairs_and_breaks_exact_ties_by_index():
    c = np.array([[1.0, 1.0], [1.0, 1.0 + 1e-15]])
    r, k = gated_assignment(c, 2.0)
    assert r.tolist() == [0, 1] and k.tolist() == [0, 1]
    r, k = gated_assignment(np.array([[5.0, 0.5], [0.7, 9.0]]), 1.0)
    assert r.tolist() == [0, 1] and k.tolist() == [1, 0]
    r, k = gated_assignment(np.array([[5.0, 6.0]]), 1.0)
    assert len(r) == len(k) == 0
    r, k = gated_assignment(np.zeros((0, 3)), 1.0)
    assert len(r) == 0


def test_a_plateau_is_one_local_maximum():
    p = 1.0 + 0.01 * np.arange(30.0).reshape(5, 6) % 7  # a background without plateaus
    p[2, 2] = p[2, 3] = 9.0
    p[0, 5] = 4.0
    p[4, 0] = 4.0 * (1 - 1e-12)
    p[4, 1] = 4.0
    m = local_maxima(p)
    assert m[2, 2] and not m[2, 3]                # an exact two-cell plateau: its first cell
    assert m[4, 1] and not m[4, 0]                # equal up to rounding: the larger cell
    assert m[0, 5]
    old_rule = p >= ndimage.maximum_filter(p, size=3, mode="constant", cval=-np.inf)
    assert m.sum() == old_rule.sum() - 1          # the plateau counted once


def test_noiseless_braking_is_identified_with_a_margin():
    # rounding-level residuals are floored, so the one-term model wins by its parameter penalty
    t = np.arange(30) * 0.1
    u = np.array([np.cos(0.6), np.sin(0.6)])
    pos = (9.0 * t - 1.25 * t ** 2)[:, None] * u
    model = identify_motion(t, pos, 1e-3, n_models=3)
    assert model.terms() == ["vx'=vx", "vy'=vy"]
    assert model.margin > 1.0  # nats: ln(2n) per extra parameter, far above the tolerance


# --- a few ulps change no outcome whose margin exceeds the tolerance --------------------------------

@settings(max_examples=12, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2 ** 31), kind=st.sampled_from(["braking", "turn", "straight"]),
       noise=st.sampled_from([0.0, 1e-3, 0.2]))
def test_motion_support_survives_ulp_perturbations(seed, kind, noise):
    rng = np.random.default_rng(seed)
    t = np.arange(25) * 0.1
    v0, heading = rng.uniform(4, 12), rng.uniform(-np.pi, np.pi)
    u = np.array([np.cos(heading), np.sin(heading)])
    start = rng.uniform(-30, 30, 2)
    if kind == "braking":
        pos = start + (v0 * t - 1.0 * t ** 2)[:, None] * u
    elif kind == "turn":
        w = rng.uniform(0.2, 0.5) * rng.choice([-1, 1])
        ang = heading + w * t
        pos = start + v0 / w * np.stack([np.sin(ang) - np.sin(heading), np.cos(heading) - np.cos(ang)], axis=1)
    else:
        pos = start + (v0 * t)[:, None] * u
    pos = pos + rng.normal(0.0, noise, pos.shape) if noise else pos
    sigma = max(noise, 1e-3)
    a = identify_motion(t, pos, sigma, n_models=2)
    b = identify_motion(t, ulps(pos, rng), sigma, n_models=2)
    if min(a.margin, b.margin) > CRITERION_TOL:
        assert a.terms() == b.terms()


@settings(max_examples=15, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2 ** 31), noise=st.sampled_from([0.0, 0.02, 0.1]))
def test_corner_pieces_survive_ulp_perturbations(seed, noise):
    rng = np.random.default_rng(seed)
    n1, n2 = rng.integers(20, 50, 2)
    turn = rng.uniform(np.radians(40), np.radians(140))
    d1 = np.array([1.0, 0.0])
    d2 = np.array([np.cos(turn), np.sin(turn)])
    corner = rng.uniform(5, 30, 2)
    x = np.concatenate([corner - np.linspace(10, 0, n1)[:, None] * d1,
                        corner + np.linspace(0.3, 10, n2)[:, None] * d2])
    x = x + rng.normal(0, noise, x.shape) if noise else x
    a = sorted(len(p) for p in split_corners(x, 0.5))
    b = sorted(len(p) for p in split_corners(ulps(x, rng), 0.5))
    assert a == b


@settings(max_examples=30, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2 ** 31))
def test_peak_count_survives_ulp_perturbations(seed):
    # powers on a coarse grid (so any two cells are equal or apart by far more than the tie tolerance)
    rng = np.random.default_rng(seed)
    p = np.round(rng.exponential(3.0, (rng.integers(3, 30), rng.integers(3, 30)))) * 0.5
    assert local_maxima(p).sum() == local_maxima(ulps(p, rng)).sum()


@settings(max_examples=30, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2 ** 31))
def test_assignment_survives_ulp_perturbations(seed):
    rng = np.random.default_rng(seed)
    c = rng.integers(0, 4, (rng.integers(1, 6), rng.integers(1, 6))).astype(float) * 0.7  # many exact ties
    r0, k0 = gated_assignment(c, 1.5)
    r1, k1 = gated_assignment(ulps(c, rng), 1.5)
    assert r0.tolist() == r1.tolist() and k0.tolist() == k1.tolist()
