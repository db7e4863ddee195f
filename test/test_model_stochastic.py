"""The stochastic model (docs/model.md, eq. 11) through the Python API `om.simulate`."""
from __future__ import annotations

import math

import numpy as np
import pytest

import octoroach_model as om
from octoroach_model.errors import ParameterError
from octoroach_model.model import kinematics
from octoroach_model.model.parameters import ModelParameters

PARAMETERS = ModelParameters.nominal()
SWITCHES = np.arange(21) / (2 * PARAMETERS.stride_frequency)   # t of every stance switch


def stance_steps(poses):
    """(n, S, 3) motion of each stance in the body frame at its touchdown: dx, dy, dheading."""
    delta = np.diff(poses, axis=1)
    rotation = -(poses[:, :-1, 2] - math.pi / 2)
    cos_r, sin_r = np.cos(rotation), np.sin(rotation)
    return np.stack([cos_r * delta[..., 0] - sin_r * delta[..., 1],
                     sin_r * delta[..., 0] + cos_r * delta[..., 1], delta[..., 2]], axis=-1)


def test_same_seed_gives_identical_runs():
    first = om.simulate(50, seed=3)
    second = om.simulate(50, seed=3)
    np.testing.assert_array_equal(first.poses, second.poses)
    np.testing.assert_array_equal(first.t, second.t)


def seed_sequence_of(seed) -> np.random.SeedSequence:
    """Return a fresh copy of `seed` as a SeedSequence (spawn advances the one it is called on)."""
    if isinstance(seed, np.random.SeedSequence):
        return np.random.SeedSequence(seed.entropy, spawn_key=seed.spawn_key,
                                      pool_size=seed.pool_size)
    return np.random.SeedSequence(seed)


@pytest.mark.parametrize('antithetic', [False, True])
@pytest.mark.parametrize('seed', [11, np.random.SeedSequence([11, 5]),
                                  np.random.SeedSequence(11).spawn(3)[2]],
                         ids=['int', 'entropy list', 'spawned child'])
def test_each_stream_draws_child_i_of_the_seed_whenever_and_in_whatever_order_it_is_made(
        antithetic, seed):
    """A generator made when first drawn from draws what child i of the seed draws."""
    from octoroach_model.model.effects import MODEL_TERMS
    from octoroach_model.model.simulate import AntitheticNormal, RandomStreams

    names = ('angles', 'extra_stances', *MODEL_TERMS)
    children = seed_sequence_of(seed).spawn(len(names))
    expected = {}
    for name, child in zip(names, children):
        generator = np.random.default_rng(child)
        source = AntitheticNormal(generator) if antithetic else generator
        expected[name] = [source.standard_normal((4, 3)) for _ in range(2)]
    for order in (names, names[::-1]):
        streams = RandomStreams(seed, antithetic=antithetic)
        assert sorted(streams.effects) == sorted(MODEL_TERMS)
        drawn = {name: [] for name in names}
        for _ in range(2):      # the second draw goes on from the first, from the same stream
            for name in order:
                source = getattr(streams, name) if name in ('angles', 'extra_stances') \
                    else streams.effects[name]
                drawn[name].append(source.standard_normal((4, 3)))
        for name in names:
            np.testing.assert_array_equal(drawn[name], expected[name], err_msg=name)


def test_different_seeds_give_different_runs():
    first = om.simulate(50, seed=3)
    second = om.simulate(50, seed=4)
    assert np.all(np.abs(first.poses[:, -1, :2] - second.poses[:, -1, :2]).max(axis=1) > 1e-6)


def test_draws_per_run_repeat_the_same_angles_every_gait_cycle():
    per_run = stance_steps(om.simulate(20, seed=5, draws='run', t=SWITCHES).poses)
    np.testing.assert_allclose(per_run[:, 2:], per_run[:, :-2], rtol=0, atol=1e-12)
    # ... but not across runs, and right and left stances differ
    assert np.all(np.abs(per_run[1:, 0] - per_run[:1, 0]).max(axis=1) > 1e-6)
    assert np.all(np.abs(per_run[:, 0] - per_run[:, 1]).max(axis=1) > 1e-6)


def test_draws_per_stance_give_every_stance_new_angles():
    per_stance = stance_steps(om.simulate(20, seed=5, draws='stance', t=SWITCHES).poses)
    assert np.all(np.abs(per_stance[:, 2:] - per_stance[:, :-2]).max(axis=2) > 1e-6)


def test_zero_sigmas_give_identical_runs_on_the_deterministic_path():
    runs = om.simulate(5, seed=6, sigma1=0.0, sigma2=0.0)
    phase = 2 * PARAMETERS.stride_frequency * runs.t
    n_stances = 2 * 10
    deterministic = kinematics.integrate_stances(
        np.broadcast_to(PARAMETERS.nominal_angles, (1, n_stances, 6)), phase,
        (0.0, 0.0, math.pi / 2), PARAMETERS.leg_length, PARAMETERS.hip_distance)[0]
    for run in runs.poses:
        np.testing.assert_array_equal(run, runs.poses[0])
        np.testing.assert_allclose(run, deterministic, rtol=0, atol=1e-12)


@pytest.mark.parametrize('draws', ['stance', 'run'])
def test_spread_at_the_end_grows_with_sigma(draws):
    # Same seed, so the same standard normals scaled up: common random numbers.
    spreads = []
    for sigma in (0.0, 0.03, 0.06, 0.09, 0.12, 0.15):
        end = om.simulate(300, seed=7, sigma1=sigma, sigma2=sigma, draws=draws).poses[:, -1]
        spreads.append(np.sqrt(end[:, 0].var() + end[:, 1].var()))
    assert spreads[0] < 1e-12
    assert np.all(np.diff(spreads) > 0)


def test_simulate_returns_time_and_poses_as_documented():
    runs = om.simulate(200, seed=8)
    assert isinstance(runs, om.Paths)
    assert runs.t.shape == (251,)
    assert runs.poses.shape == (200, 251, 3)
    np.testing.assert_allclose(runs.t, np.arange(251) / 50.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(runs.poses[:, 0], np.tile([0.0, 0.0, math.pi / 2], (200, 1)),
                               rtol=0, atol=1e-12)
    # Heading pi/2 is moving along +y: about 55-60 cm forward after 10 cycles.
    final = runs.poses[:, -1]
    assert final[:, 1].mean() > 0.5
    assert abs(final[:, 0].mean()) < 0.25 * final[:, 1].mean()
    assert np.all(np.isfinite(runs.poses))


def test_simulate_takes_cycles_and_custom_times():
    assert om.simulate(2, seed=1, cycles=4).t.shape == (101,)
    runs = om.simulate(3, seed=1)
    every_fifth = om.simulate(3, seed=1, t=runs.t[::5])
    np.testing.assert_allclose(every_fifth.poses, runs.poses[:, ::5], rtol=0, atol=1e-12)


@pytest.mark.parametrize('kwargs, message', [
    ({'sigma1': -0.1}, 'sigma'),
    ({'sigma2': -1e-9}, 'sigma'),
    ({'draws': 'foo'}, 'draws'),
    ({'effects': {'wobble': {}}}, r'unknown effect, text \(6 characters, not shown\); known'),
    ({'effects': {'lateral_slp': 5}}, r'unknown effect, .* \(did you mean lateral_slip\?\)'),
    ({'effects': {'measurement_noise': {'std_cm': 1.0}}},
     r'no parameter text \(6 characters, not shown\); it takes position_std_cm'),
    ({'effects': {'lateral_slip': {'velocity_cm': 1.0}}}, r'\(did you mean velocity_cm_s\?\)'),
    ({'effects': {'speed_decay': {'fraction': 2.0}}}, 'outside'),
    ({'effects': {'lateral_slip': {'velocity_cm_s': float('nan')}}}, 'outside'),
    ({'n_paths': 0}, 'n_paths'),
    ({'n_paths': 2.5}, 'n_paths'),
    ({'cycles': 0}, 'cycles'),
], ids=['negative sigma1', 'negative sigma2', 'unknown draws', 'unknown effect',
        'a typo of an effect', 'unknown effect parameter', 'a typo of a parameter',
        'effect value out of range', 'effect value not finite',
        'no paths', 'fractional paths', 'no cycles'])
def test_bad_parameters_raise_parameter_error_with_a_reason(kwargs, message):
    kwargs = {'n_paths': 2, 'seed': 1, **kwargs}
    with pytest.raises(ParameterError, match=message) as raised:
        om.simulate(kwargs.pop('n_paths'), **kwargs)
    assert '\n' not in str(raised.value)
