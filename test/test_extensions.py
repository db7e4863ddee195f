"""
The extension families beyond the table of causes: definitions, and the diagnosis finding them.

Each family's simulator term is checked against its definition (docs/extensions.md) on runs
of the same seed with and without it (common random numbers). Then every family is hidden in
data from a robot drawn at random near Table II, at a size drawn where 300 runs find it
reliably, and the diagnosis must name it (and no cause of the table) with its size within
40 %. The draws come from the suite seed (pytest's header; `OCTOROACH_TEST_SEED=N make test`
replays them), and every failure message says how to replay it.
"""
from __future__ import annotations

from dataclasses import replace
import json
import math
import random
import subprocess
import sys

from hidden_effects import FAST, SEED, WEAR_SETTINGS
from hypothesis import given, seed, settings, strategies as st
import numpy as np
import pytest

import octoroach_model as om
from octoroach_model.diagnosis import diagnose, write_report
from octoroach_model.diagnosis.discrepancies import HEADING_RATE_CHANGE
from octoroach_model.diagnosis.features import INDEX, run_features
from octoroach_model.diagnosis.misfit import Misfit, where_in_a_run
from octoroach_model.diagnosis.modelfit import FittedModel
from octoroach_model.diagnosis.plots import _mean_turn, _turn_spread, stride_windows
from octoroach_model.diagnosis.summary import summary_text
from octoroach_model.model.extensions import drift_term, WORN_ANGLES
from octoroach_model.studies.outside import leg_wear, speed_wobble, WORN_LEG, yaw_ramp

N = 400
DETERMINISTIC = {'sigma1': 0.0, 'sigma2': 0.0}


def replay(what: str) -> str:
    """Begin a failure message with how to draw the same case again."""
    return f'OCTOROACH_TEST_SEED={SEED} ({what})'


def evidence(report, family: str) -> str:
    """Say how a family fared where it was last weighed: its size's bound and its test."""
    weighed = [c for c in report.extension_candidates if c.family == family]
    return '; '.join(
        f'{c.cause} at step {c.step}: {c.parameters}, bound {c.lower_bound:.3g} for a floor '
        f'of {c.floor:.3g}, held-out gain {c.gain:.3g} +- {c.gain_se:.3g} nats a run, '
        f'p {c.p_value:.2g}' + (' (screened)' if c.screened else '') for c in weighed)


@pytest.fixture(scope='module')
def plain():
    return om.simulate(N, seed=11)


def plain_at(times) -> np.ndarray:
    """Sample the deterministic Table II model at `times`: (1, T, 3)."""
    return om.simulate(1, seed=0, t=np.asarray(times, float), **DETERMINISTIC).poses


def extra_heading(runs: om.Paths, base: om.Paths) -> np.ndarray:
    return runs.poses[..., 2] - base.poses[..., 2]


def turned_steps(base: om.Paths, angle: np.ndarray) -> np.ndarray:
    """Each sample step of `base` turned by `angle` at its midpoint: the definition's integral."""
    steps = np.diff(base.poses[..., :2], axis=1)
    middle = 0.5 * (angle[:, 1:] + angle[:, :-1])
    cos, sin = np.cos(middle), np.sin(middle)
    return np.stack([cos * steps[..., 0] - sin * steps[..., 1],
                     sin * steps[..., 0] + cos * steps[..., 1]], axis=-1)


def test_a_stride_frequency_drift_runs_run_i_at_its_own_rate():
    change = -0.15
    runs = om.simulate(5, seed=0, extensions={'run_order_drift': {
        'parameter': 'stride_frequency', 'change': change}}, **DETERMINISTIC)
    for index, place in enumerate(np.linspace(0, 1, 5)):
        expected = plain_at((1 + change * place) * runs.t)[0]
        np.testing.assert_allclose(runs.poses[index], expected, rtol=0, atol=1e-9)


@pytest.mark.parametrize('change', [6.0, -4.0])
def test_a_yaw_rate_drift_turns_run_i_at_change_times_its_place(plain, change):
    runs = om.simulate(N, seed=11, extensions={'run_order_drift': {
        'parameter': 'yaw_rate', 'change': change}})
    places = np.linspace(0, 1, N)
    angle = math.radians(change) * places[:, None] * runs.t[None, :]
    np.testing.assert_allclose(extra_heading(runs, plain), angle, rtol=0, atol=1e-12)
    steps = np.diff(runs.poses[..., :2], axis=1)
    np.testing.assert_allclose(steps, turned_steps(plain, angle), rtol=0, atol=1e-12)


def test_a_lateral_velocity_drift_slips_run_i_at_change_times_its_place():
    change = 3.0
    runs = om.simulate(5, seed=0, extensions={'run_order_drift': {
        'parameter': 'lateral_velocity', 'change': change}}, **DETERMINISTIC)
    for index, place in enumerate(np.linspace(0, 1, 5)):
        slip = om.simulate(1, seed=0, effects={'lateral_slip': {
            'velocity_cm_s': change * place}}, **DETERMINISTIC).poses[0]
        np.testing.assert_allclose(runs.poses[index], slip, rtol=0, atol=1e-12)


@pytest.mark.parametrize('leg, change', [(1, 9.0), (2, -12.0), (3, 9.0), (3, -12.0), (4, 7.0)])
def test_a_touchdown_angle_drift_strides_run_i_with_its_leg_moved_by_change_times_its_offset(
        leg, change):
    """Run i is the robot with phi_leg + change (q_i - 1/2), its liftoff by eqs. (7)-(8)."""
    robot = om.ModelParameters.nominal()
    runs = om.simulate(5, seed=0, extensions={'run_order_drift': {
        'parameter': f'touchdown_angle_{leg}', 'change': change}}, **DETERMINISTIC)
    for index, place in enumerate(np.linspace(0, 1, 5)):
        angles = list(robot.touchdown_angles)
        angles[leg - 1] += math.radians(change) * (place - 0.5)
        worn = replace(robot, touchdown_angles=tuple(angles)).with_paper_liftoff()
        alone = om.simulate(1, seed=0, parameters=worn, **DETERMINISTIC).poses[0]
        np.testing.assert_allclose(runs.poses[index], alone, rtol=0, atol=1e-12)


@seed(SEED)
@settings(max_examples=60, deadline=None)
@given(changes=st.dictionaries(st.sampled_from(sorted(WORN_ANGLES)), st.floats(-60.0, 60.0),
                               min_size=1),
       places=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=6),
       liftoff_offset=st.sampled_from([0.0, 0.05]))
def test_drifted_touchdown_angles_move_their_pairs_liftoff_as_eqs_7_8_run_by_run(
        changes, places, liftoff_offset):
    """
    Whatever legs drift, by whatever and wherever: each pair's liftoff moves as -min does.

    Each drifted angle moves by its change times (q_i - 1/2), the others stay; each pair's
    liftoff is -min(rear, front) on Table II's robot (liftoff by eqs. 7-8), and on a table
    whose liftoff angles are its own (0.05 rad off) it moves from them by as much.
    """
    from octoroach_model.model.effects import worn_angles

    nominal = om.ModelParameters.nominal()
    robot = replace(nominal, liftoff_angles=tuple(a + liftoff_offset
                                                  for a in nominal.liftoff_angles))
    effects = {drift_term(name): {'change': change} for name, change in changes.items()}
    t = np.linspace(0.0, 1.0, 3)
    angles = worn_angles(robot.nominal_angles, effects, t, np.array(places))[:, 0, :]
    expected = np.tile(robot.touchdown_angles, (len(places), 1))
    for name, change in changes.items():
        expected[:, WORN_ANGLES[name]] += math.radians(change) * (np.array(places) - 0.5)
    np.testing.assert_allclose(angles[:, :4], expected, rtol=0, atol=1e-12)
    for pair, liftoff in ((0, 4), (2, 5)):
        np.testing.assert_allclose(angles[:, liftoff], liftoff_offset - np.minimum(
            angles[:, pair], angles[:, pair + 1]), atol=1e-12)


def test_a_heading_random_walk_steps_at_each_stance_after_the_first(plain):
    step_deg = 2.0
    runs = om.simulate(N, seed=11, extensions={'heading_random_walk': {
        'step_std_deg': step_deg}})
    angle = extra_heading(runs, plain)
    stances = np.floor(2 * om.ModelParameters.nominal().stride_frequency * runs.t + 1e-9)
    begins = np.flatnonzero(np.diff(stances) > 0) + 1          # first sample of each stance
    np.testing.assert_allclose(angle[:, :begins[0]], 0.0, atol=1e-12)   # the first stance
    jumps = np.diff(angle, axis=1)
    inside = np.setdiff1d(np.arange(jumps.shape[1]), begins - 1)
    np.testing.assert_allclose(jumps[:, inside], 0.0, atol=1e-12)       # steady in a stance
    sizes = jumps[:, begins - 1].ravel()
    assert abs(sizes.std() / math.radians(step_deg) - 1) < 4 / math.sqrt(2 * sizes.size)
    assert abs(np.corrcoef(jumps[:, begins[0] - 1], jumps[:, begins[1] - 1])[0, 1]) < 0.2
    steps = np.diff(runs.poses[..., :2], axis=1)
    np.testing.assert_allclose(steps, turned_steps(plain, angle), rtol=0, atol=1e-12)


def test_a_periodic_heading_swings_from_a_random_phase(plain):
    amplitude, frequency = 4.0, 0.7
    runs = om.simulate(N, seed=11, extensions={'periodic_heading': {
        'amplitude_deg': amplitude, 'frequency_hz': frequency}})
    angle = extra_heading(runs, plain)
    t = runs.t
    # a(t) = A (sin(2 pi f t + phi) - sin(phi)): recover phi from a(t) at two times
    phases = []
    for row in angle:
        fit = np.linalg.lstsq(np.column_stack([np.sin(2 * np.pi * frequency * t),
                                               np.cos(2 * np.pi * frequency * t) - 1]),
                              row, rcond=None)[0]
        phases.append(math.atan2(fit[1], fit[0]))
        expected = math.radians(amplitude) * (np.sin(2 * np.pi * frequency * t + phases[-1])
                                              - math.sin(phases[-1]))
        np.testing.assert_allclose(row, expected, rtol=0, atol=1e-9)
    counts, _ = np.histogram(np.mod(phases, 2 * np.pi), bins=4, range=(0, 2 * np.pi))
    assert counts.min() > N / 4 - 4 * math.sqrt(N / 4), counts     # uniform phases


@pytest.mark.parametrize('factor', [0.7, 1.3])
def test_a_change_point_runs_the_gait_clock_at_a_new_rate_from_its_time(factor):
    time_s = 2.75
    runs = om.simulate(1, seed=0, extensions={'change_point': {
        'time_s': time_s, 'speed_factor': factor}}, **DETERMINISTIC)
    t = runs.t
    tau = np.where(t < time_s, t, time_s + factor * (t - time_s))
    np.testing.assert_allclose(runs.poses[0], plain_at(tau)[0], rtol=0, atol=1e-9)


def test_a_run_mixture_turns_a_share_of_the_runs_and_leaves_the_rest(plain):
    fraction, rate = 0.3, 8.0
    runs = om.simulate(N, seed=11, extensions={'run_mixture': {
        'fraction': fraction, 'yaw_rate_deg_s': rate}})
    angle = extra_heading(runs, plain)
    turning = np.abs(angle[:, -1]) > 1e-9
    np.testing.assert_allclose(angle[turning], math.radians(rate) * np.broadcast_to(
        runs.t, angle[turning].shape), rtol=0, atol=1e-12)
    np.testing.assert_allclose(runs.poses[~turning], plain.poses[~turning], rtol=0, atol=1e-12)
    assert abs(turning.mean() - fraction) < 4 * math.sqrt(fraction * (1 - fraction) / N)


@pytest.mark.parametrize('rate', [6.0, -3.0])
def test_a_yaw_rate_ramp_turns_every_run_at_a_rate_rising_to_its_final_value(plain, rate):
    runs = om.simulate(N, seed=11, extensions={'yaw_rate_ramp': {'final_yaw_rate_deg_s': rate}})
    duration = float(runs.t[-1])
    angle = np.broadcast_to(math.radians(rate) * runs.t ** 2 / (2 * duration), (N, len(runs.t)))
    np.testing.assert_allclose(extra_heading(runs, plain), angle, rtol=0, atol=1e-12)
    steps = np.diff(runs.poses[..., :2], axis=1)
    np.testing.assert_allclose(steps, turned_steps(plain, np.ascontiguousarray(angle)),
                               rtol=0, atol=1e-12)


def test_an_extension_of_size_zero_or_beside_others_leaves_every_draw_unchanged(plain):
    for extensions in ({'heading_random_walk': {'step_std_deg': 0.0}},
                       {'periodic_heading': {'amplitude_deg': 0.0, 'frequency_hz': 0.5}},
                       {'change_point': {'time_s': 1.0, 'speed_factor': 1.0}},
                       {'run_mixture': {'fraction': 0.0, 'yaw_rate_deg_s': 5.0}},
                       {'run_order_drift': {'parameter': 'yaw_rate', 'change': 0.0}},
                       {'run_order_drift': {'parameter': 'touchdown_angle_3', 'change': 0.0}},
                       {'yaw_rate_ramp': {'final_yaw_rate_deg_s': 0.0}}):
        runs = om.simulate(N, seed=11, extensions=extensions)
        np.testing.assert_allclose(runs.poses, plain.poses, rtol=0, atol=1e-12,
                                   err_msg=str(extensions))
    noise = {'measurement_noise': {'position_std_cm': 0.5}}
    alone = om.simulate(50, seed=11, effects=noise)
    beside = om.simulate(50, seed=11, effects=noise, extensions={
        'heading_random_walk': {'step_std_deg': 0.0}})
    np.testing.assert_allclose(beside.poses, alone.poses, rtol=0, atol=1e-12)


def test_bad_extensions_are_refused_with_a_reason():
    with pytest.raises(om.ParameterError, match=r'unknown extension, text \(6 characters'):
        om.simulate(2, extensions={'wobble': {}})
    with pytest.raises(om.ParameterError, match=r'\(did you mean run_mixture\?\); known'):
        om.simulate(2, extensions={'run_mixtur': {}})
    with pytest.raises(om.ParameterError, match='needs parameter .*, got None'):
        om.simulate(2, extensions={'run_order_drift': {'change': 0.1}})
    with pytest.raises(om.ParameterError, match=r'got text .* \(did you mean yaw_rate\?\)'):
        om.simulate(2, extensions={'run_order_drift': {'parameter': 'yawrate'}})
    with pytest.raises(om.ParameterError, match=r'touchdown_angle is touchdown_angle_3 \(phi3\)'):
        om.simulate(2, extensions={'run_order_drift': {'parameter': 'touchdown_angle'}})
    with pytest.raises(om.ParameterError, match='outside'):
        om.simulate(2, extensions={'run_mixture': {'fraction': 1.5}})
    with pytest.raises(om.ParameterError, match=r'no parameter text \(4 characters'):
        om.simulate(2, extensions={'change_point': {'time': 1.0}})


def test_simulate_writes_runs_with_an_extension_in_recording_order(tmp_path):
    bag = tmp_path / 'drift'
    done = subprocess.run(
        [sys.executable, '-m', 'octoroach_model', 'simulate', '--paths', '6', '--seed', '3',
         '--out', str(bag), '--cycles', '4', '--extension', 'run_order_drift',
         '--extension-param', 'parameter=yaw_rate', '--extension-param', 'change=20'],
        capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    written = json.loads(done.stdout)
    assert written['extensions'] == [{'family': 'run_order_drift', 'parameters': {
        'parameter': 'yaw_rate', 'change': 20.0}}]
    measured = om.load_measured([bag])
    places, known = measured.recording_positions()
    assert known and np.all(np.diff(places) > 0)               # bag order is recording order
    drawn = om.simulate(6, seed=3, cycles=4, extensions={'run_order_drift': {
        'parameter': 'yaw_rate', 'change': 20.0}})
    turn = measured.poses[:, -1, 2] - measured.poses[:, 0, 2]
    np.testing.assert_allclose(turn, drawn.poses[:, -1, 2] - drawn.poses[:, 0, 2], atol=2e-3)
    bad = subprocess.run(
        [sys.executable, '-m', 'octoroach_model', 'simulate', '--paths', '2', '--out',
         str(tmp_path / 'bad'), '--extension', 'run_order_drift', '--extension-param',
         'parameter=speed'], capture_output=True, text=True, timeout=60)
    assert bad.returncode != 0 and bad.stderr.count('\n') == 1 and 'Traceback' not in bad.stderr
    assert 'run_order_drift needs parameter' in bad.stderr
    not_a_number = subprocess.run(
        [sys.executable, '-m', 'octoroach_model', 'simulate', '--paths', '2', '--out',
         str(tmp_path / 'bad'), '--extension', 'change_point', '--extension-param',
         'speed_factor=slow'], capture_output=True, text=True, timeout=60)
    assert not_a_number.returncode == 1, not_a_number.stderr
    assert not_a_number.stderr == ("error: simulate: --extension-param speed_factor=slow: 'slow' "
                                   'is not a number\n')
    assert not (tmp_path / 'bad').exists()


def test_a_data_set_and_shuffled_inputs_keep_the_recording_order(tmp_path):
    measured = om.load_measured([write_bag(tmp_path / 'bag', 8)])
    om.save_dataset(tmp_path / 'runs.npz', measured)
    again = om.load_measured([tmp_path / 'runs.npz'])
    np.testing.assert_array_equal(again.recording_positions()[0],
                                  measured.recording_positions()[0])
    assert again.recording_positions()[1]
    shuffled = measured.subset(np.array([3, 0, 7, 1, 2, 6, 5, 4]))
    places, known = shuffled.recording_positions()
    assert known
    np.testing.assert_allclose(places * 7, [3, 0, 7, 1, 2, 6, 5, 4])
    unknown = om.Paths(measured.t, measured.poses)                # no start times at all
    assert not unknown.recording_positions()[1]
    np.testing.assert_allclose(unknown.recording_positions()[0] * 7, np.arange(8))


def write_bag(path, runs: int):
    om.write_paths_bag(path, om.simulate(runs, seed=1, cycles=3))
    return path


HIDDEN = ('run_order_drift', 'heading_random_walk', 'periodic_heading', 'change_point',
          'run_mixture', 'yaw_rate_ramp')


def random_robot(rng: random.Random) -> tuple[om.ModelParameters, int, float]:
    """Draw a robot near Table II: angles within 3 deg, leg 1.9-2.4 cm, 1.5-3 Hz, 8-12 cycles."""
    nominal = om.ModelParameters.nominal()
    angles = tuple(a + math.radians(rng.uniform(-3, 3)) for a in nominal.touchdown_angles)
    robot = replace(nominal, touchdown_angles=angles, leg_length=rng.uniform(0.019, 0.024),
                    stride_frequency=rng.uniform(1.5, 3.0),
                    sample_rate=rng.choice([50.0, 100.0])).with_paper_liftoff()
    return robot, rng.randint(8, 12), rng.uniform(0.6, 1.2)


def draw_extension(rng: random.Random, family: str, robot: om.ModelParameters, cycles: int,
                   scale: float) -> tuple[dict, str, float]:
    """
    Return (extensions, the term's main parameter, its size) at a size 300 runs find.

    heading_random_walk's step is drawn in units of the robot's spread scale, and
    run_mixture's turning rate in units of the robot's own spread of heading rates
    across runs (4.5 to 6.5 of them): its detection limit is about 3 (8.4 deg/s for a robot
    whose rates spread by 2.8 deg/s, 150 calibration runs), so a rate drawn in deg/s alone
    fell below the limit of the robots with the widest spread. So is the yaw rate's drift
    over the session (3.5 to 5.5 of them): drawn as 25-45 deg a run, it came to 2.1 spreads on
    a robot of spread x1.12 and went unnamed (suite seed 8128).
    """
    sign = rng.choice([-1.0, 1.0])
    if family == 'run_order_drift':
        drifted = rng.choice(['stride_frequency', 'yaw_rate', 'lateral_velocity'])
        sizes = {'stride_frequency': rng.uniform(0.08, 0.2),
                 'yaw_rate': rng.uniform(3.5, 5.5),          # spreads of heading rates
                 'lateral_velocity': rng.uniform(1.5, 3.0)}
        if drifted == 'yaw_rate':
            sizes['yaw_rate'] *= heading_rate_spread_deg_s(rng, robot, cycles, scale)
        size = sign * sizes[drifted]
        return {family: {'parameter': drifted, 'change': round(size, 4)}}, 'change', size
    duration = cycles / robot.stride_frequency
    if family == 'heading_random_walk':
        # in units of the robot's spread scale: its limit at 500 runs is 0.9-1.2 x the scale
        # (studies/open_world.yaml), a little more at 300; 1.5-3 deg alone came within 1.2 x
        # the limit of the widest-spread robots
        size = scale * rng.uniform(2.5, 3.5)
        return {family: {'step_std_deg': round(size, 3)}}, 'step_std_deg', size
    if family == 'periodic_heading':
        size = rng.uniform(3.0, 6.0)
        frequency = rng.uniform(2.2 / duration, 0.55 * robot.stride_frequency)
        return ({family: {'amplitude_deg': round(size, 3), 'frequency_hz': round(frequency, 3)}},
                'amplitude_deg', size)
    if family == 'change_point':
        factor = rng.uniform(0.65, 0.85) if sign < 0 else rng.uniform(1.15, 1.35)
        return ({family: {'time_s': round(rng.uniform(0.3, 0.7) * duration, 3),
                          'speed_factor': round(factor, 3)}}, 'speed_factor', factor)
    spread = heading_rate_spread_deg_s(rng, robot, cycles, scale)
    if family == 'yaw_rate_ramp':
        # in units of the robot's spread of heading rates too: on Table II's robot (1.9
        # deg/s) 300 runs named a ramp to 4 and 5 deg/s (t 7.4 and 4.7), not one to 3 (2.3),
        # before the ramp's signature was scored (features.py, note (5))
        size = sign * rng.uniform(3.5, 5.0) * spread
        return ({family: {'final_yaw_rate_deg_s': round(size, 3)}}, 'final_yaw_rate_deg_s',
                size)
    size = sign * rng.uniform(4.5, 6.5) * spread
    return ({family: {'fraction': round(rng.uniform(0.25, 0.45), 3),
                      'yaw_rate_deg_s': round(size, 3)}}, 'yaw_rate_deg_s', size)


def heading_rate_spread_deg_s(rng: random.Random, robot: om.ModelParameters, cycles: int,
                              scale: float) -> float:
    """Return the robot's own spread of heading rates across runs (300 simulated runs), deg/s."""
    sigma1, sigma2 = om.model.nominal_sigmas()
    plain = om.simulate(300, seed=rng.randrange(10 ** 6), cycles=cycles, parameters=robot,
                        sigma1=sigma1 * scale, sigma2=sigma2 * scale)
    rates = run_features(plain, robot.stride_frequency, 0.0)[:, INDEX['heading_rate']]
    return math.degrees(float(np.std(rates, ddof=1)))


@pytest.mark.long
@pytest.mark.parametrize('family', HIDDEN)
def test_a_family_hidden_in_data_from_a_random_robot_is_named_and_sized(family):
    rng = random.Random(SEED * 100 + HIDDEN.index(family))
    robot, cycles, scale = random_robot(rng)
    extensions, parameter, truth = draw_extension(rng, family, robot, cycles, scale)
    sigma1, sigma2 = om.model.nominal_sigmas()
    measured = om.simulate(300, seed=SEED + 31, cycles=cycles, parameters=robot,
                           sigma1=sigma1 * scale, sigma2=sigma2 * scale, extensions=extensions)
    report = diagnose(measured, replace(FAST, seed=SEED + 31))
    found = [(e.family, e.parameters) for e in report.extensions]
    case = f'{extensions}, robot {robot.table()}, {cycles} cycles, spread x{scale:.2f}'
    causes = [(c.cause, c.parameters) for c in report.causes]
    message = f'{replay(case)}: extensions {found}, causes {causes}; {evidence(report, family)}'
    named = [e for e in report.extensions if e.family == family]
    assert len(named) == 1 and not report.causes, message
    if family == 'run_order_drift':
        assert named[0].parameters['parameter'] == extensions[family]['parameter'], message
    estimate = named[0].parameters[parameter]
    assert abs(estimate - truth) <= 0.4 * abs(truth - (1.0 if family == 'change_point' else 0)), \
        message
    low, high = named[0].interval[parameter]
    assert low <= estimate <= high, message
    assert named[0].description, message


@pytest.mark.long
def test_an_effect_outside_table_and_library_is_reported_as_unexplained(tmp_path):
    rng = random.Random(SEED * 10 + 41)
    amplitude, period = rng.uniform(0.3, 0.5), rng.uniform(1.2, 2.0)
    grid = om.simulate(300, seed=SEED + 41)
    measured = speed_wobble(grid.t, grid.n_paths, amplitude, period, seed=SEED + 41)
    report = diagnose(measured, replace(FAST, seed=SEED + 41))
    message = replay(f'speed wobble +-{amplitude:.2f} every {period:.2f} s: causes '
                     f'{[c.cause for c in report.causes]}, extensions '
                     f'{[e.family for e in report.extensions]}')
    assert not report.adequate, message
    assert report.unexplained and all(row.material for row in report.unexplained), message
    misfit = report.misfit        # where to look: which runs, which part of a run
    assert misfit is not None and len(misfit.worst_runs) == 5, message
    assert all(0 <= entry.run < 300 for entry in misfit.worst_runs), message
    assert all(entry.log_score <= misfit.median_log_score for entry in misfit.worst_runs)
    assert misfit.parts and abs(misfit.parts[0].z) > 3, message
    worst = misfit.parts[0]
    written = write_report(report, tmp_path, measured=measured)
    summary = written['summary'].read_text()
    assert 'not adequate' in summary and report.unexplained[0].statistic in summary, message
    assert written['misfit_plot'].stat().st_size > 10_000, message     # the pattern, drawn
    assert 'misfit.png draws the runs over time' in summary, message
    if report.causes or report.extensions:    # what was named is said to stand in, in part
        assert 'may stand in for part of it' in summary.splitlines()[2], message
    assert 'Where to look' in summary and worst.quantity in summary, message
    assert json.loads(written['report'].read_text())['misfit']['parts'][0]['quantity'] == \
        worst.quantity


@pytest.mark.parametrize('factor', [0.75, 1.3])
def test_the_per_stride_panels_span_one_stride_of_the_fitted_clock_either_side_of_a_change(
        factor):
    """extensions.png's speed and heading-rate curves: a window one stride long throughout."""
    parameters = om.ModelParameters.nominal()
    t = np.arange(0.0, 5.0, 0.01)
    model = FittedModel(parameters, (0.0, 0.0, 0.0), 1.0,
                        {'change_point': {'time_s': 2.0, 'speed_factor': factor}})
    starts, ends = stride_windows(model, t)
    span = np.interp(ends, np.arange(len(t)), t) - t[starts]
    stride = 1.0 / parameters.stride_frequency
    assert np.allclose(span[t[starts] + span <= 2.0], stride)           # before the change
    assert np.allclose(span[t[starts] >= 2.0], stride / factor)          # after it
    assert len(starts) and t[starts[-1]] + span[-1] <= t[-1]
    plain_starts, plain_ends = stride_windows(replace(model, effects={}), t)
    assert np.allclose(np.interp(plain_ends, np.arange(len(t)), t) - t[plain_starts], stride)


@seed(SEED)
@settings(max_examples=25, deadline=None, database=None)
@given(st.floats(1.5, 5.0), st.floats(0.0, 10.0), st.floats(-20.0, 20.0), st.floats(0.0, 1.0))
def test_misfit_png_s_turn_is_the_heading_over_a_whole_stride_without_its_sway(
        stride_hz, sway_deg, rate_deg_s, offset):
    """
    misfit.png's turn curves average a stride: what each run turns, not where its sway stands.

    Runs turning at their own rates with a sway of one cycle per stride (any phase and
    amplitude): over windows one stride long the mean turn since the first window is the mean
    rate times the time since that window, and its spread across runs the rates' spread
    times it.
    """
    dt = 0.002
    t = np.arange(0.0, 4.0, dt)
    rates = np.radians(rate_deg_s + np.array([-2.0, 0.0, 3.0]))
    phase = 2 * np.pi * (stride_hz * t + offset)
    heading = rates[:, None] * t + np.radians(sway_deg) * (np.sin(phase) - np.sin(phase[0]))
    poses = np.zeros((3, len(t), 3))
    poses[..., 2] = heading
    paths = om.Paths(t, poses)
    stride = 1.0 / (stride_hz * dt)                          # samples, fractional
    starts = np.arange(0, len(t) - int(stride) - 2, 7)
    ends = starts + stride
    since = (starts - starts[0]) * dt
    expected = np.degrees(rates.mean()) * since
    assert np.allclose(_mean_turn(paths, starts, ends), expected, atol=0.02)
    spread = np.degrees(rates.std(ddof=1)) * since
    assert np.allclose(_turn_spread(paths, starts, ends), spread, atol=0.02)


@pytest.mark.parametrize('leg, chosen', [(WORN_LEG, {}), (4, {'leg': 4})])
def test_a_worn_leg_strides_run_by_run_with_its_touchdown_angle_moved_by_the_run_s_place(
        leg, chosen):
    """
    studies/outside.leg_wear: run i at place q_i is the robot with phi_k + drift q_i.

    Each run is the model's own run of that geometry on the run's stream, so the first is the
    robot as it was and the last is the robot worn by the whole drift; phi3 by default.
    """
    robot = om.ModelParameters.nominal()
    drift = 7.5
    worn = leg_wear(9, drift, parameters=robot, seed=SEED, cycles=3, sigma1=0.1, sigma2=0.1,
                    **chosen)
    for run, place in ((0, 0.0), (4, 0.5), (8, 1.0)):
        angles = list(robot.touchdown_angles)
        angles[leg - 1] += math.radians(drift) * place
        stream = int(np.random.SeedSequence([SEED, run]).generate_state(1)[0])
        alone = om.simulate(1, seed=stream, cycles=3, sigma1=0.1, sigma2=0.1, parameters=replace(
            robot, touchdown_angles=tuple(angles)).with_paper_liftoff())
        assert np.array_equal(worn.poses[run], alone.poses[0]), (run, replay('leg wear'))
    with pytest.raises(ValueError, match='leg must be 1, 2, 3 or 4'):    # counted as terms are
        leg_wear(9, drift, parameters=robot, seed=SEED, leg=0)      # phi1's old 0-based index


def test_where_to_look_points_at_the_mean_that_every_run_moves_alike():
    """
    A speed that swings shows in the mean progress, a turn that grows in the heading change.

    Every run moves alike, which the spreads across runs do not show. Data made outside the
    model (studies/outside.py) against runs of the same robot without the effect.
    """
    rng = random.Random(SEED * 10 + 47)
    grid = om.simulate(300, seed=SEED + 47)
    model = om.simulate(300, seed=SEED + 48)
    amplitude, period = rng.uniform(0.2, 0.4), rng.uniform(1.2, 2.0)
    final = rng.choice([-1, 1]) * rng.uniform(3, 6)
    for measured, quantity, what in (
            (speed_wobble(grid.t, 300, amplitude, period, seed=SEED + 47), 'progress',
             f'speed wobble +-{amplitude:.2f} every {period:.2f} s'),
            (yaw_ramp(grid, final), 'heading change', f'yaw ramp to {final:.2f} deg/s')):
        parts = where_in_a_run(measured, model, np.random.default_rng(SEED))
        assert [part.statistic for part in parts] == ['mean', 'spread'], replay(f'{what}: {parts}')
        assert parts[0].quantity == quantity and abs(parts[0].z) > 5, replay(f'{what}: {parts}')
        words = Misfit((), 0.0, 0.0, 1.0, parts).words()
        assert f'the mean over the runs differs most in the {quantity}' in words[-2]
        assert 'spread across runs differs most' in words[-1]


@pytest.mark.long
def test_a_turn_that_grows_within_each_run_is_named_or_reported_by_the_statistic_showing_it(
        tmp_path):
    """
    A yaw ramp from outside the model (studies/outside.py) is never missed in silence.

    A ramp to 4-7 deg/s on 200 runs of Table II's robot: either the family is named and
    sized, or the report is not adequate with the heading rate's change among the statistics
    left off (suite seeds 1-16: 15 named, 1 flagged; 14 and 2 before that change was scored,
    features.py note (5); `benchmarks/bench_seed_sweep.py test/test_extensions.py -k
    turn_that_grows_within_each_run --base 891bdb0`). Smaller ramps can go unseen: drawn from
    2.5-6 deg/s, one of 20 seeds (-2.82 deg/s) was named nothing and called adequate. Before
    that statistic, 2 of 4 seeds of the test (no family then) called the paper's model
    adequate.
    """
    rng = random.Random(SEED * 10 + 43)
    final = rng.choice([-1.0, 1.0]) * rng.uniform(4.0, 7.0)
    measured = yaw_ramp(om.simulate(200, seed=SEED + 43), final)
    report = diagnose(measured, replace(FAST, seed=SEED + 43))
    message = replay(f'yaw rate rising to {final:.2f} deg/s: causes '
                     f'{[c.cause for c in report.causes]}, extensions '
                     f'{[(e.family, e.parameters) for e in report.extensions]}, unexplained '
                     f'{[(row.statistic, round(row.z, 1)) for row in report.unexplained]}; '
                     f'{evidence(report, "yaw_rate_ramp")}')
    named = [e for e in report.extensions if e.family == 'yaw_rate_ramp']
    if named:
        estimate = named[0].parameters['final_yaw_rate_deg_s']
        assert abs(estimate - final) <= 0.4 * abs(final), message
        written = write_report(report, tmp_path, measured=measured)   # the ramp's panel too
        assert written['extension_plot'].stat().st_size > 0, message
        return
    assert not report.adequate, message
    shown = [row for row in report.unexplained if row.statistic == HEADING_RATE_CHANGE]
    assert len(shown) == 1 and shown[0].material, message
    # the rate rises by `final` over the run: its halves differ by half of it
    assert shown[0].data == pytest.approx(final / 2, rel=0.4), message
    first = summary_text(report).splitlines()[2]
    if not report.causes and not report.extensions:
        assert "The paper's model does not explain these runs" in first, message


# the drifts (deg) the leg-wear tests hide, per leg: 1.3-2.6 times each leg's detection
# limit for 300 runs of Table II's robot (phi1 9.7-10.0, phi2 9.0-9.8, phi3 5.4-6.4, phi4
# 10.6-11.2 deg on the null data sets of seeds 5 and 6): a leg that shows in the distance
# alone (phi1, phi2) or in the turn alone (phi4) needs more wear to show than phi3, which
# moves both. phi4 no further: 47 deg on Table II, it turns the runs less past about 67, and
# backward past phi3 (39.9) hardly at all (bench_wear_range.py --turns). The limits were the
# reports' at the library's moment_runs, which the tests keep (hidden_effects.WEAR_SETTINGS)
WEAR_DEG = {1: (16.0, 20.0), 2: (16.0, 20.0), 3: (10.0, 14.0), 4: (15.0, 18.0)}


def draw_wear(rng: random.Random) -> tuple[int, float]:
    """Draw a worn leg (1-4) and its drift over the session, either sign (WEAR_DEG)."""
    leg = rng.randint(1, 4)
    return leg, rng.choice([-1.0, 1.0]) * rng.uniform(*WEAR_DEG[leg])


@pytest.mark.long
def test_a_leg_that_wears_over_the_session_is_named_as_its_drifting_touchdown_angle():
    """
    A worn leg from outside the library (studies/outside.leg_wear) is named and sized.

    Any of the four legs' touchdown angles moving by about twice its detection limit from
    the first of 300 runs of Table II's robot to the last (WEAR_DEG), made run by run with
    the model's own runs of each geometry (not the family's code): that leg's drift is named,
    no other, its change within 40 % (phi4 worn forward: backward it passes phi3, the next
    test). Before the family had a term per leg only phi3's
    was named; before it had any, this test required only that nothing was missed in silence
    (suite seeds 1-12: a yaw-rate or sideways drift named on 4, nothing on 8).
    """
    rng = random.Random(SEED * 10 + 53)
    leg, drift = draw_wear(rng)
    if leg == 4:        # past phi3 the left pair stops turning the robot: the next test
        drift = abs(drift)
    measured = leg_wear(300, drift, parameters=om.ModelParameters.nominal(), seed=SEED + 53,
                        leg=leg)
    report = diagnose(measured, replace(WEAR_SETTINGS, seed=SEED + 53))
    left = [(row.statistic, round(row.z, 1)) for row in report.unexplained]
    message = replay(f'phi{leg} drifting by {drift:.1f} deg: named {list(report.named_terms)}, '
                     f'unexplained {left}; {evidence(report, "run_order_drift")}')
    worn = named_touchdown_drift(report, leg, drift, message)
    assert 'a leg that wears' in worn.description, message


@pytest.mark.long
def test_a_front_left_leg_worn_past_its_partner_is_never_missed_in_silence():
    """
    phi4 worn below phi3 (Table II: 47.0 against 39.9 deg) is named as phi4 or reported off.

    There the left pair's liftoff changes legs and the pair hardly turns the robot any more
    (bench_wear_range.py --turns): the wear shows in the forward distance alone and its
    reading is short, by a seed's luck (suite seed 143911, -15.8 deg: read -11.2 with these
    settings as with the defaults, the truth outside its interval; -8.2 and not named with
    FAST's fewer moment runs). What must hold: no other term named, and phi4's drift named or
    the model reported not adequate.
    """
    drift = -random.Random(SEED * 10 + 59).uniform(*WEAR_DEG[4])
    measured = leg_wear(300, drift, parameters=om.ModelParameters.nominal(), seed=SEED + 59,
                        leg=4)
    report = diagnose(measured, replace(WEAR_SETTINGS, seed=SEED + 59))
    left = [(row.statistic, round(row.z, 1)) for row in report.unexplained]
    message = replay(f'phi4 drifting by {drift:.1f} deg: named {list(report.named_terms)}, '
                     f'unexplained {left}; {evidence(report, "run_order_drift")}')
    assert set(report.named_terms) <= {drift_term('touchdown_angle_4')}, message
    assert report.named_terms or not report.adequate, message


@pytest.mark.long
def test_a_touchdown_angle_drift_hidden_in_data_from_a_random_robot_is_named_and_sized():
    """The family's own drift of any leg on a robot near Table II: named, within 40 %."""
    rng = random.Random(SEED * 100 + 71)
    robot, cycles, scale = random_robot(rng)
    leg, change = draw_wear(rng)
    extensions = {'run_order_drift': {'parameter': f'touchdown_angle_{leg}',
                                      'change': round(change, 3)}}
    sigma1, sigma2 = om.model.nominal_sigmas()
    measured = om.simulate(300, seed=SEED + 71, cycles=cycles, parameters=robot,
                           sigma1=sigma1 * scale, sigma2=sigma2 * scale, extensions=extensions)
    report = diagnose(measured, replace(WEAR_SETTINGS, seed=SEED + 71))
    case = f'{extensions}, robot {robot.table()}, {cycles} cycles, spread x{scale:.2f}'
    message = (f'{replay(case)}: named {list(report.named_terms)}; '
               f'{evidence(report, "run_order_drift")}')
    named_touchdown_drift(report, leg, change, message)


def named_touchdown_drift(report, leg: int, truth: float, message: str):
    """Check leg's touchdown drift alone named, its change within 40 % of `truth`."""
    worn = [e for e in report.extensions if e.term == drift_term(f'touchdown_angle_{leg}')]
    assert len(worn) == 1 and len(report.extensions) == 1 and not report.causes, message
    estimate = worn[0].parameters['change']
    assert abs(estimate - truth) <= 0.4 * abs(truth), message
    low, high = worn[0].interval['change']
    assert low < estimate < high, message
    assert f'(phi{leg})' in worn[0].description, message
    return worn[0]


@pytest.mark.long
def test_the_report_says_each_extension_in_words_with_its_evidence(tmp_path):
    measured = om.simulate(160, seed=5, cycles=8, extensions={'change_point': {
        'time_s': 2.0, 'speed_factor': 0.75}})
    report = diagnose(measured, replace(FAST, seed=5))
    written = write_report(report, tmp_path, measured=measured)
    loaded = json.loads(written['report'].read_text())
    assert [e['family'] for e in loaded['extensions']] == ['change_point']
    extension = loaded['extensions'][0]
    assert set(extension) >= {'family', 'parameters', 'interval', 'gain', 'p_value',
                              'description'}
    assert extension['parameters']['speed_factor'] == pytest.approx(0.75, abs=0.03)
    low, high = extension['interval']['time_s']
    assert low - 0.05 < 2.0 < high + 0.05 and extension['gain'] > 0
    assert loaded['causes'] == [] and loaded['cause'] == 'none'
    assert {c['family'] for c in loaded['extension_candidates']} == set(HIDDEN)
    summary = written['summary'].read_text()
    first = summary.splitlines()[2]
    assert first.startswith('**Conclusion:**') and 'change_point' in first
    assert 'Beyond the table of causes' in summary and extension['description'] in summary
    assert (tmp_path / 'extensions.png').stat().st_size > 10_000
