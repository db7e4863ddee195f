"""
The nominal fit (eq. 9): the deterministic model closest to the average measured path.

Runs made by the model itself with known, perturbed parameters must be fitted back exactly;
the start pose is the measured mean start pose; the stride-frequency start value comes from
the spectrum of the average speed.
"""
from __future__ import annotations

from dataclasses import replace
import math
import os
import warnings

from hypothesis import given, seed, settings, strategies as st
import numpy as np
import pytest

import octoroach_model as om
from octoroach_model.errors import DataError
from octoroach_model.fitting import fit_nominal, mean_start_pose
from octoroach_model.fitting.nominal import stride_frequency_guess

NOMINAL = om.ModelParameters.nominal()
TOUCHDOWN_OFFSETS_DEG = (2.0, -3.0, 1.5, -2.0)
TRUE_START = (0.01, -0.02, math.radians(80.0))


def perturbed_parameters() -> om.ModelParameters:
    """Table II moved: legs 2.4 cm, touchdown angles a few degrees off, 2.3 Hz, eqs. 7-8."""
    touchdown = tuple(angle + math.radians(offset)
                      for angle, offset in zip(NOMINAL.touchdown_angles, TOUCHDOWN_OFFSETS_DEG))
    return replace(NOMINAL, leg_length=0.024, touchdown_angles=touchdown,
                   stride_frequency=2.3).with_paper_liftoff()


def deterministic_runs(parameters: om.ModelParameters, cycles: float) -> om.Paths:
    """
    Two runs of the deterministic model whose average is exactly the model path.

    The runs are shifted by opposite offsets and their recorded headings turned by opposite
    angles, so the mean start pose is TRUE_START while no single run starts there.
    """
    path = om.simulate(1, seed=0, sigma1=0.0, sigma2=0.0, parameters=parameters,
                       start_pose=TRUE_START, cycles=cycles)
    offset = np.array([0.01, -0.005, 0.1])
    poses = np.stack([path.poses[0] + offset, path.poses[0] - offset])
    return om.Paths(path.t, poses)


@pytest.fixture(scope='module', params=[6, 10], ids=['6_cycles', '10_cycles'])
def recovery(request):
    truth = perturbed_parameters()
    measured = deterministic_runs(truth, request.param)
    return truth, measured, fit_nominal(measured)


def test_the_fit_recovers_leg_length_touchdown_angles_and_stride_frequency(recovery):
    truth, _, fit = recovery
    fitted = fit.parameters
    assert fitted.leg_length == pytest.approx(truth.leg_length, rel=1e-6)
    np.testing.assert_allclose(np.degrees(fitted.touchdown_angles),
                               np.degrees(truth.touchdown_angles), rtol=1e-6)
    assert fitted.stride_frequency == pytest.approx(truth.stride_frequency, rel=1e-6)
    assert fitted.hip_distance == NOMINAL.hip_distance


def test_the_fitted_liftoff_angles_follow_eqs_7_and_8(recovery):
    _, _, fit = recovery
    touchdown = fit.parameters.touchdown_angles
    assert fit.parameters.liftoff_angles == (-min(touchdown[0], touchdown[1]),
                                             -min(touchdown[2], touchdown[3]))


def test_the_fit_of_deterministic_model_runs_leaves_no_error(recovery):
    _, measured, fit = recovery
    assert fit.rms_error_m < 1e-8
    np.testing.assert_allclose(fit.average_path, measured.positions.mean(axis=0))


def test_the_fit_starts_the_model_at_the_mean_measured_start_pose(recovery):
    _, measured, fit = recovery
    np.testing.assert_allclose(fit.start_pose, mean_start_pose(measured), atol=1e-12)
    np.testing.assert_allclose(fit.start_pose, TRUE_START, atol=1e-12)


def test_the_fit_report_is_in_the_papers_units(recovery):
    _, _, fit = recovery
    report = fit.report()
    assert report['leg_length_cm'] == pytest.approx(fit.parameters.leg_length * 100)
    np.testing.assert_allclose(report['touchdown_angles_deg'],
                               np.degrees(fit.parameters.touchdown_angles))
    assert report['stride_frequency_hz'] == fit.parameters.stride_frequency
    assert report['start_pose']['heading_deg'] == pytest.approx(80.0, abs=1e-9)
    assert report['start_pose']['x_cm'] == pytest.approx(1.0, abs=1e-9)
    assert report['rms_error_cm'] == pytest.approx(fit.rms_error_m * 100)


def test_the_mean_start_pose_averages_x_and_y_and_takes_the_circular_mean_of_the_heading():
    t = np.arange(3) / 50.0
    first = np.array([[0.01, 0.02, math.pi - 0.1],
                      [0.03, -0.04, -math.pi + 0.1],
                      [-0.01, 0.05, math.pi - 0.05],
                      [0.05, 0.01, -math.pi + 0.05]])
    poses = np.repeat(first[:, None, :], len(t), axis=1)
    x, y, heading = mean_start_pose(om.Paths(t, poses))
    assert x == pytest.approx(0.02)
    assert y == pytest.approx(0.01)
    # the arithmetic mean of these headings is 0; the circular mean is pi (backwards)
    assert abs(math.remainder(heading - math.pi, 2 * math.pi)) < 1e-12


def test_the_mean_start_pose_of_runs_with_initial_pose_error_is_near_the_nominal_start():
    runs = om.simulate(400, seed=4, cycles=1, effects={
        'initial_pose_error': {'heading_std_deg': 5.0, 'position_std_cm': 0.5}})
    x, y, heading = mean_start_pose(runs)
    assert abs(x) < 0.001 and abs(y) < 0.001            # 0.5 cm / sqrt(400) = 0.25 mm
    assert heading == pytest.approx(math.pi / 2, abs=math.radians(1.0))
    expected = runs.poses[:, 0]
    assert x == pytest.approx(expected[:, 0].mean())
    assert y == pytest.approx(expected[:, 1].mean())


@pytest.mark.parametrize('frequency', [1.5, 2.0, 2.17, 2.3, 3.1])
def test_the_stride_frequency_guess_lies_within_half_a_spectral_bin_of_the_truth(frequency):
    t = np.arange(251) / 50.0                      # 5 s, not a whole number of cycles
    runs = om.simulate(40, seed=2, t=t,
                       parameters=replace(NOMINAL, stride_frequency=frequency))
    guess = stride_frequency_guess(runs.positions.mean(axis=0), t, fallback=9.0)
    half_bin = 0.5 / (len(t) * 0.02) / 2           # speed bin, halved (two stances a cycle)
    assert abs(guess - frequency) <= half_bin


def test_the_stride_frequency_guess_falls_back_on_runs_too_short_for_a_spectrum():
    t = np.arange(10) / 50.0
    runs = om.simulate(3, seed=2, t=t)
    assert stride_frequency_guess(runs.positions.mean(axis=0), t, fallback=1.7) == 1.7


def test_the_fit_refuses_runs_of_fewer_than_three_samples():
    t = np.arange(2) / 50.0
    with pytest.raises(DataError, match='three samples'):
        fit_nominal(om.simulate(3, seed=1, t=t))


def test_the_fit_refuses_a_non_finite_average_path():
    runs = om.simulate(3, seed=1, cycles=1)
    poses = runs.poses.copy()
    poses[1, 5, 0] = np.nan
    with pytest.raises(DataError, match='not finite inside a run'):
        fit_nominal(om.Paths(runs.t, poses))


def test_the_gait_target_reads_simulated_runs_as_the_features_read_the_data():
    """
    The geometry fit compares like with like.

    The gait target's five means (sway, stride frequency, heading to travel angle) of the
    data's own runs, read as simulated runs are read (cut to the same lengths, the angle over
    the same window), are the data's values.
    """
    from octoroach_model.diagnosis.modelfit import RunData

    robot = replace(om.ModelParameters.nominal(),
                    touchdown_angles=(0.80, 0.92, 0.72, 0.64)).with_paper_liftoff()
    runs = om.simulate(40, seed=5, cycles=6, parameters=robot,
                       effects={'lateral_slip': {'velocity_cm_s': 1.5}})
    poses = runs.poses.copy()
    poses[::3, -40:] = np.nan                       # a third of the runs end early
    data = RunData(om.Paths(runs.t, poses), robot.stride_frequency, math.pi / 2)
    target = data.gait
    read = np.nanmean(target.of_runs(poses, robot.stride_frequency), axis=0)
    assert read == pytest.approx(np.asarray(target.values), rel=1e-9, abs=1e-12)
    assert abs(target.values[4]) > math.radians(0.5)   # the slip shows in the angle


def test_a_gait_target_without_its_standard_errors_is_refused_at_once():
    """
    A gait target's stride frequency (Hz) and angles share no unit with the path's cm.

    It is matched in the data's standard errors only; without them the fit used to fail
    deep inside least squares with numpy's broadcasting message (five gaps, three weights).
    """
    from octoroach_model.diagnosis.modelfit import RunData
    from octoroach_model.fitting.nominal import MeanPathSettings
    from octoroach_model.fitting.target import residual_vector

    runs = om.simulate(40, seed=5, cycles=4)
    data = RunData(runs, 2.0, math.pi / 2)
    sigmas = om.model.nominal_sigmas()
    with pytest.raises(ValueError, match='give scales too'):
        MeanPathSettings(sigmas, 40, 1, gait=data.gait)
    assert MeanPathSettings(sigmas, 40, 1, gait=data.gait, scales=data.scales).gait is not None
    with pytest.raises(ValueError, match='matched in standard errors'):
        residual_vector(np.zeros((3, 2)), None, np.zeros(5), 0.13, None)
    assert residual_vector(np.zeros((3, 2)), np.zeros(3), None, 0.13, None).shape == (9,)


def test_runs_with_every_sample_read_bit_for_bit_as_through_the_masked_path():
    # whole runs skip the masks (gait.py's fast paths, the nominal fit's hot loop); a run
    # that ends early beside them sends every run through the masked form, which must give
    # the whole runs' features to the last bit
    from octoroach_model.fitting.gait import detrended, gait_features, stride_samples
    paths = om.simulate(12, seed=3, cycles=6)
    t, poses = paths.t, paths.poses
    short = poses[:1].copy()
    short[:, len(t) // 2:] = np.nan
    both = np.concatenate([poses, short])
    cycle = stride_samples(om.ModelParameters.nominal().stride_frequency, float(t[1] - t[0]))
    guess = om.ModelParameters.nominal().stride_frequency
    whole = gait_features(t, poses[..., :2], poses[..., 2], guess, cycle)
    masked = gait_features(t, both[..., :2], both[..., 2], guess, cycle)[:-1]
    assert np.array_equal(whole, masked)
    assert np.array_equal(detrended(poses[..., 2], t), detrended(both[..., 2], t)[:-1])
    assert np.isfinite(masked).all()
    from octoroach_model.diagnosis.features import _slope      # the heading rate's line
    assert np.array_equal(_slope(poses[..., 2], t), _slope(both[..., 2], t)[:-1])


SUITE_SEED = int(os.environ.get('OCTOROACH_TEST_SEED', '0'))   # pytest's header prints it


# The bootstrap resamples of the runs are taken all at once (a product of multiplicities and
# the runs, not a copy per resample), and the change point's step at every time and every
# resample at once (prefix sums): checked against the definitions, one resample and one time
# at a time, on arrays Hypothesis draws (runs that end early leave NaN behind them).
@st.composite
def rows_with_ends(draw) -> np.ndarray:
    runs, cycles = draw(st.integers(1, 30)), draw(st.integers(1, 60))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    rows = 0.05 * (1.0 + draw(st.floats(0.0, 0.3)) * rng.standard_normal((runs, cycles)))
    if draw(st.booleans()):                 # a step in speed, anywhere (the first cycles too)
        rows[:, draw(st.integers(0, cycles - 1)):] *= draw(st.floats(0.3, 2.0))
    ends = rng.integers(0, cycles + 1, runs) if draw(st.booleans()) else np.full(runs, cycles)
    for run, end in enumerate(ends):
        rows[run, end:] = np.nan
    return rows


def steps_by_definition(ratio, middle, duration, time_s=None) -> dict[float, tuple]:
    """Each allowed step time's (cost, factor), one time at a time."""
    usable = np.isfinite(ratio)
    ratio, middle = ratio[usable], middle[usable]
    steps = {}
    for time in (np.linspace(0.1, 0.9, 33) * duration if time_s is None else [time_s]):
        after = middle >= time
        if after.sum() < 2 or (~after).sum() < 2:
            continue
        first, second = np.mean(ratio[~after]), np.mean(ratio[after])
        if first > 0:
            steps[float(time)] = (np.sum((ratio[~after] - first) ** 2)
                                  + np.sum((ratio[after] - second) ** 2), second / first)
    return steps


def assert_best_step(found, steps, duration, time_s) -> None:
    """`found` is a step of least cost (ties within rounding either way), else the default."""
    if not steps:
        assert found == (0.5 * duration if time_s is None else time_s, 1.0)
        return
    least = min(cost for cost, _ in steps.values())
    [(cost, factor)] = [value for time, value in steps.items()
                        if time == pytest.approx(found[0], rel=1e-12)]
    assert cost <= least + 1e-9 * max(least, 1e-12), (found, steps)
    assert found[1] == pytest.approx(factor, rel=1e-9)


def mean_of_runs(rows):
    with np.errstate(invalid='ignore'), warnings.catch_warnings():
        warnings.simplefilter('ignore', RuntimeWarning)     # all-NaN columns: NaN, as wanted
        return np.nanmean(rows, axis=0)


@seed(SUITE_SEED)
@settings(max_examples=60, deadline=None, database=None)
@given(rows_with_ends(), st.integers(0, 5), st.booleans(), st.integers(0, 1000))
def test_resamples_and_steps_taken_at_once_are_those_taken_one_at_a_time(rows, n_boot, held,
                                                                         draw_seed):
    from octoroach_model.diagnosis.modelfit import SpeedRatio
    from octoroach_model.fitting.covariance import resample_weights, resampled_means

    runs, cycles = rows.shape
    picks = np.random.default_rng(draw_seed).integers(0, runs, runs)
    weights = resample_weights(np.random.default_rng(draw_seed), runs, 1)
    assert np.array_equal(weights[0], np.bincount(picks, minlength=runs))
    np.testing.assert_allclose(resampled_means(weights, rows)[0], mean_of_runs(rows[picks]),
                               rtol=1e-12, atol=1e-15, equal_nan=True)

    speed = np.full(cycles, 0.05)
    middle = 0.02 * np.arange(cycles) + 0.01
    duration = 0.02 * cycles
    time_s = float(middle[cycles // 2]) if held else None
    ratio = SpeedRatio(speed, middle, 1, duration)
    assert_best_step(ratio.step(rows, time_s),
                     steps_by_definition(mean_of_runs(rows) / speed, middle, duration, time_s),
                     duration, time_s)
    # the bootstrap's resamples, drawn one after the other from the same generator
    rng = np.random.default_rng(draw_seed)
    resamples = [rows[rng.integers(0, runs, runs)] for _ in range(n_boot)]
    times, factors = ratio.steps(rows, resample_weights(np.random.default_rng(draw_seed), runs,
                                                        n_boot), time_s)
    for resample, time, factor in zip(resamples, times, factors):
        assert_best_step((time, factor), steps_by_definition(
            mean_of_runs(resample) / speed, middle, duration, time_s), duration, time_s)


@st.composite
def poses_with_ends(draw) -> np.ndarray:
    """(n, T, 3) random-walk poses of runs that may end early (NaN after their end)."""
    runs, samples = draw(st.integers(1, 12)), draw(st.integers(20, 90))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    poses = np.cumsum(0.01 * rng.standard_normal((runs, samples, 3)), axis=1)
    if draw(st.booleans()):
        for run, end in enumerate(rng.integers(10, samples + 1, runs)):
            poses[run, end:] = np.nan
    return poses


@seed(SUITE_SEED)
@settings(max_examples=60, deadline=None, database=None)
@given(poses_with_ends(), st.integers(1, 6))
def test_positions_taken_a_coordinate_at_a_time_are_the_numbers_of_xy_pairs(poses, cycle):
    """Each coordinate apart: bit for bit the (x, y) pair arithmetic it stands for."""
    from octoroach_model.diagnosis.features import INDEX, RESOLUTION_NOISE_M2, run_features
    from octoroach_model.fitting.gait import cycle_distances
    from octoroach_model.model.effects import add_to_positions

    xy = poses[..., :2]
    np.testing.assert_array_equal(cycle_distances(xy, cycle),
                                  np.linalg.norm(xy[:, cycle:] - xy[:, :-cycle], axis=-1))
    # the noise feature: the median of both coordinates' squared fourth differences together
    fourth = np.diff(xy, n=4, axis=1) ** 2
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', RuntimeWarning)
        median = np.nanmedian(fourth.reshape(len(poses), -1), axis=1) \
            if np.isnan(poses).any() else np.median(fourth, axis=(1, 2))
        features = run_features(om.Paths(0.01 * np.arange(poses.shape[1]), poses), 2.0, 0.0)
    np.testing.assert_array_equal(features[:, INDEX['log_noise']],
                                  np.log(np.nan_to_num(median, nan=0.0) + RESOLUTION_NOISE_M2))
    offsets = np.random.default_rng(cycle).standard_normal((len(poses), poses.shape[1], 2))
    for offset in (offsets, offsets[:, :1]):            # one per sample, or one per run
        moved = poses.copy()
        add_to_positions(moved, offset)
        np.testing.assert_array_equal(moved[..., :2], poses[..., :2] + offset)
        np.testing.assert_array_equal(moved[..., 2], poses[..., 2])
