"""
The effects of the table of causes (docs/causes.md), each against its definition.

Every check compares a run with an effect to the plain run of the same seed: the angle draws
are the same by design (common random numbers), so the difference is the effect alone.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

import octoroach_model as om

N = 2000
SEED = 21
DETERMINISTIC = {'sigma1': 0.0, 'sigma2': 0.0}


def within_sampling_error(estimate_std, true_std, n, sigmas=4.0):
    """|sample std / true std - 1| within `sigmas` standard errors (1 / sqrt(2 (n - 1)))."""
    return abs(estimate_std / true_std - 1.0) < sigmas / math.sqrt(2.0 * (n - 1))


def path_length(poses):
    return np.hypot(*np.diff(poses[..., :2], axis=-2).transpose(2, 0, 1)).sum(axis=-1)


@pytest.fixture(scope='module')
def plain():
    return om.simulate(N, seed=SEED)


def test_initial_pose_error_rotates_each_run_about_its_start_and_shifts_it(plain):
    effect = om.simulate(N, seed=SEED, effects={'initial_pose_error': {
        'heading_std_deg': 5.0, 'position_std_cm': 1.0}})
    turn = effect.poses[..., 2] - plain.poses[..., 2]
    np.testing.assert_allclose(turn, turn[:, :1] * np.ones(turn.shape[1]), rtol=0, atol=1e-12)
    angle = turn[:, 0]
    start = plain.poses[:, :1, :2]
    shift = effect.poses[:, 0, :2] - plain.poses[:, 0, :2]
    rel = plain.poses[..., :2] - start
    cos_a, sin_a = np.cos(angle)[:, None], np.sin(angle)[:, None]
    expected = start + shift[:, None] + np.stack(
        [cos_a * rel[..., 0] - sin_a * rel[..., 1], sin_a * rel[..., 0] + cos_a * rel[..., 1]],
        axis=-1)
    np.testing.assert_allclose(effect.poses[..., :2], expected, rtol=0, atol=1e-12)
    assert within_sampling_error(angle.std(), math.radians(5.0), N)
    assert abs(angle.mean()) < 4 * math.radians(5.0) / math.sqrt(N)
    for axis in (0, 1):
        assert within_sampling_error(shift[:, axis].std(), 0.01, N)
    assert abs(np.corrcoef(angle, shift[:, 0])[0, 1]) < 0.1


def test_measurement_noise_adds_independent_noise_to_positions_only(plain):
    effect = om.simulate(N, seed=SEED, effects={'measurement_noise': {'position_std_cm': 0.5}})
    np.testing.assert_array_equal(effect.poses[..., 2], plain.poses[..., 2])
    noise = effect.poses[..., :2] - plain.poses[..., :2]
    for axis in (0, 1):
        values = noise[..., axis]
        assert within_sampling_error(values.std(), 0.005, values.size)
        assert abs(values.mean()) < 4 * 0.005 / math.sqrt(values.size)
        # independent across time: lag-1 autocorrelation within a run near 0
        lag1 = np.mean(values[:, 1:] * values[:, :-1]) / values.var()
        assert abs(lag1) < 4 / math.sqrt(values.size)
    assert abs(np.corrcoef(noise[..., 0].ravel(), noise[..., 1].ravel())[0, 1]) < 0.01


@pytest.mark.parametrize('effects', [
    {'measurement_noise': {'position_std_cm': 0.5}},
    {'initial_pose_error': {'heading_std_deg': 5.0, 'position_std_cm': 1.0},
     'measurement_noise': {'position_std_cm': 0.5}},
    {'persistent_turning': {'yaw_rate_std_deg_s': 5.0}},
    {'lateral_slip': {'velocity_cm_s': 2.0}, 'measurement_noise': {'position_std_cm': 0.5}}])
def test_the_poses_effects_are_applied_to_are_left_as_they_were(plain, effects):
    """apply_pose_effects writes its effects on a new array (noise alone on a copy)."""
    from octoroach_model.model.effects import apply_pose_effects, check_effects
    from octoroach_model.model.simulate import RandomStreams

    poses = plain.poses[:50].copy()
    moved = apply_pose_effects(poses, plain.t, check_effects(effects), RandomStreams(1).effects)
    np.testing.assert_array_equal(poses, plain.poses[:50])
    assert not np.shares_memory(moved, poses)
    assert np.abs(moved[..., :2] - poses[..., :2]).max() > 1e-4


def test_adding_an_effect_leaves_the_angle_draws_unchanged(plain):
    # Same seed with and without effects of zero size: the very same runs.
    for effects in ({'measurement_noise': {'position_std_cm': 0.0}},
                    {'persistent_turning': {'yaw_rate_std_deg_s': 0.0}},
                    {'initial_pose_error': {'heading_std_deg': 0.0, 'position_std_cm': 0.0}},
                    {'gait_frequency_variation': {'relative_std': 0.0}},
                    {'speed_decay': {'fraction': 0.0}},
                    {'lateral_slip': {'velocity_cm_s': 0.0}}):
        effect = om.simulate(200, seed=SEED, effects=effects)
        np.testing.assert_allclose(effect.poses, plain.poses[:200], rtol=0, atol=1e-12,
                                   err_msg=str(effects))
    # and with noise switched on, the difference is the noise alone: the noise of one
    # effect's stream, identical whatever else is asked for
    noisy = om.simulate(200, seed=SEED, effects={'measurement_noise': {'position_std_cm': 1.0}})
    both = om.simulate(200, seed=SEED, effects={
        'measurement_noise': {'position_std_cm': 1.0},
        'persistent_turning': {'yaw_rate_std_deg_s': 0.0}})
    np.testing.assert_allclose(both.poses, noisy.poses, rtol=0, atol=1e-12)


def deterministic_at(times):
    """Sample the deterministic (Table II) model at the given times: (len(times), 3)."""
    return om.simulate(1, seed=0, t=np.asarray(times, dtype=float), **DETERMINISTIC).poses[0]


def test_gait_frequency_variation_stretches_time_per_run():
    effect = om.simulate(N, seed=SEED, effects={'gait_frequency_variation': {
        'relative_std': 0.1}}, **DETERMINISTIC)
    t = effect.t
    duration = t[-1]
    # Undo the stretch of a few runs exactly: the deterministic y(t) increases with t.
    for run in effect.poses[:5]:
        stretch = brentq(lambda s, run=run: deterministic_at([s * duration])[0, 1] - run[-1, 1],
                         0.5, 1.5, xtol=1e-14)
        np.testing.assert_allclose(run, deterministic_at(stretch * t), rtol=0, atol=1e-9)
    # The stretch of every run, from its final progress on a fine grid of the plain model.
    fine = np.linspace(0.0, 1.6 * duration, 4001)
    progress = deterministic_at(fine)[:, 1]
    assert np.all(np.diff(progress) > 0)
    stretch = np.interp(effect.poses[:, -1, 1], progress, fine) / duration
    assert within_sampling_error(stretch.std(), 0.1, N)
    assert abs(stretch.mean() - 1.0) < 4 * 0.1 / math.sqrt(N)
    # final progress then varies by about relative_std of its mean
    final_y = effect.poses[:, -1, 1]
    assert final_y.std() / final_y.mean() == pytest.approx(0.1, rel=0.2)


def test_gait_frequency_variation_of_zero_is_the_plain_model(plain):
    effect = om.simulate(N, seed=SEED, effects={'gait_frequency_variation': {
        'relative_std': 0.0}})
    np.testing.assert_allclose(effect.poses, plain.poses, rtol=0, atol=1e-12)


@pytest.mark.parametrize('fraction', [0.3, -0.3])
@pytest.mark.parametrize('draws', ['run', 'stance'])
def test_speed_decay_is_the_plain_model_at_warped_times(fraction, draws):
    effect = om.simulate(50, seed=SEED, draws=draws, effects={'speed_decay': {
        'fraction': fraction}})
    t = effect.t
    warped = t - fraction * t ** 2 / (2 * t[-1])
    plain_warped = om.simulate(50, seed=SEED, draws=draws, t=warped)
    np.testing.assert_allclose(effect.poses, plain_warped.poses, rtol=0, atol=1e-12)
    # deterministic: slower at the end, so less progress than the plain model
    decayed = om.simulate(1, seed=0, effects={'speed_decay': {'fraction': fraction}},
                          **DETERMINISTIC).poses[0]
    plain_end = deterministic_at(t)[-1, 1]
    assert np.sign(plain_end - decayed[-1, 1]) == np.sign(fraction)
    np.testing.assert_allclose(decayed, deterministic_at(warped), rtol=0, atol=1e-12)


@pytest.mark.parametrize('fraction', [0.4, 0.1, -0.3])
def test_a_decaying_run_shows_strides_at_the_mean_gait_rate(fraction):
    from octoroach_model.model.effects import mean_gait_rate
    from octoroach_model.fitting.gait import heading_sway

    effects = {'speed_decay': {'fraction': fraction}}
    runs = om.simulate(1, seed=0, cycles=12, effects=effects, **DETERMINISTIC)
    seen, _ = heading_sway(runs.poses[..., 2], runs.t, 2.0)
    stride_frequency = om.ModelParameters.nominal().stride_frequency
    assert seen[0] == pytest.approx(stride_frequency * mean_gait_rate(effects), rel=0.02)
    assert mean_gait_rate({}) == 1.0


def test_custom_times_only_choose_where_the_model_is_sampled():
    runs = om.simulate(20, seed=SEED)
    rng = np.random.default_rng(0)
    picked = np.sort(rng.choice(len(runs.t), 40, replace=False))
    sampled = om.simulate(20, seed=SEED, t=runs.t[picked])
    np.testing.assert_allclose(sampled.poses, runs.poses[:, picked], rtol=0, atol=1e-12)


@pytest.mark.parametrize('velocity_cm_s', [2.0, -3.0])
def test_lateral_slip_drifts_along_the_body_right_axis(velocity_cm_s):
    effect = om.simulate(1, seed=0, effects={'lateral_slip': {
        'velocity_cm_s': velocity_cm_s}}, **DETERMINISTIC).poses[0]
    plain = deterministic_at(om.simulate(1, seed=0).t)
    t = om.simulate(1, seed=0).t
    np.testing.assert_array_equal(effect[:, 2], plain[:, 2])
    drift = effect[:, :2] - plain[:, :2]
    # v * integral_0^t r(theta(s)) ds with r = (sin theta, -cos theta), on a 20x finer grid
    fine = np.linspace(0.0, t[-1], 20 * (len(t) - 1) + 1)
    heading = deterministic_at(fine)[:, 2]
    right = np.stack([np.sin(heading), -np.cos(heading)], axis=1)
    integral = np.concatenate([[[0.0, 0.0]], np.cumsum(
        0.5 * (right[1:] + right[:-1]) * np.diff(fine)[:, None], axis=0)])
    expected = velocity_cm_s / 100 * integral[::20]
    # The effect integrates on the run's own 50 Hz samples (trapezoid rule): within a stance
    # the heading swings, so that rule is off by about 1e-4 of the drift.
    np.testing.assert_allclose(drift, expected, rtol=0,
                               atol=5e-4 * abs(velocity_cm_s) / 100 * t[-1])
    # heading near pi/2: positive velocity moves the robot to its right, +x
    assert np.sign(drift[-1, 0]) == np.sign(velocity_cm_s)
    assert abs(drift[-1, 0]) == pytest.approx(abs(velocity_cm_s) / 100 * t[-1], rel=0.05)
    assert abs(drift[-1, 1]) < 0.2 * abs(drift[-1, 0])


def test_persistent_turning_adds_a_constant_yaw_rate_per_run(plain):
    effect = om.simulate(N, seed=SEED, effects={'persistent_turning': {
        'yaw_rate_std_deg_s': 10.0}})
    t = effect.t
    extra = effect.poses[..., 2] - plain.poses[..., 2]
    rate = extra[:, -1] / t[-1]
    np.testing.assert_allclose(extra, rate[:, None] * t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(effect.poses[:, 0], plain.poses[:, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(path_length(effect.poses), path_length(plain.poses), rtol=1e-6)
    assert within_sampling_error(rate.std(), math.radians(10.0), N)
    # each step is the plain step turned by the extra heading at mid-step
    steps = np.diff(effect.poses[..., :2], axis=1)
    plain_steps = np.diff(plain.poses[..., :2], axis=1)
    mid = rate[:, None] * 0.5 * (t[1:] + t[:-1])
    np.testing.assert_allclose(
        steps[..., 0], np.cos(mid) * plain_steps[..., 0] - np.sin(mid) * plain_steps[..., 1],
        rtol=0, atol=1e-12)
    # turning left (w > 0) ends further left (-x) than the plain run
    final_offset = effect.poses[:, -1, 0] - plain.poses[:, -1, 0]
    assert np.corrcoef(rate, final_offset)[0, 1] < -0.9
