"""
The paper's probabilistic validation (NOTES.md section 4, eqs. 13-16).

Sample size, disjoint multisamples, the per-sample Student-t region, the estimate E^_k, the
search (15) for the widest admissible spreads, and the plug-in interface that makes the method
independent of the four-bar model. Small data (n x k of a few dozen runs) keeps this fast; the
paper's own numbers appear only where they are the point.
"""
from __future__ import annotations

from dataclasses import replace
import json
import math

import numpy as np
import pytest
from scipy import stats

import octoroach_model as om
from octoroach_model.errors import DataError, ParameterError
from octoroach_model.validation import (
    chernoff_sample_size, disjoint_multisamples, FourBarModel, guarantee_text, prediction_region,
    search_sigmas, t_multiplier, validate, Validation, ValidationSettings, violations)

# Small settings: n = ceil(ln(10) / 0.08) = 29 multisamples of k = 4 runs, 116 runs in all.
SMALL = {'epsilon': 0.2, 'delta': 0.2, 'k': 4}
REQUIRED_KEYS = {'n', 'k', 'sigma1', 'sigma2', 'violation', 'rho', 'epsilon', 'delta', 'gamma',
                 'paths_used', 'guarantee'}


@pytest.fixture(scope='module')
def four_bar_data() -> om.Paths:
    """120 runs of the paper's model at Table III spreads, 5 gait cycles each."""
    return om.simulate(120, seed=1, cycles=5)


def hoeffding_n(epsilon: float, delta: float) -> int:
    return math.ceil(math.log(2 / delta) / (2 * epsilon ** 2))


# A second model, a unicycle, as a validation plug-in (ModelPlugin); used throughout.
UNICYCLE_SPEED = 0.12   # m/s


def unicycle(sigmas, seed, n_runs, t):
    """
    Draw (n_runs, T, 3) straight runs along +y from `seed` alone.

    Each run's heading is ~ N(pi/2, sigma1^2) and its speed ~ v (1 + sigma2 N(0, 1)).
    """
    rng = np.random.default_rng(seed)
    heading = math.pi / 2 + sigmas[0] * rng.standard_normal(n_runs)
    speed = UNICYCLE_SPEED * (1 + sigmas[1] * rng.standard_normal(n_runs))
    distance = speed[:, None] * np.asarray(t)[None, :]
    return np.stack([distance * np.cos(heading)[:, None], distance * np.sin(heading)[:, None],
                     np.broadcast_to(heading[:, None], distance.shape)], axis=-1)


def unicycle_data(sigmas, n_runs=300, seed=99) -> om.Paths:
    t = np.arange(101) / 50.0
    return om.Paths(t, unicycle(sigmas, np.random.SeedSequence(seed), n_runs, t))


UNICYCLE_SETTINGS = {'epsilon': 0.2, 'delta': 0.2, 'k': 10, 'grid_points': 13,
                     'sigma1_max': 0.6, 'sigma2_max': 0.6}


# --------------------------------------------------------------------------------------------
# Sample size (eq. 16)

def test_the_papers_epsilon_and_delta_give_45_multisamples_and_need_495_runs():
    assert chernoff_sample_size(0.15, 0.27) == 45
    settings = ValidationSettings()
    assert (settings.epsilon, settings.delta, settings.k) == (0.15, 0.27, 11)
    assert settings.n == 45
    assert settings.runs_needed == 45 * 11 == 495


@pytest.mark.parametrize('epsilon, delta', [(0.3, 0.3), (0.2, 0.2), (0.1, 0.05), (0.05, 0.01),
                                            (0.25, 0.5)])
def test_the_sample_size_is_the_smallest_n_that_satisfies_the_hoeffding_bound(epsilon, delta):
    n = chernoff_sample_size(epsilon, delta)
    assert n == hoeffding_n(epsilon, delta)
    assert 2 * math.exp(-2 * n * epsilon ** 2) <= delta            # the bound holds at n ...
    assert 2 * math.exp(-2 * (n - 1) * epsilon ** 2) > delta       # ... and not at n - 1
    assert ValidationSettings(epsilon=epsilon, delta=delta).n == n


@pytest.mark.parametrize('epsilon, delta', [(0.0, 0.2), (1.0, 0.2), (0.2, 0.0), (0.2, 1.5)])
def test_the_sample_size_rejects_epsilon_or_delta_outside_the_unit_interval(epsilon, delta):
    with pytest.raises(ParameterError, match='must lie in'):
        chernoff_sample_size(epsilon, delta)


# --------------------------------------------------------------------------------------------
# Multisamples

def test_multisamples_are_disjoint_groups_of_k_distinct_runs():
    groups = disjoint_multisamples(100, 9, 7, np.random.default_rng(0))
    assert groups.shape == (9, 7)
    assert len(np.unique(groups)) == 9 * 7
    assert groups.min() >= 0 and groups.max() < 100


def test_multisamples_are_reproducible_for_a_seed_and_differ_between_seeds():
    first = disjoint_multisamples(100, 9, 7, np.random.default_rng(5))
    again = disjoint_multisamples(100, 9, 7, np.random.default_rng(5))
    other = disjoint_multisamples(100, 9, 7, np.random.default_rng(6))
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)


def test_multisamples_use_every_run_when_there_are_exactly_n_times_k():
    groups = disjoint_multisamples(495, 45, 11, np.random.default_rng(1))
    np.testing.assert_array_equal(np.sort(groups.ravel()), np.arange(495))


def test_too_few_runs_for_n_times_k_raise_a_data_error_saying_how_many_are_needed():
    with pytest.raises(DataError, match='needs 495 runs'):
        disjoint_multisamples(494, 45, 11, np.random.default_rng(0))


def test_a_validation_with_the_papers_constants_on_too_few_runs_says_495_are_needed(
        four_bar_data):
    with pytest.raises(DataError, match=r'120 runs are too few.*needs 495 runs'):
        Validation(four_bar_data, ValidationSettings())


def test_multisamples_of_one_run_are_rejected_for_lack_of_a_spread():
    with pytest.raises(ParameterError, match='k must be at least 2'):
        disjoint_multisamples(100, 5, 1, np.random.default_rng(0))


# --------------------------------------------------------------------------------------------
# The region and the decision g (eq. 13)

@pytest.mark.parametrize('k, gamma', [(4, 0.95), (11, 0.95), (11, 0.8), (25, 0.99)])
def test_the_region_is_the_mean_plus_minus_the_student_t_prediction_half_width(k, gamma):
    rng = np.random.default_rng(k)
    samples = rng.normal([0.3, -2.0], [0.05, 1.5], size=(k, 20, 2))      # (k, T, C)
    centre, half_width = prediction_region(samples, gamma)
    assert centre.shape == half_width.shape == (20, 2)
    expected_t = stats.t.ppf((1 + gamma) / 2, df=k - 1)
    np.testing.assert_allclose(centre, samples.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(
        half_width, expected_t * samples.std(axis=0, ddof=1) * math.sqrt(1 + 1 / k), rtol=1e-12)
    assert t_multiplier(k, gamma) == pytest.approx(expected_t * math.sqrt(1 + 1 / k), rel=1e-12)


def test_the_region_is_computed_for_every_multisample_at_once():
    samples = np.random.default_rng(2).normal(size=(6, 5, 10, 2))          # (n, k, T, C)
    centre, half_width = prediction_region(samples, 0.95)
    assert centre.shape == half_width.shape == (6, 10, 2)
    single_centre, single_half_width = prediction_region(samples[3], 0.95)
    np.testing.assert_allclose(centre[3], single_centre)
    np.testing.assert_allclose(half_width[3], single_half_width)


@pytest.mark.parametrize('k, gamma', [(4, 0.95), (11, 0.95), (11, 0.8)])
def test_a_new_gaussian_draw_lies_inside_the_region_a_fraction_gamma_of_the_time(k, gamma):
    rng = np.random.default_rng(100 + k)
    trials = 40_000
    mean, scale = np.array([1.0, -3.0]), np.array([0.2, 2.0])
    samples = rng.normal(mean, scale, size=(trials, k, 1, 2))             # (trials, k, T=1, C)
    new = rng.normal(mean, scale, size=(trials, 1, 2))
    centre, half_width = prediction_region(samples, gamma)
    for coordinate in range(2):
        pick = slice(coordinate, coordinate + 1)
        g = violations(new[..., pick], centre[..., pick], half_width[..., pick])
        inside = 1 - g.mean()
        # binomial standard error ~ 0.002 at 40 000 trials
        assert inside == pytest.approx(gamma, abs=0.008), coordinate


def test_a_run_violates_when_any_coordinate_at_any_sample_leaves_its_interval():
    centre = np.zeros((4, 2))
    half_width = np.full((4, 2), 1.0)
    inside = np.zeros((4, 2))
    on_the_edge = np.full((4, 2), 1.0)
    one_y_sample_out = inside.copy()
    one_y_sample_out[2, 1] = -1.01
    runs = np.stack([inside, on_the_edge, one_y_sample_out])
    np.testing.assert_array_equal(violations(runs, centre, half_width), [0.0, 0.0, 1.0])


# --------------------------------------------------------------------------------------------
# E^_k (eq. 14)

def test_a_model_identical_to_the_data_generator_violates_well_below_always(four_bar_data):
    estimates = [Validation(four_bar_data, ValidationSettings(**SMALL, seed=seed))
                 .violation(FourBarModel(), (0.12, 0.15)) for seed in range(4)]
    assert max(estimates) < 0.7
    assert np.mean(estimates) < 0.6


def test_a_model_with_spread_against_data_without_spread_always_violates():
    identical_runs = om.simulate(120, seed=1, cycles=5, sigma1=0.0, sigma2=0.0)
    validation = Validation(identical_runs, ValidationSettings(**SMALL))
    assert validation.violation(FourBarModel(), (0.12, 0.15)) == 1.0
    # ... while the same model without spread is the data and never leaves
    assert validation.violation(FourBarModel(), (0.0, 0.0)) == 0.0


def test_a_model_far_wider_than_the_data_violates_almost_always(four_bar_data):
    validation = Validation(four_bar_data, ValidationSettings(**SMALL))
    assert validation.violation(FourBarModel(), (0.4, 0.4)) >= 0.9


def test_the_violation_grows_with_the_four_bars_spread_on_common_random_numbers(four_bar_data):
    validation = Validation(four_bar_data, ValidationSettings(**SMALL))
    estimates = [validation.violation(FourBarModel(), (0.12 * scale, 0.15 * scale))
                 for scale in (0.5, 1.0, 1.5, 2.0, 2.5)]
    assert np.all(np.diff(estimates) >= 0), estimates
    assert estimates[-1] - estimates[0] >= 0.5, estimates


def test_the_violation_is_the_mean_of_the_n_decisions():
    validation = Validation(unicycle_data((0.1, 0.1)), ValidationSettings(**SMALL))
    decisions = validation.decisions(unicycle, (0.2, 0.2))
    assert decisions.shape == (validation.settings.n,)
    assert set(np.unique(decisions)) == {0.0, 1.0}
    assert validation.violation(unicycle, (0.2, 0.2)) == decisions.mean()


def test_the_four_bar_plug_in_draws_its_runs_from_its_seed_alone():
    seed = np.random.SeedSequence(7)
    t = np.arange(50) / 50.0
    first = FourBarModel()((0.12, 0.15), seed, 4, t)
    again = FourBarModel()((0.12, 0.15), seed, 4, t)
    assert first.shape == (4, 50, 3)
    np.testing.assert_array_equal(first, again)


def test_the_same_spreads_evaluated_twice_give_the_same_violation(four_bar_data):
    # common random numbers: every evaluation of the search sees the same model draws
    validation = Validation(four_bar_data, ValidationSettings(**SMALL))
    first = validation.decisions(FourBarModel(), (0.12, 0.15))
    again = validation.decisions(FourBarModel(), (0.12, 0.15))
    np.testing.assert_array_equal(first, again)


# --------------------------------------------------------------------------------------------
# The search (15)

@pytest.fixture(scope='module')
def search_settings() -> ValidationSettings:
    return ValidationSettings(**SMALL, seed=3, grid_points=6)


@pytest.fixture(scope='module')
def four_bar_search(four_bar_data, search_settings):
    return search_sigmas(Validation(four_bar_data, search_settings), FourBarModel())


def test_the_search_is_reproducible_for_a_seed(four_bar_data, search_settings):
    first = validate(four_bar_data, search_settings)
    second = validate(four_bar_data, search_settings)
    assert json.dumps(first.to_json()) == json.dumps(second.to_json())


def test_the_chosen_spreads_are_admissible(four_bar_search, search_settings):
    assert four_bar_search.feasible
    assert four_bar_search.violation <= search_settings.rho
    i = int(np.flatnonzero(four_bar_search.sigma1_grid == four_bar_search.sigma1)[0])
    j = int(np.flatnonzero(four_bar_search.sigma2_grid == four_bar_search.sigma2)[0])
    assert four_bar_search.monotone_grid[i, j] <= search_settings.rho
    assert four_bar_search.violation == four_bar_search.violation_grid[i, j]


def test_the_monotone_grid_never_decreases_along_either_spread(four_bar_search):
    monotone, raw = four_bar_search.monotone_grid, four_bar_search.violation_grid
    assert monotone.shape == raw.shape == (6, 6)
    assert np.all(np.diff(monotone, axis=0) >= 0)
    assert np.all(np.diff(monotone, axis=1) >= 0)
    assert np.all(monotone >= raw)


def test_the_chosen_spreads_lie_on_the_boundary_of_the_admissible_set(four_bar_search,
                                                                      search_settings):
    search, rho = four_bar_search, search_settings.rho
    i = int(np.flatnonzero(search.sigma1_grid == search.sigma1)[0])
    j = int(np.flatnonzero(search.sigma2_grid == search.sigma2)[0])
    last = len(search.sigma1_grid) - 1
    assert i == last or search.monotone_grid[i + 1, j] > rho
    assert j == last or search.monotone_grid[i, j + 1] > rho
    # and nothing admissible on the grid has a larger sigma1 + sigma2
    admissible = search.monotone_grid <= rho
    totals = np.add.outer(search.sigma1_grid, search.sigma2_grid)
    assert search.sigma1 + search.sigma2 == pytest.approx(totals[admissible].max())


def test_the_search_finds_spreads_near_the_ones_that_made_the_data(four_bar_search):
    # data at Table III (0.12, 0.15); the grid step is 0.08 rad
    assert 0.08 <= four_bar_search.sigma1 + four_bar_search.sigma2 <= 0.6


def test_when_no_spread_is_admissible_the_result_is_not_accepted():
    data = om.simulate(120, seed=2, cycles=5, sigma1=0.0, sigma2=0.0)
    wrong_geometry = FourBarModel(replace(om.ModelParameters.nominal(), leg_length=0.03))
    result = validate(data, ValidationSettings(**SMALL, grid_points=3), wrong_geometry)
    assert result.accepted is False
    assert result.violation == 1.0
    assert (result.sigma1, result.sigma2) == (0.0, 0.0)


# --------------------------------------------------------------------------------------------
# Model-agnostic: a unicycle plug-in through the same code

def test_the_unicycle_plug_in_is_reproducible_for_a_seed():
    first = unicycle((0.1, 0.2), np.random.SeedSequence(4), 5, np.arange(10) / 50)
    again = unicycle((0.1, 0.2), np.random.SeedSequence(4), 5, np.arange(10) / 50)
    assert first.shape == (5, 10, 3)
    np.testing.assert_array_equal(first, again)


@pytest.mark.parametrize('truth, larger', [((0.2, 0.05), 'sigma1'), ((0.05, 0.2), 'sigma2')])
def test_a_unicycle_model_is_validated_through_the_same_code(truth, larger):
    settings = ValidationSettings(**UNICYCLE_SETTINGS, seed=1)
    result = validate(unicycle_data(truth), settings, unicycle).to_json()
    assert REQUIRED_KEYS <= set(result)
    assert result['n'] == 29 and result['k'] == 10 and result['paths_used'] == 290
    assert result['accepted'] and result['violation'] <= settings.rho
    # the spread that made the data larger is found larger, and the total is of its order
    smaller = 'sigma2' if larger == 'sigma1' else 'sigma1'
    assert result[larger] > result[smaller]
    assert 0.8 * sum(truth) <= result['sigma1'] + result['sigma2'] <= 3 * sum(truth)
    json.dumps(result)


def test_a_unicycle_at_the_spreads_that_made_the_data_is_accepted_and_a_wider_one_is_not():
    data = unicycle_data((0.1, 0.1))
    settings = ValidationSettings(**UNICYCLE_SETTINGS, seed=2)
    right = validate(data, settings, unicycle, sigmas=(0.1, 0.1)).to_json()
    wide = validate(data, settings, unicycle, sigmas=(0.4, 0.4)).to_json()
    assert right['accepted'] and right['violation'] <= 0.35
    assert not wide['accepted'] and wide['violation'] >= 0.8
    assert (right['sigma1'], right['sigma2']) == (0.1, 0.1)


# --------------------------------------------------------------------------------------------
# The result and the settings

def test_the_result_is_json_with_the_required_fields_and_a_guarantee_in_words(four_bar_data):
    settings = ValidationSettings(**SMALL, grid_points=3)
    result = json.loads(json.dumps(validate(four_bar_data, settings).to_json()))
    assert REQUIRED_KEYS <= set(result)
    assert (result['n'], result['k'], result['paths_used']) == (29, 4, 116)
    assert (result['rho'], result['epsilon'], result['delta'], result['gamma']) == \
        (0.35, 0.2, 0.2, 0.95)
    guarantee = result['guarantee']
    assert 'delta' in guarantee and 'epsilon' in guarantee
    assert '0.80' in guarantee            # 1 - delta
    assert f'{result["violation"]:.3f}' in guarantee
    assert guarantee == guarantee_text(result['violation'], settings)


def test_the_guarantee_states_the_interval_of_the_true_violation():
    text = guarantee_text(0.3, ValidationSettings())
    assert '1 - delta = 0.73' in text
    assert 'epsilon = 0.15' in text
    assert '[0.150, 0.450]' in text
    assert 'n = 45' in text


@pytest.mark.parametrize('field, value, reason', [
    ('rho', 0.0, 'rho must lie in'),
    ('rho', 1.0, 'rho must lie in'),
    ('epsilon', 1.5, 'epsilon must lie in'),
    ('delta', 0.0, 'delta must lie in'),
    ('k', 1, 'k must lie in'),
    ('gamma', 1.0, 'gamma must lie in'),
    ('gamma', 0.0, 'gamma must lie in'),
    ('seed', -1, 'seed must be non-negative'),
    ('grid_points', 1, 'grid_points must lie in'),
    ('sigma1_max', 0.0, r'sigma1_max must lie in \(0, 1.5\) rad'),
    ('sigma2_max', 1.5, r'sigma2_max must lie in \(0, 1.5\) rad'),
])
def test_validation_settings_reject_bad_values_with_a_reason(field, value, reason):
    with pytest.raises(ParameterError, match=reason):
        ValidationSettings(**{field: value})
