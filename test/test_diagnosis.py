"""
The diagnosis must find effects hidden in data: the suite hides causes drawn at random.

Every run of the suite draws afresh, from the suite seed (printed in pytest's header and in
every failure message; `OCTOROACH_TEST_SEED=N make test` replays a run):
- one random cause at a time, twice: it alone is named, its size within 40 %;
- two causes at once: both named (and nothing else), each within 40 %;
- a null from the paper's model (Table II), and one from a robot drawn at random from the
  robot space of the false-positive study (docs/measured.md): no cause named;
- an effect outside the table (a slow yaw wobble, `wobble` below, written independently of
  the package's simulator): the extension family periodic_heading finds and sizes it, and no
  cause of the table is named for it (test_extensions.py hides every family; an effect that
  neither the table nor the library names is left unexplained there).
Sizes come from HIDDEN_RANGE, where 300 runs of 10 cycles find a cause reliably (docs/measured.md).
"""
from __future__ import annotations

from dataclasses import replace
import importlib
import json
import math
from pathlib import Path
import random

from hidden_effects import FAST, FEW_SIMULATED_RUNS, SEED
from hypothesis import given, settings as hypothesis_settings, strategies as st
import numpy as np
import pytest

import octoroach_model as om
from octoroach_model.diagnosis import diagnose, DiagnosisSettings, write_report
from octoroach_model.diagnosis.causes import BY_NAME, CANDIDATES, FeatureStatistic, Reading
from octoroach_model.diagnosis.diagnose import screened_first
from octoroach_model.diagnosis.features import FEATURES, INDEX, OUTCOMES
from octoroach_model.diagnosis.stages import STAGES
from octoroach_model.model.extensions import drift_term, FAMILY_NAMES
from octoroach_model.validation import ValidationSettings

REPO = Path(__file__).resolve().parents[1]
N_RUNS = 300
# cause -> (low, high, signed, fixed other parameters) of the main parameter
HIDDEN_RANGE = {
    'initial_pose_error': (2.0, 8.0, False, {'position_std_cm': 0.3}),
    'measurement_noise': (0.05, 0.3, False, {}),
    'gait_frequency_variation': (0.03, 0.1, False, {}),
    'speed_decay': (0.1, 0.4, False, {}),
    'lateral_slip': (1.0, 3.0, True, {}),
    'persistent_turning': (5.0, 12.0, False, {}),
}


def main_parameter(cause: str) -> str:
    return om.EFFECT_PARAMETERS[cause][0]


def draw_effect(rng: random.Random, cause: str) -> dict:
    low, high, signed, others = HIDDEN_RANGE[cause]
    value = low + (high - low) * rng.random()
    if signed and rng.random() < 0.5:
        value = -value
    return {cause: {main_parameter(cause): round(value, 4), **others}}


def named_sizes(report) -> dict[str, float]:
    return {c.cause: c.parameters[main_parameter(c.cause)] for c in report.causes}


def replay(what: str) -> str:
    """Begin a failure message with how to draw the same case again."""
    return f'OCTOROACH_TEST_SEED={SEED} ({what})'


def settings(offset: int = 0) -> DiagnosisSettings:
    return replace(FAST, seed=SEED + offset)


@pytest.mark.long
@pytest.mark.parametrize('draw', [0, 1])
def test_a_hidden_cause_drawn_at_random_is_named_alone_and_its_size_estimated(draw):
    rng = random.Random(SEED * 10 + draw)
    cause = rng.choice(sorted(HIDDEN_RANGE))
    effects = draw_effect(rng, cause)
    report = diagnose(om.simulate(N_RUNS, seed=SEED + draw, effects=effects), settings(draw))
    found = named_sizes(report)
    truth = effects[cause][main_parameter(cause)]
    message = f'{replay(f"hidden {effects}")}: named {found}'
    assert set(found) == {cause}, message
    assert abs(found[cause] - truth) <= 0.4 * abs(truth), message
    assert report.cause == cause and report.parameters[main_parameter(cause)] == found[cause]


@pytest.mark.long
def test_two_causes_at_once_are_both_named_with_their_sizes():
    rng = random.Random(SEED * 10 + 5)
    first, second = rng.sample(sorted(HIDDEN_RANGE), 2)
    effects = {**draw_effect(rng, first), **draw_effect(rng, second)}
    report = diagnose(om.simulate(N_RUNS, seed=SEED + 5, effects=effects), settings(5))
    found = named_sizes(report)
    message = f'{replay(f"hidden {effects}")}: named {found}'
    # both named, as the diagnosis must; a third, spurious cause beside two large ones is a
    # known weakness (docs/measured.md), tolerated here but not a fourth
    assert {first, second} <= set(found) and len(found) <= 3, message
    for cause in (first, second):
        truth = effects[cause][main_parameter(cause)]
        assert abs(found[cause] - truth) <= 0.4 * abs(truth), message
        named = next(c for c in report.causes if c.cause == cause)
        low, high = named.interval[main_parameter(cause)]
        assert low <= found[cause] <= high, message


def random_robot(rng: random.Random) -> tuple[om.ModelParameters, int, int, float]:
    """
    Draw a robot of the false-positive study's space (docs/measured.md).

    Touchdown angles within 5 deg of Table II, leg 1.8-2.6 cm, strides 1.5-3.5 Hz, 8-14
    cycles, 50/100/200 Hz, 150-600 runs (up to 1000 in the benchmark; fewer here for time),
    spreads 0.3-1.5 x Table III.
    """
    nominal = om.ModelParameters.nominal()
    angles = tuple(a + math.radians(rng.uniform(-5, 5)) for a in nominal.touchdown_angles)
    robot = replace(nominal, touchdown_angles=angles, leg_length=rng.uniform(0.018, 0.026),
                    stride_frequency=rng.uniform(1.5, 3.5),
                    sample_rate=rng.choice([50.0, 100.0, 200.0])).with_paper_liftoff()
    return robot, rng.randint(8, 14), rng.randint(150, 600), rng.uniform(0.3, 1.5)


@pytest.mark.long
def test_data_from_the_paper_model_name_no_cause():
    report = diagnose(om.simulate(N_RUNS, seed=SEED + 7), settings(7))
    assert report.causes == () and report.cause == 'none' and report.parameters == {}, \
        f'{replay("Table II null")}: named {named_sizes(report)}'
    # a term whose bound cannot reach its floor is screened, not refit nor scored: families
    # and the table's causes sized by their moments (on a null, three or four of the four
    # each time at suite seeds 1-3), never a path cause of the table (its estimate before
    # the refit reads too small where the geometry mimics it)
    first = report.steps[0].candidates
    screened = [c for c in first if c.screened]
    assert all(screened_first(BY_NAME[c.cause]) and c.scored_runs == 0 for c in screened)
    assert any(not c.family for c in screened), replay('Table II null: no cause screened')
    assert all(c.scored_runs > 0 for c in first if not screened_first(BY_NAME[c.cause]))


def test_the_screen_stops_only_terms_whose_bound_cannot_reach_their_floor():
    """
    `diagnose.screen` alone: what a race step and a live look ask before any refit.

    A term is stopped exactly where its size estimated at the current geometry has a bound
    below its floor even SCREEN_ALLOWANCE standard errors up (or a mixture lacks evidence of
    two groups); a measurement noise at many times its floor passes; the table's path causes
    are never screened; a screened term was not refit nor scored (the current geometry and
    scores, no gain), and `evaluate_candidate` answers the same for it.
    """
    from octoroach_model.diagnosis.causes import CANDIDATES, EstimateKind
    from octoroach_model.diagnosis.decide import decision_z
    from octoroach_model.diagnosis.diagnose import (
        evaluate_candidate, fit_baseline, halves_as_diagnosed, MIXTURE_EVIDENCE_NATS,
        out_of_reach, quick_fit, score_held_out, screen, SCREEN_ALLOWANCE, Simulator)

    measured = om.simulate(120, seed=SEED + 61, cycles=8, effects={
        'measurement_noise': {'position_std_cm': 0.2}})
    quick = replace(FAST, seed=SEED + 61, **FEW_SIMULATED_RUNS)
    halves = halves_as_diagnosed(measured, quick)
    baseline = fit_baseline(halves, quick).model
    scores = score_held_out(Simulator(halves.test, quick.seed), baseline, halves, quick)
    z = decision_z(quick.decision_alpha, len(CANDIDATES))
    answers = {cause.name: screen(halves, baseline, scores, cause.name, quick, z)
               for cause in CANDIDATES}
    message = replay(f'screened {[name for name, answer in answers.items() if answer]}')
    assert answers['measurement_noise'] is None, message
    for cause in CANDIDATES:
        answer = answers[cause.name]
        if not cause.is_extension and cause.kind == EstimateKind.PATH:
            assert answer is None, message
            continue
        estimate = quick_fit(halves.train, baseline, cause, quick).estimates[cause.name]
        stopped = out_of_reach(estimate, cause.floor(halves.run_scale), z - SCREEN_ALLOWANCE) \
            or (cause.kind == EstimateKind.MIXTURE
                and estimate.detail['log_likelihood_ratio'] < MIXTURE_EVIDENCE_NATS)
        assert (answer is not None) == stopped, f'{cause.name}: {message}'
        if answer is not None:
            assert answer.screened and answer.scores is scores, message
            assert (answer.gain.mean, answer.gain.p_value, answer.gain_cm) == (0.0, 1.0, 0.0)
            assert answer.model.parameters == baseline.parameters, message
            assert repr(answer.estimates[cause.name]) == repr(estimate), message  # NaN-safe
    screened = [name for name, answer in answers.items() if answer is not None]
    assert screened, message
    evaluated = evaluate_candidate(halves, baseline, scores, screened[0], quick, z)
    assert evaluated.screened and repr(evaluated.estimates) == repr(
        answers[screened[0]].estimates)


@pytest.mark.long
def test_every_feature_a_term_is_sized_or_started_from_is_scored():
    """
    A term whose size the runs show in a feature the held-out test does not read goes unnamed.

    yaw_rate_ramp was started from the heading rate's change between a run's halves while the
    test scored every feature but that one: at suite seed 1206 a ramp to 7.1 deg/s, its bound
    at 6.0 for a floor of 0.28, went unnamed (features.py, note (5)).
    """
    read = sorted({(cause.name, statistic.feature) for cause in CANDIDATES
                   for statistic in (cause.statistic, cause.signature, *cause.also_reads)
                   if statistic is not None})
    assert ('yaw_rate_ramp', 'heading_rate_change') in read
    unscored = [(name, feature) for name, feature in read if not OUTCOMES[INDEX[feature]]]
    assert not unscored, f'terms sized from features no held-out test reads: {unscored}'
    # each reading is the one it names, on a made-up matrix of runs in recording order
    rng = np.random.default_rng(SEED)
    features = rng.normal(size=(40, len(FEATURES)))
    features[:, INDEX['position']] = np.linspace(0.0, 1.0, 40)
    features[:, INDEX['heading_rate']] += 3.0 * features[:, INDEX['position']]
    column = features[:, INDEX['heading_rate']]
    assert FeatureStatistic('heading_rate', Reading.MEAN)(features) == pytest.approx(column.mean())
    assert FeatureStatistic('heading_rate', Reading.VARIANCE)(features) == pytest.approx(
        column.var(ddof=1))
    assert FeatureStatistic('heading_rate', Reading.MEAN_EXP)(features) == pytest.approx(
        np.exp(column).mean())
    slope = np.polyfit(features[:, INDEX['position']], column, 1)[0]
    assert FeatureStatistic('heading_rate', Reading.TREND)(features) == pytest.approx(slope)


@pytest.mark.long      # 7-56 s: the robot's samples are drawn (up to 1867 a run)
def test_a_null_from_a_randomly_drawn_robot_names_no_cause():
    rng = random.Random(SEED * 10 + 8)
    robot, cycles, runs, scale = random_robot(rng)
    sigma1, sigma2 = om.model.nominal_sigmas()
    measured = om.simulate(runs, seed=SEED + 8, cycles=cycles, parameters=robot,
                           sigma1=sigma1 * scale, sigma2=sigma2 * scale)
    report = diagnose(measured, settings(8))
    case = f'robot {robot.table()}, {cycles} cycles, {runs} runs, spread x{scale:.2f}'
    assert report.causes == (), f'{replay(case)}: named {named_sizes(report)}'


def wobble(paths: om.Paths, amplitude_deg: float, period_s: float, seed: int) -> om.Paths:
    """
    Add an effect outside the table of causes: a slow yaw wobble, from a tether or an uneven floor.

    The heading becomes heading + A sin(2 pi t / P + phase_i) - A sin(phase_i), and each step
    is turned with it.
    """
    rng = np.random.default_rng(seed)
    t = paths.t
    phase = rng.uniform(0, 2 * np.pi, paths.n_paths)
    offset = math.radians(amplitude_deg) * (
        np.sin(2 * np.pi * t[None, :] / period_s + phase[:, None]) - np.sin(phase)[:, None])
    steps = np.diff(paths.poses[..., :2], axis=1)
    middle = 0.5 * (offset[:, 1:] + offset[:, :-1])
    cos, sin = np.cos(middle), np.sin(middle)
    turned = np.stack([cos * steps[..., 0] - sin * steps[..., 1],
                       sin * steps[..., 0] + cos * steps[..., 1]], axis=-1)
    poses = paths.poses.copy()
    poses[:, 1:, :2] = paths.poses[:, :1, :2] + np.cumsum(turned, axis=1)
    poses[..., 2] += offset
    return om.Paths(t, poses)


@pytest.mark.long
def test_an_effect_outside_the_table_is_found_by_its_extension_family(tmp_path):
    rng = random.Random(SEED * 10 + 9)
    amplitude, period = rng.uniform(4, 8), rng.uniform(1.5, 3.0)
    measured = wobble(om.simulate(N_RUNS, seed=SEED + 9), amplitude, period, SEED)
    report = diagnose(measured, settings(9))
    message = replay(f'wobble {amplitude:.1f} deg every {period:.2f} s: causes '
                     f'{named_sizes(report)}, extensions '
                     f'{[(e.family, e.parameters) for e in report.extensions]}')
    assert [e.family for e in report.extensions] == ['periodic_heading'], message
    assert not report.causes, message
    found = report.extensions[0].parameters
    assert abs(found['amplitude_deg'] - amplitude) <= 0.4 * amplitude, message
    assert abs(found['frequency_hz'] * period - 1) <= 0.15, message
    written = write_report(report, tmp_path, plots=False)
    summary = written['summary'].read_text()
    assert 'periodic_heading' in summary and 'swings' in summary, message


@pytest.mark.long
def test_the_report_has_the_documented_fields_a_summary_and_plots(tmp_path, monkeypatch):
    # the module, which its function of the same name shadows as an attribute of the package
    diagnosis_module = importlib.import_module('octoroach_model.diagnosis.diagnose')
    measured = om.simulate(200, seed=3, effects={
        'initial_pose_error': {'heading_std_deg': 4.5, 'position_std_cm': 0.3}})
    # fewer simulated runs than FAST's: the cause here is strong (a gain of 15 nats per run),
    # and what is checked is the report's shape, with every limit and validation in it
    quick = replace(FAST, validate_models=True, detection_limits=True, score_runs=300,
                    moment_runs=150, mean_path_runs=60, bootstrap=40,
                    validation=ValidationSettings(epsilon=0.3, delta=0.3, k=8, grid_points=5))
    sought = {}

    def recorded(simulator, without, estimate, *args, **kwargs):
        sought[estimate.cause] = args[7] if len(args) > 7 else kwargs.get('fitted_values')
        return detection_limit(simulator, without, estimate, *args, **kwargs)

    detection_limit = diagnosis_module.detection_limit
    monkeypatch.setattr(diagnosis_module, 'detection_limit', recorded)
    report = diagnose(measured, quick)
    # a change point's limit is sought (and stated) for a change at half the runs, not where
    # chance put the null's step
    assert sought['change_point']['time_s'] == pytest.approx(0.5 * measured.t[-1], rel=0.02)
    written = write_report(report, tmp_path, measured=measured)
    loaded = json.loads(written['report'].read_text())
    for key in ('paths', 'baseline', 'discrepancies', 'candidates', 'cause', 'parameters',
                'extended', 'gain', 'causes', 'adequate', 'unexplained'):
        assert key in loaded, key
    assert loaded['paths'] == 200 and loaded['cause'] == 'initial_pose_error'
    assert loaded['causes'][0]['cause'] == 'initial_pose_error'
    assert set(loaded['causes'][0]) >= {'cause', 'parameters', 'interval', 'gain', 'p_value'}
    low, high = loaded['causes'][0]['interval']['heading_std_deg']
    assert low < 4.5 < high
    for key in ('sigma1', 'sigma2', 'violation'):
        assert key in loaded['baseline'] and key in loaded['extended'], key
    for key in ('metric', 'baseline', 'extended', 'relative'):
        assert key in loaded['gain'], key
    assert loaded['gain']['extended'] > loaded['gain']['baseline']   # log score: higher is better
    assert 0 < loaded['gain']['relative'] <= 1.5
    assert set(loaded['discrepancies'][0]) >= {'statistic', 'data', 'model', 'z'}
    assert {c['cause'] for c in loaded['candidates']} == set(om.EFFECT_NAMES)
    for candidate in loaded['candidates']:
        assert set(candidate) >= {'cause', 'parameters', 'gain', 'p_value', 'detectable',
                                  'detectable_method', 'detectable_power'}
    summary = written['summary'].read_text()
    assert 'initial_pose_error' in summary and 'would go unseen' in summary
    assert '(for a change at half the runs) would go unseen' in summary
    assert not loaded['extensions']       # so the summary says which families were tried: all
    tried = summary.split('No extension family (', 1)[1].split(')', 1)[0]
    assert tried.split(', ') == [name.replace('_', ' ') for name in FAMILY_NAMES]
    # no limit carries a caveat now: studies found every computed limit to hold
    assert all(not candidate['detectable_caveat']
               for candidate in loaded['candidates'] + loaded['extension_candidates'])
    assert 'This limit is' not in summary
    for name in ('paths.png', 'violation_grid.png', 'deciding_statistic.png',
                 'discrepancies.png'):
        assert (tmp_path / name).stat().st_size > 10_000, name
    # where an inadequate model misses is drawn for such a model alone (test_extensions.py)
    assert (tmp_path / 'misfit.png').exists() == (not loaded['adequate'])
    assert ('misfit.png' in summary) == (not loaded['adequate'])
    # each stage timed once, in the documented order (docs/report.md names them all)
    stages = list(loaded['stages_s'])
    assert stages == [stage for stage in STAGES if stage in stages], stages
    assert set(stages) >= {'prepare', 'baseline', 'race', 'final_fit', 'adequacy'}
    assert all(seconds >= 0 for seconds in loaded['stages_s'].values())
    documented = (REPO / 'docs' / 'report.md').read_text()
    assert all(f'`{stage}`' in documented for stage in STAGES)


def test_a_gap_closed_past_its_whole_is_said_as_all_of_it_and_more():
    """A model that scores held-out runs above the calibration runs themselves: 'all and more'."""
    from octoroach_model.diagnosis.summary import _gap_closed, BASELINE_GAP

    assert _gap_closed(0.42, BASELINE_GAP) == "42 % of the baseline's gap"
    assert _gap_closed(1.0, BASELINE_GAP) == "100 % of the baseline's gap"
    said = _gap_closed(4.99, BASELINE_GAP)
    assert said.startswith("all of the baseline's gap and more (499 %") and 'calibration' in said
    assert _gap_closed(float('nan'), 'it') == 'an unmeasured share of it'


def test_the_summary_says_when_the_held_out_runs_are_too_few_for_a_spread_at_any_size():
    """A spread's held-out t tends to sqrt(n / 2) as it grows (docs/diagnosis.md, section 12)."""
    from types import SimpleNamespace

    from scipy import stats

    from octoroach_model.diagnosis.summary import spread_ceiling_line

    level = 0.01 / 14                                 # the first step's, 14 candidates
    power_z = stats.norm.ppf(0.8)

    def line(held_out: int) -> str | None:
        return spread_ceiling_line(SimpleNamespace(steps=[SimpleNamespace(test_level=level)],
                                                   split={'held_out': held_out}))

    said = line(22)                                   # studies/spreads_few_runs.yaml's 45 runs
    assert 'cannot be named at any size' in said and 'sqrt(22 / 2) = 3.3' in said, said
    assert 'cannot reach 80 % power at any size' in line(30)
    total = int(said.split('with about ')[1].split(' runs')[0])
    enough = total // 2
    assert math.sqrt(enough / 2) >= stats.t.isf(level, enough - 1) + power_z
    assert math.sqrt((enough - 1) / 2) < stats.t.isf(level, enough - 2) + power_z
    assert line(enough) is None and line(250) is None and line(enough - 1) is not None


def test_a_statistic_still_off_names_the_term_that_reads_it_and_why_it_was_not_named():
    """
    summary.md links a statistic left off to the unnamed term sized from it (Statistic.read_by).

    An estimate past its limit beside a failed held-out test is a term that describes the runs
    only in part (a leg that wears, docs/measured.md); one within its limit is one the runs
    show too little of; a named term, or a statistic no term reads, gets no line. Where
    several terms read it (the four worn legs read the distance's trend as their own, and
    the heading rate's beside the yaw rate's drift), only those past their limit get one.
    """
    from types import SimpleNamespace

    from octoroach_model.diagnosis.discrepancies import STATISTICS
    from octoroach_model.diagnosis.summary import _reader_lines

    readers = {statistic.name: [cause.name for cause in statistic.read_by()]
               for statistic in STATISTICS if statistic.read_by()}
    legs = [drift_term(f'touchdown_angle_{leg}') for leg in range(1, 5)]
    assert readers['heading rate change from the first run to the last'] == [
        'run_order_drift:yaw_rate', *legs]      # the worn legs read it beside the distance
    assert readers['forward distance change from the first run to the last'] == legs
    for statistic in STATISTICS:        # those that read it as their own, then those beside
        own = [statistic.reads(cause.statistic, cause.signature)
               for cause in statistic.read_by()]
        assert own == sorted(own, reverse=True), statistic.name
        for cause, first in zip(statistic.read_by(), own):
            assert first or statistic.reads(*cause.also_reads), statistic.name
    trend = [statistic.name for statistic in STATISTICS if statistic.read_by()
             and statistic.read_by()[0].order_dependent]
    assert len(trend) == 4      # every run-order drift has its statistic; the legs, the distance
    # a statistic's declared reading is the one its function makes: on any features its
    # value, or its square (a spread, an rms), is a fixed multiple of the term's reading
    from octoroach_model.diagnosis.causes import FeatureStatistic
    from octoroach_model.diagnosis.features import INDEX

    rng = np.random.default_rng(SEED)
    draws = [np.exp(rng.normal(size=(40, len(INDEX)))) for _ in range(3)]
    for statistic in STATISTICS:
        if statistic.reading is None:
            continue
        read = FeatureStatistic(statistic.feature, statistic.reading)
        ratios = [[statistic.function(f) ** power / read(f) for f in draws] for power in (1, 2)]
        assert any(np.allclose(row, row[0], rtol=1e-9) for row in ratios), statistic.name

    def drift(change: float, t: float | None, limit: float = 1.97) -> SimpleNamespace:
        return SimpleNamespace(cause='run_order_drift:yaw_rate', step=1, clears_floor=True,
                               parameters={'parameter': 'yaw_rate', 'change': change},
                               detectable={'change': limit}, held_out_t=t)

    def lines(candidate: SimpleNamespace, named: tuple[str, ...] = (),
              statistic: str = 'heading rate change from the first run to the last'
              ) -> list[str]:
        report = SimpleNamespace(
            unexplained=[SimpleNamespace(statistic=statistic)], candidates=[],
            extension_candidates=[candidate], named_terms=dict.fromkeys(named),
            critical_t=lambda candidate: 3.22)
        return _reader_lines(report)

    said = lines(drift(4.41, 2.56))
    assert len(said) == 1 and 'run order drift (yaw rate) reads' in said[0], said
    assert 'past the 1.97 deg/s' in said[0] and '(t = 2.56 for 3.22)' in said[0], said
    assert 'describes only in part' in said[0], said
    within = lines(drift(1.2, 1.1))
    assert 'within the 1.97 deg/s' in within[0] and 'only in part' not in within[0], within
    assert 'did not clear the floor' in lines(drift(0.1, None))[0]
    assert lines(drift(4.41, 2.56), named=('run_order_drift:yaw_rate',)) == []
    assert lines(drift(4.41, 2.56), statistic='progress spread at the end') == []
    # a worn leg reads the heading rate's trend beside the distance's: a line past its limit
    leg = drift_term('touchdown_angle_4')
    worn = lines(SimpleNamespace(**{**vars(drift(0.0, 1.0)), 'cause': leg,
                                    'parameters': {'parameter': 'touchdown_angle_4',
                                                   'change': -11.0},
                                    'detectable': {'change': 6.0}}))
    assert len(worn) == 1 and '(touchdown angle 4) reads' in worn[0], worn
    assert 'past the 6 deg' in worn[0], worn
    within_leg = SimpleNamespace(**{**vars(drift(0.0, 1.0)), 'cause': leg,
                                    'parameters': {'parameter': 'touchdown_angle_4',
                                                   'change': -3.0},
                                    'detectable': {'change': 6.0}})
    assert lines(within_leg) == []
    distance = 'forward distance change from the first run to the last'  # the four legs' own
    assert lines(within_leg, statistic=distance) == []
    assert len(lines(SimpleNamespace(**{**vars(within_leg), 'parameters': {
        'parameter': 'touchdown_angle_4', 'change': -11.0}}), statistic=distance)) == 1


def test_a_declared_limit_caveat_reaches_the_candidate_and_its_line_in_the_summary(monkeypatch):
    # where studies find a term's limit not to hold, its declaration says so (Cause.limit_caveat)
    # and the report carries it beside the limit, in report.json and in summary.md
    from octoroach_model.diagnosis import records, summary
    from octoroach_model.diagnosis.limits import Limit

    cause = records.BY_NAME['periodic_heading']
    monkeypatch.setitem(records.BY_NAME, cause.name,
                        replace(cause, limit_caveat='possibly optimistic: a study says so'))
    candidate = records.CandidateResult(   # a periodic heading below its floor, unnamed
        cause=cause.name, parameters={'amplitude_deg': 0.3, 'frequency_hz': 0.7}, gain=0.01,
        gain_se=0.02, p_value=0.3, relative=0.0, gain_cm=0.0,
        interval={'amplitude_deg': [0.1, 0.5]}, standard_error=0.1, lower_bound=0.15,
        floor=0.5, detectable={'amplitude_deg': 1.2},
        detectable_method=records.LimitMethod.SIZE_BOUND, detectable_power={},
        clears_floor=False, significant=False, named_here=False, step=1,
        statistic=cause.statistic_name, family=cause.family)
    with_limit = candidate.with_limit(Limit(cause.name, 1.4, 0.95, 0.84))
    assert with_limit.detectable_caveat == 'possibly optimistic: a study says so'
    assert with_limit.detectable == {'amplitude_deg': 1.4}
    line = summary._unseen_line(with_limit, 500)
    assert line.endswith('This limit is possibly optimistic: a study says so.'), line
    none_found = candidate.with_limit(Limit(cause.name, None, 0.0, 0.0))
    assert none_found.detectable_caveat == ''          # no limit, nothing to qualify
    assert 'This limit is' not in summary._unseen_line(none_found, 500)


def test_statistics_that_are_numerical_noise_are_no_discrepancy():
    report = diagnose(om.simulate(120, seed=4, cycles=6), replace(FAST, seed=4))
    start = next(row for row in report.discrepancies if row.statistic == 'start heading spread')
    assert start.z == 0.0 and not start.material     # both 0 up to rounding: not a finding


def test_few_runs_that_happen_to_look_tight_are_not_a_discrepancy():
    """
    Sixty runs against two thousand of the same model: the heading rates' excess kurtosis.

    Every feature is standard normal in data and model alike, so no statistic is off. A few
    runs that happen to be light-tailed bootstrap to a tiny error of their own kurtosis: with
    the data's bootstrap alone, the z of 100 such draws had a mean square of 1.15-3.0 over 16
    seeds (2-12 past 2.58, minimum -3.1 to -6.7). The data's error is now at least the
    model's spread of the statistic at sixty runs: mean square 0.51-0.97 over 17 seeds, the
    check conservative rather than loose (and 0-2 past 2.58, the 1 % level: a count of 100
    draws is too coarse to test on).
    """
    from octoroach_model.diagnosis.discrepancies import discrepancies
    from octoroach_model.diagnosis.features import FEATURES

    rng = np.random.default_rng([SEED, 60])
    model = rng.standard_normal((2000, len(FEATURES)))
    z = []
    for _ in range(100):
        with np.errstate(invalid='ignore'):     # variances of normal noise can be negative
            rows = discrepancies(rng.standard_normal((60, len(FEATURES))), model, rng, 40)
        z.append(next(row.z for row in rows if 'kurtosis' in row.statistic))
    # an honest z has mean square 1; 1.2 lies 3.8 spreads (0.12) above the floor's mean 0.74
    # (the bootstrap alone: below 1.2 at 1 seed of 16)
    assert np.mean(np.square(z)) < 1.2, (np.mean(np.square(z)), sorted(z)[:3], SEED)


def test_the_cost_gap_of_two_fits_has_the_spread_its_bootstrap_says():
    """
    Two fixed models against the average of runs drawn again and again: the gap's spread.

    Whether the runs prefer one valley of the geometry objective to another rests on the cost
    gap's standard error from resampling the runs (`covariance.cost_gap_se`). Runs here are
    random walks (an average path whose samples move together, as a robot's do) with a
    heading and five gait values; two models sit at different places. Over 150 draws of 40
    runs, the gap's actual spread must match the bootstrap's mean estimate: 0.91 and 1.01 of
    it at seeds 1 and 2, where changes drawn sample by sample, as if the path's samples did not
    move together, give 0.58 and 0.61.
    """
    from octoroach_model.fitting.covariance import cost_gap_se, target_changes
    from octoroach_model.fitting.target import AverageTarget, residual_vector, ResidualScales

    rng = np.random.default_rng([SEED, 61])
    n_runs, samples = 40, 60
    t = np.linspace(0.0, 3.0, samples)

    def runs() -> tuple[AverageTarget, np.ndarray]:
        steps = rng.standard_normal((n_runs, samples, 3)) * [0.002, 0.002, 0.01]
        walk = np.cumsum(steps, axis=1) + np.stack([t * 0.1, 0 * t, 0 * t], axis=-1)
        gait = rng.standard_normal((n_runs, 5)) * [0.02, 0.001, 0.001, 0.05, 0.02]
        return AverageTarget(t, walk[..., :2], walk[..., 2], np.zeros(n_runs)), gait

    population, population_gait = runs()
    fixed = population.scales(population_gait)     # a fit's scales are held, as here
    scales = ResidualScales(fixed.path, fixed.turn, fixed.gait, gait_weight=2.0)
    models = [(population.average + offset, population.turn + offset,
               population_gait.mean(axis=0) + offset) for offset in (0.001, -0.002)]

    def residuals(target: AverageTarget, gait: np.ndarray, model: tuple) -> np.ndarray:
        return residual_vector(model[0] - target.average, model[1] - target.turn,
                               model[2] - gait.mean(axis=0), 0.13, scales)

    gaps, estimates = [], []
    for _ in range(150):
        target, gait = runs()
        first, second = (residuals(target, gait, model) for model in models)
        gaps.append(0.5 * (second @ second - first @ first))
        changes = target_changes(target, gait, 0.13, scales, rng, 60)
        estimates.append(cost_gap_se(first, second, changes))
    ratio = np.mean(estimates) / np.std(gaps, ddof=1)
    assert 0.8 < ratio < 1.25, (ratio, SEED)


def test_a_rival_geometry_counts_at_its_weight_and_only_from_another_valley():
    """
    A second valley of the geometry fit enters a statistic's error at the rival's weight.

    Its weight is the chance that the runs, drawn again, prefer it (a cost gap of 0 is even
    odds); the statistic's error then holds the difference between the two fits' values at
    that weight. A fit from another start that ends within two standard errors of the model
    is the model's own valley, and of two rivals in one place only the first is kept.
    """
    from octoroach_model.diagnosis.diagnose import (
        DISCREPANCY_PURPOSE, fit_errors, prepare_halves)
    from octoroach_model.diagnosis.discrepancies import statistic_values
    from octoroach_model.diagnosis.modelfit import (
        distinct_geometries, FittedModel, GeometryUncertainty, RivalGeometry, Simulator)

    measured = om.simulate(40, seed=SEED % 1000, cycles=4)
    data = prepare_halves(measured, FAST).every
    parameters = om.ModelParameters.nominal()
    model = FittedModel(parameters, (0.0, 0.0, 0.0), 1.0)

    def moved(degrees: float) -> FittedModel:
        angles = tuple(a + math.radians(degrees) * sign
                       for a, sign in zip(parameters.touchdown_angles, (1, -1, 1, -1)))
        return replace(model, parameters=replace(
            parameters, touchdown_angles=angles).with_paper_liftoff())

    errors = np.array([0.001] + [math.radians(1.0)] * 4 + [0.05])     # leg, angles, stride
    uncertainty = GeometryUncertainty((), np.diag(errors ** 2))
    near, far, again = moved(1.5), moved(6.0), moved(6.2)
    assert distinct_geometries((model, uncertainty), [near, far, again]) == (far.parameters,)

    simulator = Simulator(data, FAST.seed)
    rival = far
    even = RivalGeometry(rival, cost_gap=0.0, gap_se=100.0)
    unlikely = RivalGeometry(rival, cost_gap=300.0, gap_se=100.0)     # weight 0.00135
    assert even.weight == pytest.approx(0.5) and unlikely.weight == pytest.approx(0.00135,
                                                                                  rel=0.01)
    difference = (statistic_values(simulator.features(rival, 400, DISCREPANCY_PURPOSE))
                  - statistic_values(simulator.features(model, 400, DISCREPANCY_PURPOSE)))
    for candidate in (even, unlikely):
        error = fit_errors(simulator, model, None, 400, rivals=[candidate])
        assert error is not None
        np.testing.assert_allclose(error, np.sqrt(candidate.weight) * np.abs(difference),
                                   rtol=1e-9, atol=1e-15)
    assert np.nanmax(np.abs(difference)) > 0       # the far rival differs in some statistic


def test_the_final_model_is_the_fit_of_lowest_cost_on_all_runs_whichever_valley_it_is_in():
    """
    The final fit starts from the race's model and from it in every other valley found.

    The calibration half chose a valley the runs may not tell from another; on all runs the
    fit of lowest cost is the model a report states, the others that end elsewhere its
    rivals, and with no other valley the race's model alone is refit, as before.
    """
    from octoroach_model.diagnosis.diagnose import final_starts, lowest_cost
    from octoroach_model.diagnosis.modelfit import CausesFit, FittedModel, GeometryUncertainty

    parameters = om.ModelParameters.nominal()
    model = FittedModel(parameters, (0.0, 0.0, 0.0), 1.2, {'lateral_slip': {
        'velocity_cm_s': 0.5}})
    away = tuple(angle + math.radians(6.0) * sign        # 6 deg from the model's angles
                 for angle, sign in zip(parameters.touchdown_angles, (1, -1, 1, -1)))
    swapped = replace(parameters, sample_rate=200.0, touchdown_angles=away)
    starts = final_starts(model, [swapped])
    assert starts[0] is model and len(starts) == 2
    other = starts[1]
    assert other.parameters.touchdown_angles == swapped.touchdown_angles
    assert other.parameters.sample_rate == parameters.sample_rate      # the model's clock
    assert other.effects == model.effects and other.sigma_scale == model.sigma_scale
    assert final_starts(model, []) == [model]

    covariance = np.diag(np.array([0.001] + [math.radians(1.0)] * 4 + [0.05]) ** 2)

    def fitted(start: FittedModel, cost: float) -> CausesFit:
        return CausesFit(start, {}, GeometryUncertainty((), covariance, cost))

    race, far, same = fitted(model, 500.0), fitted(other, 400.0), fitted(model, 450.0)
    chosen = lowest_cost([race, far])
    assert chosen.model is other and chosen.alternatives == (model.parameters,)
    kept = lowest_cost([far, race])                # the same, whatever the order
    assert kept.model is other and kept.alternatives == (model.parameters,)
    assert lowest_cost([race, fitted(other, 600.0)]).model is model
    assert lowest_cost([race, same]).alternatives == ()   # one valley: no rival
    assert lowest_cost([race]) is race


def test_a_start_heading_spread_of_exactly_zero_still_gets_a_detection_limit():
    """
    Runs simulated without a start heading spread have a variance of 1e-32 rad^2.

    The ratio of its rounding errors (0.37 here) once passed for the statistic's relative
    error and left 2 of 10 null data sets of studies/limits.yaml without a limit for
    initial_pose_error. The figures are those of replicate 4 of that study.
    """
    from octoroach_model.diagnosis.decide import decision_z, judge
    from octoroach_model.diagnosis.limits import bound_power
    from octoroach_model.diagnosis.modelfit import SizeEstimate

    zero = SizeEstimate('initial_pose_error', size=1.40e-14, se=3.11e-15, u=1.97e-28,
                        se_u=8.73e-29, intercept=7.78e-33, slope=3.098e-4,
                        data_statistic=6.89e-32, data_se=2.52e-32, intercept_se=9.74e-33,
                        relative_se=0.0942)
    z = decision_z(0.05, 6)
    limit = judge(zero, 0.5, z).limit
    assert limit is not None and 0.5 < limit < 0.7, limit
    assert bound_power(zero, limit, 0.5, z) == pytest.approx(0.8, abs=1e-6)
    # a real level keeps the data's own error (here 3x what the simulated runs show)
    real = replace(zero, data_statistic=1e-4, data_se=0.3e-4, intercept=1e-4)
    assert judge(real, 0.5, z).limit > 1.2 * judge(replace(real, data_se=0.0), 0.5, z).limit


def test_the_noise_limit_carries_the_error_of_a_statistic_with_noise_in_it():
    """
    On a null the noise statistic is the motion's alone: 1.2 % relative error, 0.55 % with noise.

    Carried to the whole level, the null's relative error doubled the limit's margin above
    the floor (0.010218 cm), and noise at 1x the limit was named 20/20 in studies/limits.yaml.
    The figures are those of replicate 0 of that study.
    """
    from octoroach_model.diagnosis.decide import data_se_if_true, decision_z, judge
    from octoroach_model.diagnosis.limits import bound_power
    from octoroach_model.diagnosis.modelfit import SizeEstimate

    null = SizeEstimate('measurement_noise', size=2.90e-7, se=2.1e-7, u=8.424e-14,
                        se_u=1.77e-13, intercept=1.147e-15, slope=1.054e-4,
                        data_statistic=1.156e-15, data_se=1.42e-17, intercept_se=1.21e-17,
                        relative_se=0.00545, slope_relative_se=0.00424,
                        reference_slope_relative_se=0.00449)
    z, floor = decision_z(0.05, 6), 0.01
    limit = judge(null, floor, z).limit
    assert limit is not None and floor < limit < 0.01015, limit
    assert bound_power(null, limit, floor, z) == pytest.approx(0.8, abs=1e-6)
    level = null.intercept + null.slope * limit ** 2
    assert data_se_if_true(null, limit ** 2, floor) == pytest.approx(
        null.relative_se * level, rel=0.01)


def test_a_slope_taken_near_zero_does_not_keep_a_limit_from_being_found():
    """
    On a null the slope is taken near zero, where its relative error is large (39 % here).

    Held over every size a limit is sought at, it kept the size bound from ever clearing the
    floor: no limit for persistent_turning on 2 of 8 null data sets of studies/limits.yaml
    (these are replicate 0's figures). The limit uses the slope's error at the reference size.
    """
    from octoroach_model.diagnosis.decide import decision_z, judge
    from octoroach_model.diagnosis.limits import bound_power
    from octoroach_model.diagnosis.modelfit import moments_se_u, SizeEstimate

    null = SizeEstimate('persistent_turning', size=0.393, se=0.345, u=0.155, se_u=0.476,
                        intercept=1.337e-3, slope=3.446e-4, data_statistic=1.390e-3,
                        data_se=1.348e-4, intercept_se=9.10e-5, relative_se=0.0880,
                        slope_relative_se=0.390, reference_slope_relative_se=0.0973)
    z, floor = decision_z(0.05, 6), 0.16
    limit = judge(null, floor, z).limit
    assert limit is not None and 1.0 < limit < 5.0, limit
    assert bound_power(null, limit, floor, z) == pytest.approx(0.8, abs=1e-6)
    # the estimate's own interval keeps the error of the slope it was read with
    assert null.se_u == pytest.approx(moments_se_u(null, null.u), rel=0.01)


def test_a_limit_set_by_the_test_is_solved_where_t_was_computed_not_on_a_chord():
    """
    T of a variance effect bends in log-log (s^4 small, s^2 later): a chord lies below it.

    Solved on the chord between two sizes the limit came out too large (persistent_turning
    named 20/20 at 1x in studies/limits.yaml); with T computed again at the limit found, the
    power there is the one claimed. `bend` is such a curve, the floor far below.
    """
    from scipy import optimize

    from octoroach_model.diagnosis.limits import _solve, limit_from, t_interpolated
    from octoroach_model.diagnosis.modelfit import SizeEstimate

    def bend(size: float) -> float:
        return 3.0 * size ** 4 / (1 + size ** 2)

    sure = SizeEstimate('persistent_turning', size=0.0, se=0.0, u=0.0, se_u=0.0,
                        intercept=1.0, slope=1.0, data_statistic=1.0)   # the bound is certain
    z_test, z_bound, floor = 2.935, 2.9, 1e-3
    chord = {1.0: bend(1.0), 3.0: bend(3.0)}
    assert t_interpolated(chord, 1.0) == pytest.approx(bend(1.0))
    assert t_interpolated(chord, 2.0) < bend(2.0)                   # the chord is low inside
    assert math.log(t_interpolated(chord, 9.0) / bend(3.0)) == pytest.approx(
        math.log(bend(3.0) / bend(1.0)))                            # end segments extended
    truth = optimize.brentq(lambda s: bend(s) - z_test - 0.841621, 1.0, 3.0)
    on_chord = _solve(chord, sure, floor, z_bound, z_test)
    refined = limit_from(bend, 1.0, sure, floor, z_bound, z_test)
    assert on_chord.size > 1.03 * truth                             # the old answer: too large
    assert refined.size == pytest.approx(truth, rel=0.01)
    assert refined.test_power == pytest.approx(0.8, abs=0.005)
    assert refined.size_bound_power == 1.0


def test_a_path_familys_limit_weighs_its_screen_and_its_refits_bound_each_at_its_own_z():
    """
    A path family is screened on a quick estimate, then sized by the refit with the geometry.

    Its limit took the quick estimate's error at the decision's z, as if the screen were the
    bound: yaw_rate_ramp's limit said its size bound decided (P 0.80) where the refit's
    bound, half as wide, cleared by far and the held-out test decided (docs/diagnosis.md,
    section 8). Now P(bound) is the screen's, at z - SCREEN_ALLOWANCE, times the refit's.
    """
    from scipy import stats

    from octoroach_model.diagnosis import limits
    from octoroach_model.diagnosis.decide import SCREEN_ALLOWANCE
    from octoroach_model.diagnosis.modelfit import SizeEstimate

    quick = SizeEstimate('yaw_rate_ramp', size=0.0, se=0.74)
    refit = SizeEstimate('yaw_rate_ramp', size=0.0, se=0.37)
    floor, z_bound, z_test = 0.2, 2.69, 3.19
    for size in (1.0, 2.8, 4.0):
        screen = stats.norm.cdf((size - floor - (z_bound - SCREEN_ALLOWANCE) * 0.74) / 0.74)
        bound = stats.norm.cdf((size - floor - z_bound * 0.37) / 0.37)
        assert limits.bound_power(refit, size, floor, z_bound, quick) == pytest.approx(
            screen * bound, rel=1e-12)
    assert limits.bound_power(refit, 2.8, floor, z_bound, quick) > 0.99 > 0.8 > (
        limits.bound_power(quick, 2.8, floor, z_bound))      # the quick error at the full z
    # a quick estimate without an error (its signature flat) is screened out: never named
    flat = SizeEstimate('yaw_rate_ramp', size=0.0, se=math.inf)
    assert limits.bound_power(refit, 5.0, floor, z_bound, flat) == 0.0

    def sure(size: float) -> float:                  # the test certain: the bounds decide
        return 1e6

    alone = limits.limit_from(sure, 1.0, quick, floor, z_bound, z_test)
    screened = limits.limit_from(sure, 1.0, refit, floor, z_bound, z_test, screen=quick)
    assert screened.size < alone.size
    assert screened.size_bound_power == pytest.approx(0.8, abs=0.005)
    assert limits.bound_power(refit, screened.size, floor, z_bound, quick) == pytest.approx(
        screened.size_bound_power)


def test_a_mixture_whose_two_groups_show_only_further_up_still_gets_a_limit(monkeypatch):
    """
    P3 (two groups seen) is held at its last value beyond the sizes simulated.

    Where it was still low at 3 times the first size, no size reached 80 % and a null of
    studies/mixture_limits.yaml reported run_mixture unseen at any size; the limit now
    simulates further up (9 and 27 times) before saying so.
    """
    from octoroach_model.diagnosis import limits
    from octoroach_model.diagnosis.modelfit import SizeEstimate

    def shown(size: float) -> limits.TestPoint:      # the test is sure; the groups show late
        return limits.TestPoint(50.0, min(1.0, (size / 20.0) ** 2))

    sure = SizeEstimate('run_mixture', size=0.0, se=1e-6, u=0.0, se_u=0.0, intercept=0.0,
                        slope=1.0, data_statistic=0.0)
    found = limits.limit_from(shown, 1.0, sure, 0.1, 2.9, 2.935)
    assert found.size is not None and 9.0 < found.size < 27.0, found
    assert found.two_groups_power == pytest.approx(0.8, abs=0.01)
    assert found.size_bound_power == 1.0 and found.test_power == 1.0
    sizes: list[float] = []                           # a bound that never clears: no more runs

    def counted(size: float) -> limits.TestPoint:
        sizes.append(size)
        return shown(size)

    flat = SizeEstimate('persistent_turning', size=0.0, se=0.1, u=0.0, se_u=0.1, intercept=0.0,
                        slope=0.0, data_statistic=0.0)
    assert limits.limit_from(counted, 1.0, flat, 0.1, 2.9, 2.935).size is None
    assert sizes == [1.0, 3.0]
    monkeypatch.setattr(limits, 'FURTHER_UP', 0)     # as it was: two sizes only
    assert limits.limit_from(shown, 1.0, sure, 0.1, 2.9, 2.935).size is None


def test_a_limit_is_never_sought_beyond_the_sizes_a_path_cause_can_take():
    """
    A speed decay's T extrapolated from small sizes once put its limit at a fraction of 3.5.

    Simulated there, the gait clock ran backwards and the diagnosis of a small null data set
    ended in "stride_frequency ... must be positive" (test_studies_dask at seed 185463). No
    size past the cause's bound is computed; a limit that lies past it is none. A mixture's
    was put at thousands of deg/s, where the model's turning runs stop at 90.
    """
    from octoroach_model.diagnosis import limits
    from octoroach_model.diagnosis.causes import BY_NAME, EstimateKind
    from octoroach_model.diagnosis.modelfit import at_size, largest_size, SizeEstimate
    from octoroach_model.model.effects import mean_gait_rate

    for cause in (c for c in BY_NAME.values() if c.kind == EstimateKind.PATH):
        for values in ({}, *({cause.parameter: cause.null + step} for step in (0.1, -0.1))):
            largest = largest_size(cause, values)
            edge = at_size(cause, largest, values)[cause.parameter]
            assert min(cause.bounds) - 1e-12 <= edge <= max(cause.bounds) + 1e-12, (cause, edge)
            effects = {cause.name: at_size(cause, largest, values)}
            assert mean_gait_rate(effects, 10.0) > 0, (cause.name, values)
    # a moments or trend term stops where the model's range for its parameter does: the
    # model simulates the edge and refuses anything past it
    from octoroach_model.errors import ParameterError
    from octoroach_model.model import check_effects
    bounded_kinds = (EstimateKind.MOMENTS, EstimateKind.TREND)
    for cause in (c for c in BY_NAME.values() if c.kind in bounded_kinds):
        largest = largest_size(cause)
        assert 0 < largest < math.inf, cause.name
        check_effects({cause.name: at_size(cause, largest)})
        with pytest.raises(ParameterError):
            check_effects({cause.name: at_size(cause, 1.01 * largest)})
    # a mixture's yaw rate stops at the model's edge: past it every size is the same runs, and
    # on 60 runs its held-out t saturated and was extrapolated to limits of 200-25 000 deg/s
    mixture = BY_NAME['run_mixture']
    for fraction in (0.3, 0.1, 0.0):
        values = {'fraction': fraction, 'yaw_rate_deg_s': -4.0}
        edge = at_size(mixture, largest_size(mixture, values), values)
        assert edge['yaw_rate_deg_s'] == pytest.approx(-90.0), (fraction, edge)
        assert at_size(mixture, 0.99 * largest_size(mixture, values), values)[
            'yaw_rate_deg_s'] > -90.0
    sizes: list[float] = []

    def slow(size: float) -> float:                  # 80 % power only at size 4
        sizes.append(size)
        return (2.935 + 0.841621) * size / 4.0

    sure = SizeEstimate('speed_decay', size=0.0, se=0.0, u=0.0, se_u=0.0,
                        intercept=1.0, slope=1.0, data_statistic=1.0)
    assert limits.limit_from(slow, 0.5, sure, 1e-3, 2.9, 2.935).size == pytest.approx(4.0)
    sizes.clear()
    assert limits.limit_from(slow, 0.5, sure, 1e-3, 2.9, 2.935, largest=0.9).size is None
    assert max(sizes) == 0.9 and sizes[0] == pytest.approx(0.3)
    within = limits.limit_from(slow, 0.5, sure, 1e-3, 2.9, 2.935, largest=5.0)
    assert within.size == pytest.approx(4.0) and max(sizes) <= 5.0


@pytest.mark.parametrize('cause, size', [('persistent_turning', 6.0),
                                         ('gait_frequency_variation', 0.04)])
def test_a_moments_size_counts_the_error_of_its_simulated_slope(cause, size):
    """
    The slope of S(u) comes from runs that draw the cause afresh: 7 % error at 400 runs.

    It was left out of the size's standard error, and the reported 95 % intervals of the
    moments causes held the truth in 81-84 % of the studies' data sets. The simulation's part
    of the error must be the spread of the estimate over simulation seeds on the same data.
    """
    from octoroach_model.diagnosis.causes import BY_NAME
    from octoroach_model.diagnosis.modelfit import (
        FitSettings, fit_moment, FittedModel, moments_se_u, RunData, Simulator)
    from octoroach_model.fitting import mean_start_pose

    measured = om.simulate(200, seed=SEED, cycles=6,
                           effects={cause: {main_parameter(cause): size}})
    start = mean_start_pose(measured)
    nominal = om.ModelParameters.nominal()
    data = RunData(measured, nominal.stride_frequency, start[2])
    model = FittedModel(nominal, start, 1.0)
    estimates = [fit_moment(Simulator(data, SEED + k), model, BY_NAME[cause],
                            FitSettings(moment_runs=200, seed=SEED + k), n_boot=60)
                 for k in range(64)]
    spread = float(np.std([e.u for e in estimates], ddof=1))
    simulation_part = float(np.median([moments_se_u(e, e.u, 0.0) for e in estimates]))
    intercept_only = float(np.median([e.intercept_se / e.slope for e in estimates]))
    # The spread of 64 estimates is itself uncertain: over 30 seeds of this test (100 apart)
    # the ratio's log spread 0.08-0.10 around 1.05, so these bounds lie 4.6 of those spreads
    # away and more. With 16 estimates (log spread 0.2) the bound 1.6 failed in CI (1.64,
    # seed 176423); the old error, the intercept's alone, puts the ratio at 5 and above.
    assert 0.6 < spread / simulation_part < 1.7, (spread, simulation_part, SEED)
    assert spread > 2 * intercept_only, (spread, intercept_only, SEED)    # the old error


@pytest.mark.parametrize('data_seed', [2, 4, SEED])
def test_the_geometry_fit_keeps_the_sway_of_long_finely_sampled_runs(data_seed):
    """
    Thirty runs of 34 strides at 126 samples a stride, fitted from the robot's own geometry.

    With each sway residual weighed as one sample of the average path, the fit left the robot
    for angles that follow the chance wander of the runs' average path (seeds 2 and 4: the
    sideways sway at the stride frequency 6.2 and 5.3 standard errors off the data's) and the
    adequacy study called exact models inadequate. Weighed as a stride's samples, the fitted
    model's sway matches the data's.
    """
    from octoroach_model.diagnosis.modelfit import (
        FitSettings, fit_geometry, FittedModel, RunData)
    from octoroach_model.fitting import mean_start_pose
    from octoroach_model.fitting.gait import stride_samples, gait_features

    robot = replace(om.ModelParameters.nominal(), leg_length=0.0238,
                    touchdown_angles=(0.915, 0.614, 0.761, 0.685), stride_frequency=1.5,
                    sample_rate=189.0).with_paper_liftoff()
    scale = 0.58
    sigma1, sigma2 = (scale * sigma for sigma in om.model.nominal_sigmas())
    measured = om.simulate(30, seed=data_seed, cycles=34, parameters=robot, sigma1=sigma1,
                           sigma2=sigma2)
    start = mean_start_pose(measured)
    fitted, _, _ = fit_geometry(RunData(measured, 1.5, start[2]),
                                FittedModel(robot, start, scale), (),
                                FitSettings(mean_path_runs=200, rounds=1, seed=data_seed))
    model_runs = om.simulate(400, seed=data_seed + 1, cycles=34, parameters=fitted.parameters,
                             sigma1=sigma1, sigma2=sigma2, start_pose=start)

    def sideways_sway(paths: om.Paths) -> tuple[float, float]:
        cycle = stride_samples(1.5, float(paths.t[1] - paths.t[0]))
        sway = gait_features(paths.t, paths.poses[..., :2], paths.poses[..., 2], 1.5, cycle)[:, 1]
        return float(sway.mean()), float(sway.std(ddof=1) / math.sqrt(len(sway)))

    (data, data_se), (model, model_se) = sideways_sway(measured), sideways_sway(model_runs)
    z = (data - model) / math.hypot(data_se, model_se)
    assert abs(z) < 3.0, (z, fitted.parameters.touchdown_angles, SEED)


def test_a_speed_decay_enters_at_the_strides_the_runs_show():
    """
    A baseline fitted to decaying runs bends its legs and slows its strides to mimic the decay.

    Entering the decay at the baseline's stride frequency took a fifth of the strides from
    every run; the joint fit then stayed with bent legs (2.1 -> 3.1 cm, the stride frequency
    1.76 of 2 Hz), and the held-out log score fell by 34 nats per run: the decay, sized
    right, went unnamed (suite seed 271828; three two-cause study data sets alike). The
    decay now enters at the strides the runs show and the fit finds the robot again. (Since
    the geometry fit matches the runs' mean stride frequency the baseline bends less, 2.8 cm
    at 1.63 Hz, and the decay's gain over it is 7.5 nats per run rather than 39; the decay's
    own model scores the same.)
    """
    from octoroach_model.diagnosis.diagnose import (
        evaluate_candidate, fit_baseline, prepare_halves, score_held_out, Simulator)

    measured = om.simulate(N_RUNS, seed=271828, effects={'speed_decay': {'fraction': 0.3735}})
    fast = replace(FAST, seed=271828)
    halves = prepare_halves(measured, fast)
    baseline = fit_baseline(halves, fast).model
    scores = score_held_out(Simulator(halves.test, fast.seed), baseline, halves, fast)
    decay = evaluate_candidate(halves, baseline, scores, 'speed_decay', fast)
    robot = decay.model.parameters
    assert robot.stride_frequency == pytest.approx(2.0, rel=0.02)
    assert robot.leg_length == pytest.approx(om.ModelParameters.nominal().leg_length, rel=0.05)
    assert decay.estimates['speed_decay'].size == pytest.approx(0.3735, rel=0.1)
    assert decay.gain.mean > 5 and decay.gain.p_value < 1e-6, decay.gain


def test_a_change_point_held_at_a_time_is_sized_there_by_its_step_and_its_refit():
    """
    Where change_point's limit is stated (half the runs), both of its estimates are made.

    The limit weighs the step it is screened on and the joint refit that sizes it at the
    time the limit is stated, not where a null data set's step peaked (diagnose.
    path_family_estimates): the time is held, the factor alone fitted.
    """
    from octoroach_model.diagnosis.modelfit import (
        change_point_step, fit_causes, FitSettings, free_parameters)

    simulator, without = paper_runs(200)
    duration = float(simulator.data.paths.t[-1])
    held = 0.4 * duration           # off the step's grid of 10-90 % of the run
    change = BY_NAME['change_point']
    assert [name for name, _ in free_parameters(change, simulator.data)] == \
        ['speed_factor', 'time_s']
    assert [name for name, _ in free_parameters(change, simulator.data, held)] == \
        ['speed_factor']
    values, error = change_point_step(simulator, without, 20, held)
    assert values['time_s'] == held and error > 0
    fit = FitSettings(moment_runs=150, mean_path_runs=100, seed=SEED, change_time_s=held)
    refit = fit_causes(simulator.data, without, ('change_point',), fit, rounds=1)
    assert refit.model.effects['change_point']['time_s'] == held
    estimate = refit.estimates['change_point']
    # the paper's runs: no change, sized within a few errors of none, and no time fitted
    assert 0 < estimate.se < 0.02 and abs(estimate.size - 1) < 4 * estimate.se, replay(
        f'{estimate}')
    assert 'time_s' not in estimate.others


def test_a_change_points_screen_is_simulated_and_counted_in_its_size_bounds_part():
    """
    change_point's limit takes its screen's chance from the screen run on simulated runs.

    The race screens it on a step that seeks the change's time too, whose error depends on how
    clearly the runs show that time; the limit runs that step on calibration-sized subsets of
    runs simulated with the change (limits.screen_power). A clear change passes every time
    a floor it is clear of; the share enters the size bound's part of the limit.
    """
    from octoroach_model.diagnosis import limits
    from octoroach_model.diagnosis.modelfit import at_size, FitSettings, SizeEstimate

    simulator, without = paper_runs(200)
    scales = np.ones(len(INDEX))
    fit = FitSettings(moment_runs=150, mean_path_runs=100, seed=SEED)
    base = limits.limit_base(simulator, without, scales, 300)
    change = BY_NAME['change_point']
    values = at_size(change, 0.15, None, simulator.data)
    pair = limits.simulated_pair(simulator, without, base, change, 0.15, scales, 300, values,
                                 fit)
    # a clear change clears a floor of 1 % on every subset, never one of 50 % (the race's rule,
    # decide.out_of_reach, on the step taken as the race takes it)
    shares = [limits.screen_power(simulator, pair, 100, floor, 1.0) for floor in (0.01, 0.5)]
    assert shares == [1.0, 0.0], replay(f'{shares}')
    point = limits.expected_t(simulator, without, base, change, 0.15, scales, 100, 300,
                              values, fit, None, None, (0.01, 1.0))
    # every subset passes, so what the runs show is the chance that the change gains more than
    # the speed decay the race might add in its place (near 1 here; 0.987 at seed 1717)
    look_alike = limits.look_alike_power(simulator, pair, change,
                                         pair.gains(simulator, scales, 300), scales, 100, 300,
                                         fit)
    assert point.identified == pytest.approx(look_alike), replay(f'{point}, {look_alike}')
    # in the limit: P1 is the refit's bound times the simulated screen's share
    estimate = SizeEstimate('change_point', 1.0, 0.001)
    limit = limits.limit_from(lambda size: limits.TestPoint(40 * size, min(5 * size, 1.0)),
                              0.02, estimate, 0.01, 2.0, 3.0)
    assert limit.screen_power is not None and 0.8 <= limit.screen_power < 1.0, limit
    assert limit.two_groups_power is None
    assert limit.size_bound_power == pytest.approx(
        limits.bound_power(estimate, limit.size, 0.01, 2.0) * limit.screen_power)
    assert limit.simulated_power == pytest.approx(limit.test_power * limit.screen_power)


def test_a_change_points_limit_weighs_the_chance_that_a_speed_decay_is_added_in_its_place():
    """
    change_point's limit weighs its look-alike, speed_decay, fitted to runs with the change.

    A decay of the gait clock over the run takes up much of a change at its middle, and the
    race adds, of the terms that qualify, the one of the largest held-out gain: in
    studies/clock_terms.yaml speed_decay was named in change_point's place at its limit. The
    limit fits speed_decay to the runs simulated with the change (a least-squares line
    through a step of 1 - factor at half the run has a slope of 1.5 (1 - factor) per run, the
    mean rate kept) and weighs P(the change gains more than it), which is part of P1. On so
    few short runs the two are near each other: P varied from 0.45 to 1 for a change of 10 %
    over suite seeds (not asserted). P is Phi of a t from 300 simulated runs, itself a draw:
    over 51 seeds it was 0.978 to 1 at a change of 20 % (below 0.99 at seed 772875, where
    this test asked 0.99 of it and failed) and above 0.9999 at every seed at 30 %, which
    is asserted. The look-alike's fit is checked at 10 and 20 % (at 30 % the least-squares
    line's mean rate was 1.01 % off at seed 32).
    """
    from octoroach_model.diagnosis import limits
    from octoroach_model.diagnosis.modelfit import at_size, FitSettings
    from octoroach_model.model.effects import mean_gait_rate

    simulator, without = paper_runs(200)
    scales = np.ones(len(INDEX))
    fit = FitSettings(moment_runs=150, mean_path_runs=100, seed=SEED)
    base = limits.limit_base(simulator, without, scales, 300)
    change = BY_NAME['change_point']
    assert change.look_alike == 'speed_decay'
    duration = float(simulator.data.paths.t[-1])
    shares = {}
    for size in (0.1, 0.2, 0.3):
        values = at_size(change, size, None, simulator.data)
        pair = limits.simulated_pair(simulator, without, base, change, size, scales, 300,
                                     values, fit)
        if size < 0.3:
            look_alike = limits.look_alike_model(simulator, pair, change, fit)
            fraction = look_alike.effects['speed_decay']['fraction']
            rate = (look_alike.parameters.stride_frequency
                    * mean_gait_rate(look_alike.effects, duration))
            message = replay(f'a change of {size}: decay {fraction}, mean rate {rate} Hz, the '
                             f'model without it {pair.without.parameters.stride_frequency} Hz')
            assert fraction == pytest.approx(1.5 * size, rel=0.2), message
            assert rate == pytest.approx(pair.without.parameters.stride_frequency,
                                         rel=0.01), message
        shares[size] = limits.look_alike_power(simulator, pair, change,
                                               pair.gains(simulator, scales, 300), scales, 100,
                                               300, fit)
    assert shares[0.3] > 0.99, replay(f'P(added before speed_decay) by size: {shares}')
    # the share is part of what the runs show (P3's place), so of P1 in the limit
    point = limits.expected_t(simulator, without, base, change, 0.1, scales, 100, 300,
                              at_size(change, 0.1, None, simulator.data), fit)
    assert point.identified == pytest.approx(shares[0.1]), replay(f'{point}, {shares}')


@pytest.mark.long
def test_a_slip_against_the_robots_own_crab_is_found_with_its_sign():
    """
    The slip's refit keeps the valley whose model predicts the calibration runs best.

    The robot of limits.yaml's replicate 3 (angles 48.7, 38.5, 41.7, 47.4 deg) crabs one way,
    its slip of -0.36 cm/s the other; here with 200 runs at 50 Hz, on a fixed seed (2) whose
    runs lead the baseline into the valley (at seeds 3 and 4 they did not). The baseline bends
    to the net crab, and from the current geometry and from equal angles the slip's refit
    ended at +0.08 cm/s, a held-out loss of 0.41 nats per run: the slip went unnamed (the
    study missed it at twice its limit). From Table II's angles it ends near the robot; a lower
    least-squares cost alone would not do (docs/diagnosis.md section 3), so the ends are
    compared by the calibration runs' log score (`modelfit.best_valley`).
    """
    from octoroach_model.diagnosis.diagnose import (
        choose_wobble_hz, evaluate_candidate, fit_baseline, halves_as_diagnosed,
        score_held_out, Simulator, with_wobble)

    robot = replace(om.ModelParameters.nominal(), leg_length=0.022713, stride_frequency=1.61339,
                    touchdown_angles=tuple(np.radians([48.693, 38.452, 41.700, 47.401])),
                    sample_rate=50.0).with_paper_liftoff()
    sigma1, sigma2 = om.model.nominal_sigmas()
    measured = om.simulate(200, seed=2, cycles=13.3, parameters=robot, sigma1=0.9845 * sigma1,
                           sigma2=0.9845 * sigma2,
                           effects={'lateral_slip': {'velocity_cm_s': -0.36}})
    fast = replace(FAST, seed=2)
    halves = halves_as_diagnosed(measured, fast)
    baseline = fit_baseline(halves, fast).model
    halves = with_wobble(halves, choose_wobble_hz(halves.train, baseline, fast))
    scores = score_held_out(Simulator(halves.test, fast.seed), baseline, halves, fast)
    slip = evaluate_candidate(halves, baseline, scores, 'lateral_slip', fast)
    estimate = slip.estimates['lateral_slip']
    message = f'slip {estimate.size:+.3f} +- {estimate.se:.3f} cm/s, gain {slip.gain}'
    assert abs(estimate.size + 0.36) < 3 * estimate.se, message
    assert slip.gain.mean > 0.3 and slip.gain.p_value < 1e-6, message


def test_too_few_runs_are_refused_with_a_reason():
    with pytest.raises(om.DataError, match='at least 40 runs'):
        diagnose(om.simulate(10, seed=1))


@pytest.mark.long
def test_the_diagnosis_is_reproducible_for_a_seed():
    measured = om.simulate(60, seed=4, cycles=6, effects={'persistent_turning':
                                                          {'yaw_rate_std_deg_s': 10.0}})
    quick = replace(FAST, seed=2, **FEW_SIMULATED_RUNS)   # reproducible at any size
    first, second = diagnose(measured, quick), diagnose(measured, quick)
    first_json, second_json = first.to_json(), second.to_json()
    for volatile in ('elapsed_s', 'stages_s'):
        first_json.pop(volatile), second_json.pop(volatile)
    assert first_json == second_json


def test_the_split_seed_keeps_the_halves_while_the_seed_draws_the_simulations_again():
    """With split_seed the halves stay where the seed moves (bench_seed_agreement.py)."""
    from octoroach_model.diagnosis.diagnose import halves_as_diagnosed

    measured = om.simulate(40, seed=SEED, cycles=3)

    def held_out(**seeds: int) -> np.ndarray:
        return halves_as_diagnosed(measured, DiagnosisSettings(**seeds)).test.paths.poses

    assert np.array_equal(held_out(seed=5, split_seed=7), held_out(seed=7))
    assert np.array_equal(held_out(seed=7, split_seed=None), held_out(seed=7))
    assert not np.array_equal(held_out(seed=5), held_out(seed=7))


@pytest.mark.parametrize('effects', [
    {'speed_decay': {'fraction': 0.2}},
    {'persistent_turning': {'yaw_rate_std_deg_s': 8.0}},
])
@pytest.mark.long
def test_runs_that_end_early_keep_the_sizes_of_the_full_duration(effects):
    """
    Runs that end early must not bend the sizes of the full duration.

    A quarter of the runs leaving the capture volume at 70-95 % of the duration must not bend
    the sizes (with a common duration, speed_decay 0.2 was once read as 0.139).

    The size may miss by 15 % or by three of its reported standard errors, whichever is wider:
    persistent_turning's error here is about 7 % of its size, so a fixed 15 % is about two of
    them and fails about 4 % of seeds where the error is right (suite seed 473147: 9.21 for
    8.0, interval 8.01-10.27); speed_decay's is about 2 %, so its band stays 15 %. Either band
    still fails the bias of 30 % this test was written for.
    """
    cause = next(iter(effects))
    truth = effects[cause][main_parameter(cause)]
    full = om.simulate(N_RUNS, seed=SEED + 12, effects=effects)
    rng = np.random.default_rng(SEED)
    lengths = np.full(full.n_paths, len(full.t))
    early = rng.permutation(full.n_paths)[:full.n_paths // 4]
    lengths[early] = (rng.uniform(0.7, 0.95, len(early)) * len(full.t)).astype(int)
    report = diagnose(full.cut_to(lengths), settings(12))
    found = named_sizes(report)
    message = f'{replay(f"{effects} with {len(early)} runs cut short")}: named {found}'
    assert set(found) == {cause}, message
    standard_error = next(c for c in report.causes
                          if c.cause == cause).standard_error[main_parameter(cause)]
    band = max(0.15 * truth, 3.0 * standard_error)
    assert abs(found[cause] - truth) <= band, f'{message}, standard error {standard_error:.3g}'
    assert report.runs.ended_early == len(early)


def test_the_evidence_of_two_groups_counts_in_a_mixtures_limit():
    """P3: two groups of heading rates are seen where they stand apart, not in one normal."""
    from octoroach_model.diagnosis.features import FEATURES, INDEX
    from octoroach_model.diagnosis.limits import two_groups_power

    rng = np.random.default_rng(SEED)
    column = INDEX['heading_rate']
    without = np.zeros((1000, len(FEATURES)))
    without[:, column] = rng.normal(0.0, 0.02, 1000)

    def runs(separation: float) -> np.ndarray:
        features = np.zeros((1000, len(FEATURES)))
        turning = rng.random(1000) < 0.3
        features[:, column] = rng.normal(0.0, 0.02, 1000) + separation * turning
        return features

    apart, together, wider = runs(0.12), runs(0.0), runs(0.0)
    wider[:, column] *= 2.0            # one normal, only wider: persistent turning
    assert two_groups_power(without, apart, 250) == 1.0, replay('six spreads apart')
    # one normal: over 300 seeds P3 averaged 0.005 (99 % of seeds below 0.08, the largest
    # 0.33: the 40 subsets share their runs, so one odd draw moves them all)
    assert two_groups_power(without, together, 250) <= 0.4, replay('one group')
    assert two_groups_power(without, wider, 250) <= 0.1, replay('one wider group')


@pytest.mark.parametrize('share', [0.65, 0.35])
def test_which_group_of_runs_turns_is_told_by_the_geometry(share):
    """
    Two groups of heading rates fit alike either way round; the geometry tells which turns.

    Before, the smaller group was always the turning one: a larger share turning was named
    the other way round, with a geometry made to turn by itself (CI, seed 320706: a 44 %
    share at 8.4 deg/s, labelled the other way round on 150 calibration runs, lost the race
    to persistent_turning). The old rule fits 0.315 at -9.5 deg/s here at seed 1.

    The other labelling is 1 - share away at the opposite rate; the fitted share may miss the
    drawn one by its reported error and by the binomial spread of the calibration runs that
    happen to turn (each run is drawn turning or not): at suite seed 61803 more of the
    calibration runs turned than 0.65 of them, and 0.80 was fitted (reported error 0.04).
    """
    from octoroach_model.diagnosis.diagnose import fit_baseline, prepare_halves
    from octoroach_model.diagnosis.modelfit import fit_causes

    chosen = settings(17)
    runs = om.simulate(240, seed=SEED + 17, extensions={'run_mixture': {
        'fraction': share, 'yaw_rate_deg_s': 9.0}})
    halves = prepare_halves(runs, chosen)
    baseline = fit_baseline(halves, chosen).model
    fitted = fit_causes(halves.train, baseline, ('run_mixture',), chosen.fit(), rounds=1)
    found = fitted.model.effects['run_mixture']
    error = math.hypot(fitted.estimates['run_mixture'].others['fraction'],
                       math.sqrt(share * (1 - share) / halves.train.n))
    message = replay(f'{share:.0%} of 240 runs turning at 9 deg/s: fitted {found}, '
                     f'share error {error:.3f}')
    assert abs(found['fraction'] - share) < abs(found['fraction'] - (1 - share)), message
    assert abs(found['fraction'] - share) < 3 * error, message
    assert 6.75 < found['yaw_rate_deg_s'] < 11.25, message


def test_the_baseline_compares_its_starting_geometries_at_the_runs_spread():
    """
    The baseline's four starts reach the basin the robot's own geometry reaches.

    The robot of CI seed 183851 (0.77 times Table III's spread, 40 % of its runs turning),
    here at 100 Hz: compared at Table III's spread the wrong pair of angles won (refit at the
    fitted spread, cost 4624 against 3708 from the robot's own angles; at the CI's rate the
    turning share's fit then stayed far from the robot and lost the race). Now both 3708.
    """
    from octoroach_model.diagnosis.diagnose import fit_baseline, prepare_halves
    from octoroach_model.diagnosis.modelfit import fit_geometry

    robot = replace(om.ModelParameters.nominal(), leg_length=0.019984, stride_frequency=2.4901,
                    touchdown_angles=tuple(np.radians([43.849, 41.680, 37.660, 49.636])),
                    sample_rate=100.0).with_paper_liftoff()
    sigma1, sigma2 = om.model.nominal_sigmas()
    runs = om.simulate(300, seed=183882, cycles=12, parameters=robot, sigma1=0.7738 * sigma1,
                       sigma2=0.7738 * sigma2, extensions={'run_mixture': {
                           'fraction': 0.398, 'yaw_rate_deg_s': 8.211}})
    chosen = replace(FAST, seed=183882)
    halves = prepare_halves(runs, chosen)
    baseline = fit_baseline(halves, chosen).model
    fitted, _, at_baseline = fit_geometry(halves.train, baseline, (), chosen.fit())
    _, _, from_robot = fit_geometry(halves.train, replace(baseline, parameters=robot), (),
                                    chosen.fit())
    angles = np.round(np.degrees(fitted.parameters.touchdown_angles), 1)
    assert at_baseline.cost <= 1.05 * from_robot.cost, (
        f'baseline {angles} deg at cost {at_baseline.cost:.0f}, '
        f'from the robot {from_robot.cost:.0f}')


def em_one_row(deviation: np.ndarray, spread: float, start: tuple[float, float, float]
               ) -> tuple[float, float, float]:
    """Run the two groups' EM written plainly, one data set at a time (the reference)."""
    from octoroach_model.diagnosis.modelfit import EM_STEPS

    shift, separation, fraction = start
    for _ in range(EM_STEPS):
        before = (shift, separation, fraction)
        first = (1 - fraction) * np.exp(-0.5 * ((deviation - shift) / spread) ** 2)
        second = fraction * np.exp(-0.5 * ((deviation - shift - separation) / spread) ** 2)
        weight = second / np.maximum(first + second, 1e-300)
        fraction = float(np.clip(weight.mean(), 1e-4, 1 - 1e-4))
        shift = float(np.mean(deviation - weight * separation))
        total = max(float(np.sum(weight)), 1e-12)
        separation = float(np.sum(weight * (deviation - shift)) / total)
        if max(abs(shift - before[0]) / spread, abs(separation - before[1]) / spread,
               abs(fraction - before[2])) < 1e-6:
            break
    return shift, separation, fraction


@given(runs=st.integers(20, 300), share=st.floats(0.0, 0.5), apart=st.floats(0.0, 5.0),
       spread=st.floats(0.3, 2.0), resamples=st.integers(1, 12), seed=st.integers(0, 10_000))
@hypothesis_settings(max_examples=25, deadline=None, database=None)
def test_the_two_groups_fit_of_every_resample_at_once_is_the_fit_of_each_alone(
        runs, share, apart, spread, resamples, seed):
    """All bootstrap resamples in one array: each row stops on its own, same arithmetic."""
    from octoroach_model.diagnosis.modelfit import two_groups, two_groups_each

    rng = np.random.default_rng(seed)
    values = rng.normal(0.0, 1.0, runs) + apart * (rng.random(runs) < share)
    centre = float(rng.normal(0.0, 0.3))
    start = two_groups(values, centre, spread)
    samples = values[rng.integers(0, runs, (resamples, runs))]
    each = two_groups_each(samples, centre, spread, start)
    alone = np.array([em_one_row(row - centre, spread, start) for row in samples])
    np.testing.assert_array_equal(each, alone)


def test_the_baseline_keeps_the_stride_frequency_the_runs_show_under_a_slow_wobble():
    """
    A slow heading wobble must not move the geometry's strides.

    Suite seed 523917 hid a wobble of 7.6 deg every 1.70 s on Table II's robot (2 Hz): the
    geometry fit, matching the average path and the sway alone, settled at 2.5 Hz with the
    spread 3.6 times the robot's; every candidate's refit stayed there, a 2 % speed change
    was named instead of the wobble. The fit now matches the runs' mean stride frequency too.
    """
    from octoroach_model.diagnosis.diagnose import fit_baseline, prepare_halves

    measured = wobble(om.simulate(N_RUNS, seed=523926), 7.555, 1.7035, 523917)
    fast = replace(FAST, seed=523926)
    baseline = fit_baseline(prepare_halves(measured, fast), fast).model
    assert baseline.parameters.stride_frequency == pytest.approx(2.0, rel=0.03)


def test_a_stride_frequency_a_fraction_of_a_per_cent_off_is_no_material_discrepancy():
    """
    Runs that all stride alike spread in frequency by their spectra's noise alone.

    Replicate 27 of the adequacy study (an exact model, 60 runs of 34 strides at 1.50 Hz):
    the runs' stride frequencies spread by 0.0004 Hz, and the fitted model's mean lay 0.0004
    Hz (0.025 %) from the data's, z -3.7: a tenth of that spread made it material, and the
    model was called inadequate. A mean stride frequency now matters from 0.5 % on, the size
    floor of gait_frequency_variation; a fit 1 % off is still called off.
    """
    from octoroach_model.diagnosis.discrepancies import discrepancies
    from octoroach_model.diagnosis.features import FEATURES, INDEX

    rng = np.random.default_rng([SEED, 27])
    column = INDEX['stride_frequency']

    def mean_stride_frequency(model_hz: float):
        data = rng.standard_normal((60, len(FEATURES)))
        model = rng.standard_normal((2000, len(FEATURES)))
        data[:, column] = 1.4980 + 0.0004 * rng.standard_normal(60)
        model[:, column] = model_hz + 0.0004 * rng.standard_normal(2000)
        with np.errstate(invalid='ignore'):     # variances of normal noise can be negative
            rows = discrepancies(data, model, rng, 40)
        return next(row for row in rows if row.statistic == 'mean stride frequency')

    close, off = mean_stride_frequency(1.4976), mean_stride_frequency(1.4980 * 0.99)
    assert abs(close.z) > 3.55 and not close.material, (close, SEED)
    assert abs(off.z) > 3.55 and off.material, (off, SEED)


@pytest.mark.parametrize('cause, values', [('speed_decay', {'fraction': 0.2}),
                                           ('change_point', {'speed_factor': 0.8})])
def test_a_limit_weighs_a_clock_term_against_a_model_striding_as_the_runs_do(cause, values):
    """
    A term that slows the gait clock is weighed as the race weighs it: at the runs' strides.

    The race's baseline, fitted to runs whose clock slows (a decay over the run, or a change
    of speed partway), matches their stride frequency (the gait target), so the term's gain
    over it is the change within a run alone. The limit's runs with the term were first
    simulated at the stride frequency of the model without it, and the test also scored the
    mean stride frequency they lost (in open_world at commit 4394bf4 speed_decay's limit fell
    by a fifth and the decay at it was named in 0 of 4 data sets); then at its strides per
    run, a clock the robot does not have, against which a change at half the runs showed
    half as much again as against the model refit to runs of the robot's own clock. Now the
    runs stride as the robot with the term would, and the model without it is refit to them.
    """
    from octoroach_model.diagnosis.causes import BY_NAME
    from octoroach_model.diagnosis.features import INDEX
    from octoroach_model.diagnosis.limits import limit_base, simulated_pair
    from octoroach_model.diagnosis.modelfit import at_size, FitSettings

    simulator, without = paper_runs(200)
    scales = np.ones(len(INDEX))
    fit = FitSettings(moment_runs=150, mean_path_runs=100, seed=SEED)
    base = limit_base(simulator, without, scales, 400)
    halfway = {'time_s': float(simulator.data.paths.t[-1]) / 2, **values}
    cause_values = at_size(BY_NAME[cause], 0.2, halfway, simulator.data)
    pair = simulated_pair(simulator, without, base, BY_NAME[cause], 0.2, scales, 400,
                          cause_values, fit)
    column = INDEX['stride_frequency']
    seen, model = np.mean(pair.runs[:, column]), np.mean(base[:, column])
    refit = np.mean(pair.without_features[:, column])
    # a fifth of the gait clock taken off half the run or over it: a tenth on average, which
    # the model without the term takes up in its stride frequency
    message = replay(f'{cause}: runs {seen} Hz, model {model} Hz, refit {refit} Hz')
    assert seen == pytest.approx(0.9 * model, rel=0.02), message
    assert refit == pytest.approx(seen, rel=0.01), message
    assert pair.extended.effects[cause] == cause_values, message


def paper_runs(runs: int):
    """Return a Simulator of `runs` runs of the paper's model (8 strides) and that model."""
    from octoroach_model.diagnosis.modelfit import FittedModel, RunData, Simulator
    from octoroach_model.fitting import mean_start_pose

    measured = om.simulate(runs, seed=SEED, cycles=8)
    start = mean_start_pose(measured)
    nominal = om.ModelParameters.nominal()
    return (Simulator(RunData(measured, nominal.stride_frequency, start[2]), SEED),
            FittedModel(nominal, start, 1.0))


def test_a_heading_terms_test_power_is_averaged_over_the_error_of_the_spread_fitted_with_it():
    """
    A heading term's limit weighs the test at the spreads the race would fit, not the truth.

    With the term in it, a model's spread scale is read off the stride length's variance,
    noisier than the heading's (and matched with few simulated runs), and the test's t is
    steep in that scale: the limit averages the test's power over the scale's error (three
    points of Gauss-Hermite about the true scale, the error on runs as many as a half). A
    table cause leaves the spread's statistic alone, and its t is the one at the true scale.
    In open_world the heading terms at their old limits were named in 2 of 4 data sets each.
    """
    from scipy import stats

    from octoroach_model.diagnosis.causes import BY_NAME
    from octoroach_model.diagnosis.features import INDEX
    from octoroach_model.diagnosis.limits import (
        expected_t, limit_base, simulated_pair, SPREAD_NODES, SPREAD_WEIGHTS, t_statistic)
    from octoroach_model.diagnosis.modelfit import FitSettings, spread_error

    simulator, without = paper_runs(120)
    scales, held_out, score_runs, z = np.ones(len(INDEX)), 120, 300, 3.0
    fit = FitSettings(moment_runs=150, seed=SEED)
    base = limit_base(simulator, without, scales, score_runs)
    walk = BY_NAME['heading_random_walk']
    point = expected_t(simulator, without, base, walk, 2.0, scales, held_out, score_runs,
                       None, fit, z)
    pair = simulated_pair(simulator, without, base, walk, 2.0, scales, score_runs, None, fit)
    se = spread_error(simulator, pair.extended, fit, pair.runs, held_out)
    assert pair.absorbed and 0 < se < 0.2, replay(f'spread error {se}')
    scale = pair.extended.sigma_scale
    ts = [t_statistic(pair.gains(simulator, scales, score_runs, replace(
        pair.extended, sigma_scale=scale + node * se)), held_out) for node in SPREAD_NODES]
    power = sum(w * stats.norm.cdf(t - z) for w, t in zip(SPREAD_WEIGHTS, ts))
    message = replay(f't at the nodes {ts}, averaged power {power}, returned t {point.t}')
    assert stats.norm.cdf(point.t - z) == pytest.approx(power, abs=1e-9), message
    assert point.t != pytest.approx(ts[0], abs=1e-6), message
    turning = BY_NAME['persistent_turning']
    at_z = expected_t(simulator, without, base, turning, 4.0, scales, held_out, score_runs,
                      None, fit, z)
    assert at_z == expected_t(simulator, without, base, turning, 4.0, scales, held_out,
                              score_runs, None, fit)


def test_a_ramps_limit_weighs_it_against_the_geometry_that_bends_to_its_mean_turn():
    """
    The race weighs yaw_rate_ramp against a baseline whose touchdown angles turn like it.

    Its runs turn on average at half the ramp's final rate, which a geometry fitted without
    it takes up; its limit weighed it against the geometry fitted to runs without it, and the
    gain of the whole turn made its test look sure (Table II's robot: expected t 6.16 at the
    old limit against 3.70 refit; 1 of 4 data sets there passed: `benchmarks/
    bench_path_limits.py --size 2.82 --data-sets 4`). The model without the ramp is
    refit to the pseudo-data, its touchdown angles now apart; a term the geometry does not
    mimic keeps the model as fitted.
    """
    from octoroach_model.diagnosis.causes import BY_NAME
    from octoroach_model.diagnosis.limits import limit_base, simulated_pair, t_statistic
    from octoroach_model.diagnosis.modelfit import FitSettings

    simulator, without = paper_runs(200)
    scales, score_runs = np.ones(len(INDEX)), 1000
    fit = FitSettings(moment_runs=150, mean_path_runs=100, seed=SEED)
    base = limit_base(simulator, without, scales, score_runs)
    ramp = BY_NAME['yaw_rate_ramp']
    pair = simulated_pair(simulator, without, base, ramp, 6.0, scales, score_runs, None, fit)
    angles = np.degrees(pair.without.parameters.touchdown_angles)
    bent = np.degrees(without.parameters.touchdown_angles)
    as_fitted = replace(pair, without=without, without_features=base)
    t_bent = t_statistic(pair.gains(simulator, scales, score_runs), 100)
    t_fitted = t_statistic(as_fitted.gains(simulator, scales, score_runs), 100)
    message = replay(f'touchdown angles {angles} (fitted {bent}); t {t_bent} refit, '
                     f'{t_fitted} as fitted')
    assert np.max(np.abs(angles - bent)) > 2.0, message   # 5-6 deg
    # 0.56-0.73 of it at ten seeds (316878, 4-12); 0.50-0.84 when scored on 400 runs
    assert 0 < t_bent < 0.85 * t_fitted, message
    slip = simulated_pair(simulator, without, base, BY_NAME['lateral_slip'], 1.0, scales,
                          score_runs, None, fit)
    assert slip.without is without, message


def test_a_path_familys_test_is_averaged_over_its_refit_size_at_the_runs_strides(monkeypatch):
    """
    The race scores a path family at its size as refit, so the limit averages its test there.

    The sizes 1.7 standard errors either side of the truth are scored with the rule's weights;
    a clock term moved keeps the strides per run, as a refit matching the runs' gait would:
    moved alone, its runs gained or lost strides, the test scored that too, and
    change_point's limits rose (a first version, found with benchmarks/bench_path_limits.py).
    """
    from scipy import stats

    from octoroach_model.diagnosis import limits
    from octoroach_model.diagnosis.causes import BY_NAME
    from octoroach_model.diagnosis.modelfit import FitSettings
    from octoroach_model.model.effects import mean_gait_rate

    simulator, without = paper_runs(120)
    scales, score_runs, held_out, z = np.ones(len(INDEX)), 300, 100, 3.0
    fit = FitSettings(moment_runs=150, mean_path_runs=100, seed=SEED)
    base = limits.limit_base(simulator, without, scales, score_runs)
    change = BY_NAME['change_point']
    pair = limits.simulated_pair(simulator, without, base, change, 0.08, scales, score_runs,
                                 None, fit)
    duration = float(simulator.data.paths.t[-1])
    scored = []
    gains = limits.SimulatedPair.gains

    def recorded(self, simulator, scales, score_runs, extended=None):
        scored.append(self.extended if extended is None else extended)
        return gains(self, simulator, scales, score_runs, extended)

    monkeypatch.setattr(limits.SimulatedPair, 'gains', recorded)
    t_at_truth = limits.t_statistic(pair.gains(simulator, scales, score_runs), held_out)
    averaged = limits.size_averaged_t(simulator, pair, change, 0.08, 0.01, t_at_truth,
                                      scales, held_out, score_runs, z)
    moved = scored[1:]
    distances = [abs(model.effects['change_point']['speed_factor'] - 1) for model in moved]
    assert distances == pytest.approx([0.08 - 0.01 * math.sqrt(3), 0.08 + 0.01 * math.sqrt(3)])

    def strides(model):
        return model.parameters.stride_frequency * mean_gait_rate(model.effects, duration)

    assert [strides(model) for model in moved] == pytest.approx([strides(pair.extended)] * 2)
    ts = [t_at_truth] + [limits.t_statistic(gains(pair, simulator, scales, score_runs, model),
                                            held_out) for model in moved]
    power = sum(w * stats.norm.cdf(t - z) for w, t in zip(limits.SPREAD_WEIGHTS, ts))
    assert stats.norm.cdf(averaged - z) == pytest.approx(power, abs=1e-9), replay(f'{ts}')
