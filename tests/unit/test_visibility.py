"""The visibility gate: a hidden point only where its relay wall can show it (the wedge its observed
segment subtends from the mirrored radar, in front of the wall, ahead of the radar). Hand-made
walls and points with the answers worked out by hand; the mirror reconstructors leave ghosts out and
list them; the frame's record counts them."""
import numpy as np
import pytest

from plugins.mirror.mirror import MirrorReconstructor
from plugins.mirror.visibility import (BEHIND_RADAR, BEHIND_WALL, OUTSIDE_WEDGE, VISIBLE, describe_gated,
                                       visibility)
from xnlos_core.errors import InputError
from xnlos_core.geometry import mirror_reflect
from xnlos_core.types import LOS, MNLOS, Detections, WallPosterior

COV = np.diag([1e-4, 1e-4])
# A facade along y = 5 m seen from x = 5 to 15 m (n = (0, −1), b = 5: −y + 5 = 0, radar side y < 5).
FACADE = WallPosterior("line", np.array([-np.pi / 2, 5.0]), COV, extent=np.array([[5.0, 5.0], [15.0, 5.0]]))
# A spurious short wall 1 m ahead of the radar, facing it (n = (−1, 0), b = 1).
SPURIOUS = WallPosterior("line", np.array([np.pi, 1.0]), COV, extent=np.array([[1.0, -3.0], [1.0, 3.0]]))


def mirrored(virtual, wall):
    return mirror_reflect(np.asarray(virtual, float), wall.normal, wall.offset)


def test_inside_the_wedge_is_visible():
    # o' = (10, 8): the ray crosses y = 5 at x = 6.25, on the observed facade; o = (10, 2).
    v = np.array([[10.0, 8.0]])
    o = mirrored(v, FACADE)
    np.testing.assert_allclose(o, [[10.0, 2.0]])
    assert visibility(o, v, [FACADE], [0]).tolist() == [VISIBLE]


def test_outside_the_wedge_is_a_ghost_unless_within_the_margin():
    # o' = (30, 8) crosses y = 5 at x = 18.75: 3.75 m past the facade's seen end.
    v = np.array([[30.0, 8.0]])
    o = mirrored(v, FACADE)
    assert visibility(o, v, [FACADE], [0], margin=2.0).tolist() == [OUTSIDE_WEDGE]
    assert visibility(o, v, [FACADE], [0], margin=4.0).tolist() == [VISIBLE]
    # the same wall without a known extent is an unbounded mirror: no wedge to leave
    unbounded = WallPosterior("line", FACADE.mean, COV)
    assert visibility(o, v, [unbounded], [0]).tolist() == [VISIBLE]


def test_a_point_on_the_radars_side_of_the_wall_is_not_behind_the_mirror():
    # o' = (10, 3) lies in front of the facade: its ray never reaches the wall.
    v = np.array([[10.0, 3.0]])
    assert visibility(mirrored(v, FACADE), v, [FACADE], [0]).tolist() == [OUTSIDE_WEDGE]
    # a (residual-moved) hidden point pushed through the wall: behind the mirror
    v = np.array([[10.0, 8.0]])
    assert visibility(np.array([[10.0, 6.0]]), v, [FACADE], [0]).tolist() == [BEHIND_WALL]


def test_behind_the_radar_is_a_ghost_unless_allowed():
    # A far echo at o' = (20, 0.5) mirrored across a wall 1 m ahead lands at (−18, 0.5).
    v = np.array([[20.0, 0.5]])
    o = mirrored(v, SPURIOUS)
    np.testing.assert_allclose(o, [[-18.0, 0.5]])
    assert visibility(o, v, [SPURIOUS], [0]).tolist() == [BEHIND_RADAR]
    assert visibility(o, v, [SPURIOUS], [0], ahead=None).tolist() == [VISIBLE]


def test_bad_arguments_are_named():
    with pytest.raises(InputError, match="wall_index"):
        visibility(np.zeros((1, 2)), np.zeros((1, 2)), [FACADE], [1])
    with pytest.raises(InputError, match="one row per hidden point"):
        visibility(np.zeros((2, 2)), np.zeros((1, 2)), [FACADE], [0])
    with pytest.raises(InputError, match="margin"):
        visibility(np.zeros((1, 2)), np.ones((1, 2)), [FACADE], [0], margin=-1)


def test_description_names_rules_and_detections():
    line = describe_gated(np.array([VISIBLE, OUTSIDE_WEDGE, BEHIND_RADAR, OUTSIDE_WEDGE]), [4, 5, 6, 7])
    assert "2 outside its wall's visibility wedge (detections [5, 7])" in line
    assert "1 behind the radar (detections [6])" in line
    assert describe_gated(np.array([VISIBLE]), [0]) is None


def _detections(points, labels) -> Detections:
    p = np.asarray(points, float)
    r, az = np.hypot(p[:, 0], p[:, 1]), np.arctan2(p[:, 1], p[:, 0])
    k = len(p)
    return Detections(r, az, np.asarray(labels, np.int8), np.ones(k), np.full(k, 0.05), np.full(k, 0.01))


@pytest.mark.parametrize("gate", [True, False])
def test_mirror_reconstructor_leaves_ghosts_out_and_lists_them(gate):
    # rows: a LOS point, a visible mNLOS echo, one beyond the facade's wedge, one through a spurious wall
    # 1 m ahead of the radar seen at y = −6 … −3 m (its ray crosses x = 1 at y = −2, within the margin)
    spurious = WallPosterior("line", SPURIOUS.mean, COV, extent=np.array([[1.0, -6.0], [1.0, -3.0]]))
    det = _detections([[8.0, 4.0], [10.0, 8.0], [30.0, 8.0], [20.0, -40.0]], [LOS, MNLOS, MNLOS, MNLOS])
    recon = MirrorReconstructor({"gate": gate})
    hidden = recon.reconstruct(det, [FACADE, spurious])
    if gate:
        assert hidden.source_index.tolist() == [1] and sorted(hidden.gated.tolist()) == [2, 3]
        np.testing.assert_allclose(hidden.mean, [[10.0, 2.0]], atol=1e-9)
    else:
        assert hidden.source_index.tolist() == [1, 2, 3] and hidden.gated.tolist() == []
        assert hidden.mean[:, 0].min() < -17  # the ghost behind the radar, as the ungated path gave it


@pytest.mark.parametrize("wedge_margin, kept, gated", [(None, [0, 1], []), (1.5, [0, 1], []), (0.0, [0], [1])])
def test_the_wedge_margin_is_the_gates_own(wedge_margin, kept, gated):
    # o' = (25.6, 8) crosses y = 5 at x = 16: 1 m past the facade's seen end. Anchoring takes the facade
    # (within extent_margin = 2 m); the gate keeps it only where wedge_margin (None: extent_margin) reaches.
    det = _detections([[10.0, 8.0], [25.6, 8.0]], [MNLOS, MNLOS])
    hidden = MirrorReconstructor({"wedge_margin": wedge_margin}).reconstruct(det, [FACADE])
    assert hidden.source_index.tolist() == kept and hidden.gated.tolist() == gated


def test_frame_record_counts_gated(tmp_path):
    from xnlos_core.app.results_schema import validate_record
    from xnlos_core.frame_record import hidden_from_record, hidden_record
    from xnlos_core.pipeline import FrameResult
    from xnlos_core.radar import load_radar
    from xnlos_core.types import Frame, RAMap

    det = _detections([[8.0, 4.0], [10.0, 8.0], [30.0, 8.0]], [LOS, MNLOS, MNLOS])
    hidden = MirrorReconstructor().reconstruct(det, [FACADE])
    radar = load_radar({}, "t", ".")
    ra = RAMap(np.zeros((4, 3), np.complex64), np.arange(1.0, 5.0), np.array([-0.1, 0.0, 0.1]), radar)
    rec = FrameResult(Frame(ra), det, [FACADE], hidden, None).record()
    assert rec["n_gated"] == 1 and rec["hidden"]["gated"] == [2]
    validate_record(rec)
    assert hidden_from_record(hidden_record(hidden)).gated.tolist() == [2]


def test_a_static_echo_on_a_wall_is_that_walls_own_echo():
    from plugins.mirror.visibility import WALL_ECHO

    # o' = (20.2, 8) lies 0.2 m behind a far wall x = 20 (seen for y ∈ [0, 10]); its ray crosses the facade
    # at x = 12.6, so it mirrors to (20.2, 2), among the road users.
    far = WallPosterior("line", np.array([np.pi, 20.0]), COV, extent=np.array([[20.0, 0.0], [20.0, 10.0]]))
    v = np.array([[20.2, 8.0]])
    o = mirrored(v, FACADE)
    walls = [FACADE, far]
    assert visibility(o, v, walls, [0], velocity=[0.05], velocity_var=[0.01]).tolist() == [WALL_ECHO]
    assert visibility(o, v, walls, [0], velocity=[2.0], velocity_var=[0.01]).tolist() == [VISIBLE]  # it moves
    assert visibility(o, v, walls, [0]).tolist() == [VISIBLE]  # no Doppler: cannot tell a parked car
    assert visibility(o, v, walls, [0], velocity=[0.4], velocity_var=[0.04]).tolist() == [WALL_ECHO]  # 2σ
    v2 = np.array([[22.0, 9.0]])  # 2 m behind the far wall: a hidden object, not the wall
    assert visibility(mirrored(v2, FACADE), v2, walls, [0], velocity=[0.0], velocity_var=[0.01]).tolist() == [VISIBLE]


# A stopped car's side fitted as a short wall in front of the facade: y = 3.5 m from x = 3.5 to 5.5 m.
CAR_SIDE = WallPosterior("line", np.array([-np.pi / 2, 3.5]), COV, extent=np.array([[3.5, 3.5], [5.5, 3.5]]))


def test_a_ray_through_two_seen_walls_is_an_ambiguous_relay():
    from plugins.mirror.visibility import TWO_RELAYS
    # o' = (10, 8): its ray crosses y = 3.5 at x = 4.375 (on the car's side) before y = 5 at x = 6.25 (on
    # the facade). o' = (14, 8) crosses y = 3.5 at x = 6.125, past the car: only the facade relays it.
    v = np.array([[10.0, 8.0], [14.0, 8.0]])
    o = mirrored(v, FACADE)
    walls = [FACADE, CAR_SIDE]
    assert visibility(o, v, walls, [0, 0], margin=0.0).tolist() == [VISIBLE, VISIBLE]
    assert visibility(o, v, walls, [0, 0], margin=0.0, one_relay=True).tolist() == [TWO_RELAYS, VISIBLE]
    # within a 1 m margin the second ray reaches the car's side too (6.125 − 5.5 = 0.625 m past its end)
    assert visibility(o, v, walls, [0, 0], margin=1.0, one_relay=True).tolist() == [TWO_RELAYS, TWO_RELAYS]
    assert "ambiguous relay" in describe_gated(np.array([TWO_RELAYS]), [7])


@pytest.mark.parametrize("one_relay, kept, gated", [(True, [1], [0]), (False, [0, 1], [])])
def test_the_mirror_reports_no_point_behind_two_walls(one_relay, kept, gated):
    # Anchoring takes the first crossing (the car's side): mirrored there the point lands at (10, −1), a
    # ghost; the gate refuses it unless one_relay is off. The second point crosses the facade only.
    det = _detections([[10.0, 8.0], [14.0, 8.0]], [MNLOS, MNLOS])
    hidden = MirrorReconstructor({"one_relay": one_relay}).reconstruct(det, [FACADE, CAR_SIDE])
    assert hidden.source_index.tolist() == kept and hidden.gated.tolist() == gated
    if not one_relay:
        np.testing.assert_allclose(hidden.mean[0], [10.0, -1.0], atol=1e-9)
