"""
The switching four-bar (docs/model.md): geometry, closure, stances and their chaining.

Independent checks of `octoroach_model.model.kinematics`: feet held in the world through a
stance, the closed-form closure against numeric solutions of eq. (2)/(3), continuity at the
switches, the Table II figures, and the fast integrator against the readable per-stance
formulas of `stance_motion`.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq, fsolve

import octoroach_model as om
from octoroach_model.model import kinematics
from octoroach_model.model.parameters import ModelParameters

PARAMETERS = ModelParameters.nominal()
L = PARAMETERS.leg_length
D = PARAMETERS.hip_distance
NOMINAL = PARAMETERS.nominal_angles
START = (0.0, 0.0, math.pi / 2)
RIGHT, LEFT = 0, 1


def random_angles(seed, n_runs=40, n_stances=6, sigma=0.1):
    """(n, S, 6) stance angles around Table II, eq. (11)."""
    normals = np.random.default_rng(seed).standard_normal((n_runs, n_stances, 6))
    return kinematics.stance_angles(NOMINAL, normals, sigma, sigma)


def pair_angles(angles, stance):
    """Return rear touchdown, front touchdown, rear liftoff, mirror sign of a stance: (n,) each."""
    pair = stance % 2
    return (angles[:, stance, 2 * pair], angles[:, stance, 2 * pair + 1],
            angles[:, stance, 4 + pair], 1.0 if pair == RIGHT else -1.0)


def body_to_world(pose, x, y):
    """Body-frame points (x right, y forward) to the world: rotate by heading - pi/2 about G."""
    rotation = pose[..., 2] - math.pi / 2
    cos_r, sin_r = np.cos(rotation), np.sin(rotation)
    return (pose[..., 0] + cos_r * x - sin_r * y, pose[..., 1] + sin_r * x + cos_r * y)


def closure_ratio(rear_angle, span):
    """Return c / hypot(a, b) of the closure; |ratio| > 1 where the stance cannot be closed."""
    px = L * np.cos(rear_angle)
    py = D - L * np.sin(rear_angle)
    return (span ** 2 - px ** 2 - py ** 2 - L ** 2) / np.hypot(2 * L * px, 2 * L * py)


def stance_feet(angles, stance, within):
    """
    World feet and span of a stance at fractions `within` (W,): (n, W) arrays.

    The feet come from `feet_in_body` at the rear angle and the closure's front angle, placed
    with the poses that `integrate_stances` gives at those phases.
    """
    rear_td, front_td, rear_lo, mirror = (np.asarray(a)[:, None] if np.ndim(a) else a
                                          for a in pair_angles(angles, stance))
    rear0, front0 = kinematics.feet_in_body(rear_td, front_td, mirror, L, D)
    span = np.hypot(front0[0] - rear0[0], front0[1] - rear0[1])
    branch = kinematics.closure_branch(rear_td, front_td, L, D)
    rear_angle = rear_td + within * (rear_lo - rear_td)
    front_angle = kinematics.solve_front_angle(rear_angle, span, L, D, branch)
    rear, front = kinematics.feet_in_body(rear_angle, front_angle, mirror, L, D)
    poses = kinematics.integrate_stances(angles, stance + within, START, L, D)
    reachable = np.all(np.abs(closure_ratio(rear_angle, span)) <= 1.0, axis=1)
    return (body_to_world(poses, *rear), body_to_world(poses, *front), span, rear, front,
            reachable)


WITHIN = np.append(np.linspace(0.0, 1.0, 41)[:-1], 1.0 - 1e-12)


@pytest.mark.parametrize('seed', [0, 1, 2])
@pytest.mark.parametrize('stance', [2, 3], ids=['right pair', 'left pair'])
def test_feet_stay_fixed_in_the_world_during_a_stance(seed, stance):
    angles = random_angles(seed)
    rear_world, front_world, span, rear, front, reachable = stance_feet(angles, stance, WITHIN)
    # Stances that leave the reachable set are tested separately below.
    assert reachable.mean() > 0.9
    for foot in (*rear_world, *front_world):
        np.testing.assert_allclose(foot[reachable], foot[reachable, :1] * np.ones_like(WITHIN),
                                   rtol=0, atol=1e-9)
    # |O1 O2| keeps its touchdown value aR through the stance.
    distance = np.hypot(front[0] - rear[0], front[1] - rear[1])
    np.testing.assert_allclose(distance[reachable], np.broadcast_to(span, distance.shape)[
        reachable], rtol=0, atol=1e-9)


def test_rear_foot_stays_fixed_even_where_the_closure_cannot_be_met():
    # At sigma = 0.3 many stances sweep the rear leg past where the front leg can follow; the
    # model then holds the front leg at its closest reachable angle and pivots on the rear
    # foot, so only the rear foot stays fixed.
    angles = random_angles(7, n_runs=200, sigma=0.3)
    rear_world, front_world, span, rear, front, reachable = stance_feet(angles, 2, WITHIN)
    assert (~reachable).sum() > 5
    for foot in rear_world:
        np.testing.assert_allclose(foot, foot[:, :1] * np.ones_like(WITHIN), rtol=0,
                                   atol=1e-9)
    distance = np.hypot(front[0] - rear[0], front[1] - rear[1])
    assert np.all(np.abs(distance - span).max(axis=1)[~reachable] > 1e-6)


@pytest.mark.parametrize('seed', [3, 4])
def test_pose_is_continuous_at_every_switch_between_stances(seed):
    angles = random_angles(seed, n_stances=8)
    switches = np.arange(1, 8, dtype=float)
    before = kinematics.integrate_stances(angles, switches - 1e-9, START, L, D)
    at = kinematics.integrate_stances(angles, switches, START, L, D)
    after = kinematics.integrate_stances(angles, switches + 1e-9, START, L, D)
    # A pose moves by a few cm and a few degrees per stance: 1e-9 of a stance is < 1e-9 m.
    np.testing.assert_allclose(before, at, rtol=0, atol=1e-8)
    np.testing.assert_allclose(after, at, rtol=0, atol=1e-8)


def test_integrate_stances_chains_stance_motion():
    # The integrator is the per-stance formulas of stance_motion, rearranged for speed.
    angles = random_angles(5, n_runs=30, n_stances=5, sigma=0.15)
    phase = np.linspace(0.0, 5.5, 111)
    poses = kinematics.integrate_stances(angles, phase, START, L, D)
    pose = np.tile(np.array(START), (len(angles), 1))
    for stance in range(5):
        rear_td, front_td, rear_lo, mirror = pair_angles(angles, stance)
        in_stance = (np.floor(phase) == stance) | ((stance == 4) & (phase >= 4))
        within = np.clip(phase[in_stance] - stance, 0.0, 1.0)
        dx, dy, dheading = kinematics.stance_motion(
            rear_td[:, None], front_td[:, None], rear_lo[:, None], within, mirror, L, D)
        expected_x, expected_y = body_to_world(pose[:, None, :], dx, dy)
        np.testing.assert_allclose(poses[:, in_stance, 0], expected_x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(poses[:, in_stance, 1], expected_y, rtol=0, atol=1e-12)
        np.testing.assert_allclose(poses[:, in_stance, 2], pose[:, None, 2] + dheading,
                                   rtol=0, atol=1e-12)
        dx, dy, dheading = kinematics.stance_motion(rear_td, front_td, rear_lo, 1.0, mirror,
                                                    L, D)
        pose = np.stack([*body_to_world(pose, dx, dy), pose[:, 2] + dheading], axis=1)


def test_integrate_stances_takes_per_run_and_unsorted_phases_alike():
    angles = random_angles(6, n_runs=12, n_stances=4)
    rng = np.random.default_rng(6)
    phase = rng.uniform(-0.5, 4.5, (12, 50))      # per-run phases, beyond both ends too
    start = rng.normal(size=(12, 3))
    poses = kinematics.integrate_stances(angles, phase, start, L, D)
    for run in range(12):
        alone = kinematics.integrate_stances(angles[run:run + 1], phase[run], start[run], L, D)
        np.testing.assert_allclose(poses[run], alone[0], rtol=0, atol=1e-12)
    order = np.argsort(phase[0])
    sorted_poses = kinematics.integrate_stances(angles, phase[0][order], start, L, D)
    np.testing.assert_allclose(poses[0][order], sorted_poses[0], rtol=0, atol=1e-12)
    # held at the ends: before phase 0 at the start pose, past the last stance at its end
    np.testing.assert_allclose(
        kinematics.integrate_stances(angles, [-1.0, 0.0, 4.0, 9.0], start, L, D)[:, [0, 2]],
        kinematics.integrate_stances(angles, [0.0, 0.0, 4.0, 4.0], start, L, D)[:, [1, 3]])


def test_many_runs_give_each_run_what_it_gives_alone():
    # Large calls are worked through in blocks of runs: no run may notice.
    angles = random_angles(9, n_runs=1500, n_stances=20, sigma=0.12)
    grid = np.arange(251) / 25.0
    clocks = grid * (1.0 + 0.1 * np.random.default_rng(9).standard_normal((1500, 1)))
    shared = kinematics.integrate_stances(angles, grid, START, L, D)
    own = kinematics.integrate_stances(angles, clocks, START, L, D)
    for run in (0, 1, 651, 652, 653, 999, 1499):
        alone = kinematics.integrate_stances(angles[run:run + 1], grid, START, L, D)
        np.testing.assert_allclose(shared[run], alone[0], rtol=0, atol=1e-12)
        alone = kinematics.integrate_stances(angles[run:run + 1], clocks[run], START, L, D)
        np.testing.assert_allclose(own[run], alone[0], rtol=0, atol=1e-12)


def test_long_legs_still_chain_stance_motion():
    # With 2 l > d the feet-to-feet segment can point backwards: headings need wrapping.
    angles = random_angles(8, n_runs=10, n_stances=2, sigma=0.4)
    leg = 0.08
    poses = kinematics.integrate_stances(angles, np.linspace(0, 1, 21), START, leg, D)
    dx, dy, dheading = kinematics.stance_motion(
        angles[:, 0, 0:1], angles[:, 0, 1:2], angles[:, 0, 4:5], np.linspace(0, 1, 21), 1.0,
        leg, D)
    np.testing.assert_allclose(poses[..., 2], START[2] + dheading, rtol=0, atol=1e-12)
    np.testing.assert_allclose(poses[..., 1], dy, rtol=0, atol=1e-12)


def test_closed_form_closure_agrees_with_brentq_on_eq_3():
    rng = np.random.default_rng(11)
    rear_td, front_td = NOMINAL[0] + 0.1 * rng.standard_normal((2, 200))
    rear0, front0 = kinematics.feet_in_body(rear_td, front_td, 1.0, L, D)
    span = np.hypot(front0[0] - rear0[0], front0[1] - rear0[1])
    branch = kinematics.closure_branch(rear_td, front_td, L, D)
    rear_angle = rear_td + rng.uniform(0, 1, 200) * (NOMINAL[4] - rear_td)
    ok = np.abs(closure_ratio(rear_angle, span)) <= 1
    assert ok.mean() > 0.95
    closed_form = kinematics.solve_front_angle(rear_angle, span, L, D, branch)
    for i in np.flatnonzero(ok):
        rear, _ = kinematics.feet_in_body(rear_angle[i], 0.0, 1.0, L, D)

        def gap(front_angle, i=i, rear=rear):
            _, front = kinematics.feet_in_body(rear_angle[i], front_angle, 1.0, L, D)
            return np.hypot(front[0] - rear[0], front[1] - rear[1]) - span[i]

        # The root on the touchdown branch lies between the collinear configuration (front
        # leg along P = B - rear foot) and half a turn from it, on the branch's side.
        collinear = math.atan2(D - L * math.sin(rear_angle[i]), L * math.cos(rear_angle[i]))
        root = brentq(gap, collinear, collinear + branch[i] * math.pi, xtol=1e-15)
        assert abs(math.remainder(closed_form[i] - root, 2 * math.pi)) < 1e-9


def test_closed_form_closure_agrees_with_fsolve_on_eq_2_through_a_stance():
    # Eq. (2): l e^{j(pi - phi1)} + aR e^{j(q1 - phi1)} - d e^{j pi/2} - l e^{j phi2} = 0,
    # two real equations in phi2 and q1, followed from touchdown by continuation.
    rng = np.random.default_rng(12)
    for phi1_td, phi2_td, phi_lo in NOMINAL[[0, 1, 4]] + 0.1 * rng.standard_normal((5, 3)):
        rear0, front0 = kinematics.feet_in_body(phi1_td, phi2_td, 1.0, L, D)
        a_r = math.hypot(front0[0] - rear0[0], front0[1] - rear0[1])
        q1 = math.atan2(front0[1] - rear0[1], front0[0] - rear0[0]) + phi1_td
        branch = kinematics.closure_branch(phi1_td, phi2_td, L, D)
        guess = np.array([phi2_td, q1])
        for phi1 in np.linspace(phi1_td, phi_lo, 25):
            if abs(closure_ratio(phi1, a_r)) > 1:
                break

            def eq2(unknowns, phi1=phi1):
                phi2, q = unknowns
                z = (L * np.exp(1j * (math.pi - phi1)) + a_r * np.exp(1j * (q - phi1))
                     - D * 1j - L * np.exp(1j * phi2))
                return [z.real, z.imag]

            guess = fsolve(eq2, guess, xtol=1e-12)
            assert np.max(np.abs(eq2(guess))) < 1e-13
            phi2 = kinematics.solve_front_angle(phi1, a_r, L, D, branch)
            assert abs(math.remainder(float(phi2) - guess[0], 2 * math.pi)) < 1e-9


def test_table_ii_spans_match_the_derived_figures():
    for (rear_deg, front_deg), span_cm in (((45.3, 39.6), 13.21), ((39.9, 47.0), 13.54)):
        rear, front = kinematics.feet_in_body(math.radians(rear_deg), math.radians(front_deg),
                                              1.0, 0.021, 0.13)
        assert math.hypot(front[0] - rear[0], front[1] - rear[1]) * 100 == pytest.approx(
            span_cm, abs=0.01)


def test_table_ii_path_travels_about_56_cm_in_10_cycles():
    run = om.simulate(1, seed=0, sigma1=0.0, sigma2=0.0, parameters=PARAMETERS)
    steps = np.diff(run.poses[0, :, :2], axis=0)
    assert 0.54 < np.hypot(*steps.T).sum() < 0.58
    # about 2.8 cm per stance, measured between switches
    switches = om.simulate(1, seed=0, sigma1=0.0, sigma2=0.0, parameters=PARAMETERS,
                           t=np.arange(21) / (2 * PARAMETERS.stride_frequency))
    advance = np.hypot(*np.diff(switches.poses[0, :, :2], axis=0).T)
    assert advance.mean() == pytest.approx(0.028, abs=0.001)
    np.testing.assert_allclose(advance, 0.028, atol=0.002)
