"""
The decision made again with the simulations drawn anew on the same halves (redraws.py).

A diagnosis with `simulation_draws` K reports which terms each of K draws named; the first is
the report's own decision, the others keep its halves and move only the simulations' seed.
"""
from __future__ import annotations

from dataclasses import replace
import json
from pathlib import Path
import subprocess
import sys

from hidden_effects import FAST, FEW_SIMULATED_RUNS, SEED
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest

import octoroach_model as om
from octoroach_model import validation_jobs
from octoroach_model.diagnosis import diagnose, DiagnosisSettings, summary_text
from octoroach_model.diagnosis.diagnose import halves_as_diagnosed, redraw_settings
from octoroach_model.diagnosis.redraws import DrawAgreement
from octoroach_model.errors import ParameterError
from octoroach_model.jsonio import dumps
from octoroach_model.nodes import validator

REPO = Path(__file__).resolve().parents[1]


def test_other_draws_of_the_simulations_are_reported_beside_the_decision():
    # few simulated runs: what each draw names may differ (that is what is reported); each
    # draw must be the diagnosis at its own settings, and the report must say so (a draw
    # runs the decision alone, `redrawn_terms`: it must name what the whole diagnosis names)
    measured = om.simulate(80, seed=SEED % 1000, cycles=6, effects={
        'initial_pose_error': {'heading_std_deg': 5.0, 'position_std_cm': 0.3}})
    settings = replace(FAST, seed=SEED, simulation_draws=2, **FEW_SIMULATED_RUNS)
    report = diagnose(measured, settings)
    draws = report.simulation_draws
    assert draws is not None
    assert draws.seeds == (SEED, SEED + 1) and draws.split_seed == SEED
    assert draws.named[0] == tuple(report.named_terms)
    assert draws.named[1] == tuple(diagnose(measured, redraw_settings(settings, 1)).named_terms)
    plain = json.loads(dumps(report))
    assert plain['simulation_draws'] == {
        'count': 2, 'seeds': [SEED, SEED + 1], 'split_seed': SEED,
        'named': [list(named) for named in draws.named],
        'same_as_reported': 1 + (set(draws.named[1]) == set(draws.named[0])),
        'by_term': {term: sum(term in named for named in draws.named)
                    for term in dict.fromkeys(draws.named[0] + draws.named[1])}}
    assert 'redraws' in report.stages_s
    assert draws.sentence() in summary_text(report)
    # one draw (the default) writes no such entry
    assert 'simulation_draws' not in replace(report, simulation_draws=None).to_json()
    # every term whose test decides (size past its floor, gain material) says how far its t
    # moves with other scored runs; the others, whose test decides nothing, do not
    for candidate in report.candidates:
        decides = (candidate.clears_floor and not candidate.screened and candidate.gain_se > 0
                   and candidate.gain >= report.decision.min_gain)
        assert (candidate.t_scoring_se is not None and candidate.t_scoring_se > 0) == decides
    assert all('t_scoring_se' in entry for entry in plain['candidates'])
    close_calls_are_said(report, report.candidates[0])


def close_calls_are_said(report, candidate) -> None:
    """Check that a test ending within two scoring errors of its critical t is said, only then."""
    from scipy import stats

    from octoroach_model.diagnosis.summary import close_calls

    critical = float(stats.t.isf(report.steps[candidate.step - 1].test_level,
                                 report.split['held_out'] - 1))
    decided = replace(candidate, clears_floor=True, screened=False, gain_se=0.1,
                      gain=max(0.1 * (critical + 0.5), report.decision.min_gain))
    t = decided.gain / decided.gain_se
    for error, said in ((0.6 * abs(t - critical) + 0.01, True),
                        (0.4 * abs(t - critical), False)):
        others = tuple(c for c in report.candidates if c.cause != candidate.cause)
        shown = replace(report, candidates=(replace(decided, t_scoring_se=error),) + tuple(
            replace(c, t_scoring_se=None) for c in others), extension_candidates=())
        assert [(c.cause, round(tc, 6)) for c, tc, _ in close_calls(shown)] == (
            [(candidate.cause, round(t, 6))] if said else [])
        text = summary_text(shown)
        assert ('Decided close to the threshold' in text) == said
        if said:
            assert f'- {candidate.cause} (' in text and f'against {critical:.2f}' in text


@settings(max_examples=40, deadline=None)
@given(runs=st.integers(3, 60), held_out=st.integers(1, 20), by_position=st.booleans(),
       shift=st.floats(-2.0, 2.0), seed=st.integers(0, 2 ** 32 - 1))
def test_the_scoring_error_is_the_spread_of_paired_t_over_resampled_scored_runs(
        runs, held_out, by_position, shift, seed):
    # the resamples computed at once are PairedGain's t on the picked runs, one by one
    from octoroach_model.diagnosis.features import FEATURES
    from octoroach_model.diagnosis.scoring import (
        feature_log_score, PairedGain, SCORING_RESAMPLES, Scores, t_scoring_se)

    rng = np.random.default_rng(seed)
    width = len(FEATURES)
    current = rng.normal(size=(runs, width)) * rng.uniform(0.01, 3.0, width)
    candidate = current + shift * rng.normal(size=(runs, width)) ** 2
    observed = rng.normal(size=(held_out, width))
    empty = np.zeros(held_out)
    got = t_scoring_se(Scores(empty, empty, candidate, by_position),
                       Scores(empty, empty, current, by_position), observed,
                       np.random.default_rng(seed))
    picks = np.random.default_rng(seed).integers(0, runs, (SCORING_RESAMPLES, runs))
    t_values = []
    for pick in picks:
        gain = PairedGain.of(feature_log_score(candidate[pick], observed, by_position)
                             - feature_log_score(current[pick], observed, by_position))
        if 0.0 < gain.standard_error < np.inf:
            t_values.append(gain.mean / gain.standard_error)
    if 2 * len(t_values) < SCORING_RESAMPLES:
        assert got is None
    else:
        assert got == pytest.approx(np.std(t_values, ddof=1), rel=1e-6, abs=1e-9)


def test_the_scoring_error_of_t_is_the_spread_of_t_over_other_scored_runs():
    # the true model with a turning-rate spread against the same without it, fits held: only
    # the scored runs move between draws (benchmarks/bench_scoring_error.py: 1.05-1.5 times
    # the spread over five terms; 0.92-1.02 for this term on six other data sets at 400
    # scored runs); 48 draws of 400 scored runs a model put the spread within about a tenth
    from octoroach_model.diagnosis.diagnose import prepare_halves, score_held_out, Simulator
    from octoroach_model.diagnosis.modelfit import FittedModel
    from octoroach_model.diagnosis.scoring import PairedGain, t_scoring_se
    from octoroach_model.fitting import mean_start_pose

    effects = {'persistent_turning': {'yaw_rate_std_deg_s': 4.0}}
    measured = om.simulate(300, seed=SEED % 10_000, effects=effects)
    settings = replace(FAST, seed=SEED, score_runs=400)
    halves = prepare_halves(measured, settings)
    start = tuple(mean_start_pose(measured))
    current = FittedModel(om.ModelParameters.nominal(), start, 1.0, {})
    candidate = FittedModel(om.ModelParameters.nominal(), start, 1.0, effects)
    observed = halves.test.features / halves.scales
    t_values, reported = [], []
    for draw in range(48):
        simulator = Simulator(halves.test, SEED + 1000 + draw)
        before = score_held_out(simulator, current, halves, settings)
        after = score_held_out(simulator, candidate, halves, settings)
        gain = PairedGain.of(after.log - before.log)
        t_values.append(gain.mean / gain.standard_error)
        reported.append(t_scoring_se(after, before, observed, np.random.default_rng(draw)))
    ratio = float(np.median(reported)) / float(np.std(t_values, ddof=1))
    assert 0.6 <= ratio <= 2.0, (SEED, ratio, np.mean(t_values))


def test_a_close_call_is_decided_on_runs_scored_again(monkeypatch):
    """
    Every test that decides made a close call here (the band widened): each is scored again.

    It is scored on close_call_factor times the runs and decided on those; its first t is
    the t the same diagnosis without scoring again gives, and the t's scoring error falls: on
    four times the runs to 0.44-0.73 of itself over 16 seeds of this test (median 0.52 with
    400 resamples, benchmarks/bench_close_call_error.py; 1/sqrt(4) would be 0.5). The bound
    0.85 leaves room for that spread, and a rescoring that kept the first runs alone would
    stay near 1. With the diagnosis's 50 resamples the error estimate itself spreads by a
    tenth: a bound of 0.75 failed at suite seed 227396 (0.90; 0.73 with 400), so the test
    resamples 400 times. The bound is the hidden cause's (persistent_turning: 0.34-0.75 over
    70 seeds, median 0.52): a term not in the runs that a test decides on (at 3 of those 70
    seeds) fell less, to 0.85-0.88 (speed_decay, change_point; 0.855 failed this bound at
    suite seed 90009), and is held to falling at all. Its gain is mostly scoring noise (t's
    error about 2 where t is 0.2-2.6), and a t is scale-free: a t of noise keeps an error of
    order one however many runs are scored.
    """
    import importlib

    from octoroach_model.diagnosis import scoring
    from octoroach_model.diagnosis.summary import summary_text

    decide_module = importlib.import_module('octoroach_model.diagnosis.decide')
    monkeypatch.setattr(scoring, 'SCORING_RESAMPLES', 400)
    # few scored runs (they are what is scored again), the fits' runs as FAST has them: with
    # FEW_SIMULATED_RUNS' 60 moment runs the size bound missed its floor at some seeds
    # (855908), and then no test decided
    measured = om.simulate(120, seed=SEED % 1000, cycles=6, effects={
        'persistent_turning': {'yaw_rate_std_deg_s': 6.0}})
    settings = replace(FAST, seed=SEED, score_runs=120)
    monkeypatch.setattr(decide_module, 'CLOSE_CALL_SE', float('inf'))
    once = diagnose(measured, replace(settings, close_call_factor=1))
    again = diagnose(measured, settings)
    first_step = {c.cause: c for c in once.candidates + once.extension_candidates
                  if c.step == 1}
    decided = [c for c in again.candidates + again.extension_candidates
               if c.t_scoring_se is not None]
    assert decided, SEED
    compared = set()
    for candidate in decided:
        assert candidate.scored_runs == 4 * settings.score_runs, candidate.cause
        assert candidate.first_t is not None
        level = again.steps[candidate.step - 1].test_level
        assert candidate.named_here == (candidate.clears_floor and candidate.p_value < level
                                        and candidate.gain >= settings.min_gain)
        # a report keeps each term's last record: where the first diagnosis went on to a
        # second step (the rescoring turned its first step, seed 92005), only the term it
        # named keeps its first-step record there to compare with
        before = first_step.get(candidate.cause) if candidate.step == 1 else None
        if before is not None:
            compared.add(candidate.cause)
            assert candidate.first_t == pytest.approx(before.held_out_t, rel=1e-12)
            assert before.first_t is None and before.scored_runs == settings.score_runs
            bound = 0.85 if candidate.cause == 'persistent_turning' else 1.0
            assert candidate.t_scoring_se < bound * before.t_scoring_se, (
                SEED, candidate.cause, candidate.t_scoring_se, before.t_scoring_se)
    assert 'persistent_turning' in compared, (SEED, compared)     # the hidden cause, always
    text = summary_text(again)
    assert f'scored again on {4 * settings.score_runs} runs' in text
    assert all(f'- {candidate.cause} (' in text for candidate in decided)
    plain = json.loads(dumps(again))
    assert all({'scored_runs', 'first_t'} <= set(entry) for entry in plain['candidates'])


def test_a_model_scored_in_two_batches_is_scored_as_on_all_its_runs_at_once():
    from octoroach_model.diagnosis.features import FEATURES
    from octoroach_model.diagnosis.scoring import pooled_scores, score_model

    rng = np.random.default_rng(SEED)
    width = len(FEATURES)
    scales = rng.uniform(0.5, 2.0, width)
    features, points = rng.normal(size=(90, width)), rng.normal(size=(90, 10))
    observed, observed_points = rng.normal(size=(25, width)), rng.normal(size=(25, 10))
    for by_position in (False, True):
        first = score_model(features[:30], points[:30], observed, observed_points, scales,
                            by_position)
        more = score_model(features[30:], points[30:], observed, observed_points, scales,
                           by_position)
        whole = score_model(features, points, observed, observed_points, scales, by_position)
        both = pooled_scores(first, more, observed / scales, observed_points)
        np.testing.assert_allclose(both.log, whole.log, rtol=1e-12)
        np.testing.assert_allclose(both.energy_cm, whole.energy_cm, rtol=1e-12)
        assert both.runs == 90 and both.by_position == by_position


def test_a_draw_keeps_the_halves_and_moves_only_the_simulations():
    settings = replace(FAST, seed=SEED, simulation_draws=3)
    second = redraw_settings(settings, 2)
    assert (second.seed, second.split_seed, second.simulation_draws) == (SEED + 2, SEED, 1)
    assert not second.detection_limits and not second.validate_models
    assert redraw_settings(replace(settings, split_seed=7), 1).split_seed == 7
    measured = om.simulate(60, seed=1, cycles=6)
    first = halves_as_diagnosed(measured, settings)
    again = halves_as_diagnosed(measured, second)
    np.testing.assert_array_equal(first.test.paths.poses, again.test.paths.poses)


names = st.sampled_from(['initial_pose_error', 'lateral_slip', 'heading_random_walk',
                         'run_mixture'])


@given(st.lists(st.lists(names, unique=True, max_size=3).map(tuple), min_size=1, max_size=6))
def test_the_agreement_counts_the_draws_that_name_the_reported_terms(named):
    agreement = DrawAgreement(tuple(range(len(named))), 0, tuple(named))
    reported = set(named[0])
    assert agreement.same_as_reported == sum(set(terms) == reported for terms in named)
    assert 1 <= agreement.same_as_reported <= len(named)
    for term, count in agreement.by_term.items():
        assert count == sum(term in terms for terms in named)
    sentence = agreement.sentence()
    if all(set(terms) == reported for terms in named):
        assert 'every time' in sentence
    else:
        assert 'rests partly' in sentence
        wavering = {term for term, count in agreement.by_term.items() if count < len(named)}
        assert wavering and all(f'{term} in' in sentence for term in wavering)


def test_a_number_of_draws_outside_its_range_is_refused_before_any_work(tmp_path):
    with pytest.raises(ParameterError, match='simulation_draws must lie in'):
        DiagnosisSettings(simulation_draws=0)
    with pytest.raises(ParameterError, match='simulation_draws must lie in'):
        DiagnosisSettings(simulation_draws=21)
    with pytest.raises(ParameterError, match=r'close_call_factor must be at least 1, got 0'):
        DiagnosisSettings(close_call_factor=0)
    # the command checks it before it reads any input (this one does not exist)
    result = subprocess.run(
        [sys.executable, '-m', 'octoroach_model', 'diagnose', str(REPO / 'no-such-bag'),
         '--out', str(tmp_path / 'report'), '--simulation-draws', '21'],
        cwd=REPO, capture_output=True, text=True, timeout=120)
    assert result.returncode == 1 and 'Traceback' not in result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert lines == ['error: diagnose: simulation_draws must lie in [1, 20], got 21'], \
        result.stderr
    assert not (tmp_path / 'report').exists()


def test_the_validator_diagnoses_with_its_simulation_draws():
    values = {spec.name: spec.default for spec in validator.validator_specs()}
    assert values['simulation_draws'] == 1
    job = validation_jobs.Job.from_values({**values, 'simulation_draws': 3})
    assert validation_jobs.diagnosis_settings(job).simulation_draws == 3
    with pytest.raises(ParameterError, match='simulation_draws'):
        validation_jobs.Job.from_values({**values, 'simulation_draws': 0})
