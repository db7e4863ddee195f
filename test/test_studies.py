"""
The pieces of a study, each on its own.

Spec checks, seeding, damage, the table, the summary, the diagnosis adapter and plan's
power-curve fit. No diagnosis runs here (test_studies_dask.py runs whole studies).
"""
from __future__ import annotations

from dataclasses import replace
import json
import math
import os
from pathlib import Path
import random
from types import SimpleNamespace

from hypothesis import example, given, seed, settings, strategies as st
import numpy as np
import pytest
import yaml

import octoroach_model as om
from octoroach_model.errors import DataError, ParameterError
from octoroach_model.jsonio import dumps
from octoroach_model.recordings.runs.run_set import RunSet
from octoroach_model.studies.damage import cut_runs_short, damage_paths, drop_frames
from octoroach_model.studies.design import build_tasks, draw_robot, draw_signs
from octoroach_model.studies.plan import _coarse_grid, _next_counts, _power_text
from octoroach_model.studies.plan_model import runs_answer_text, runs_interval_text
from octoroach_model.studies.power_curve import fit_power_curve
from octoroach_model.studies.replicate import read_report, task_settings
from octoroach_model.studies.rows import Status, StudyRow, TermOutcome
from octoroach_model.studies.spec import ArmKind, DamageSpec, Draw, parse_spec
from octoroach_model.studies.summary import summarize, wilson
from octoroach_model.studies.table import (
    append_row, COLUMN_NAMES, COLUMNS, format_cell, read_table, row_cells, row_line, row_of,
    start_table, TABLE_NAME)


def suite_seed() -> int:
    seed = int(os.environ.get('OCTOROACH_TEST_SEED', random.SystemRandom().randrange(10**6)))
    print(f'OCTOROACH_TEST_SEED={seed}')
    return seed


SEED = suite_seed()
REPO = Path(__file__).resolve().parents[1]

VARIED = """
name: varied   # a comment
seed: 11
replicates: 4
runs: {low: 150, high: 1000}
robot:
  leg_length_cm: {low: 1.8, high: 2.6}
  stride_frequency_hz: {low: 1.5, high: 3.5}
  cycles: {low: 8, high: 14}
  sample_rate_hz: {choice: [50, 100, 200]}
  spread_scale: {low: 0.3, high: 1.5}
  touchdown_offset_deg: {low: -5, high: 5}
causes:
  - none
  - {cause: persistent_turning, sizes: [2, 5]}
  - {cause: lateral_slip, limit_multiples: [1, 2], sign: both}
  - {together: {speed_decay: 0.2, initial_pose_error: {heading_std_deg: 4, position_std_cm: 0.3}}}
damage: {cut_share: 0.25, cut_at: {low: 0.7, high: 0.95}, dropped_frames: 0.01}
diagnosis: {score_runs: 300, bootstrap: 20}
"""


def spec_of(text: str):
    return parse_spec(yaml.safe_load(text))


# --------------------------------------------------------------------------------------------
# the spec

def test_a_spec_lists_its_arms_null_first_with_readable_labels():
    spec = spec_of(VARIED)
    assert [arm.label for arm in spec.arms] == [
        'none', 'persistent_turning=2', 'persistent_turning=5', 'lateral_slip@+-1x',
        'lateral_slip@+-2x', 'speed_decay=0.2+initial_pose_error=4']
    assert spec.diagnosis_settings(7).seed == 7
    assert spec.diagnosis_settings(7).validate_models is False
    assert spec.diagnosis_settings(7).score_runs == 300


def test_the_spec_hash_ignores_comments_and_key_order_but_not_values():
    spec = spec_of(VARIED)
    reordered = yaml.safe_load(VARIED)
    reordered = dict(reversed(list(reordered.items())))
    assert parse_spec(reordered).spec_hash == spec.spec_hash
    assert spec_of(VARIED.replace('# a comment', '')).spec_hash == spec.spec_hash
    assert spec_of(VARIED.replace('replicates: 4', 'replicates: 5')).spec_hash != spec.spec_hash


def test_limit_multiples_bring_the_null_data_sets_they_are_read_from():
    spec = spec_of('causes: [{cause: speed_decay, limit_multiples: [1, 2]}]\nreplicates: 2')
    assert [arm.kind for arm in spec.arms] == ['null', 'relative', 'relative']
    tasks = build_tasks(spec)
    assert [task.key for task in tasks[:3]] == [
        'none/n500/r0', 'speed_decay@1x/n500/r0', 'speed_decay@2x/n500/r0']
    assert tasks[1].depends_on == 'none/n500/r0' and tasks[0].depends_on is None
    assert len({task.key for task in tasks}) == len(tasks) == 6


@pytest.mark.parametrize('text, reason', [
    ('causes: [{cause: wobble, sizes: [1]}]', 'unknown cause, text (6 characters, not shown)'),
    ('causes: [{cause: [1], sizes: [1]}]', 'unknown cause, a list'),
    ('causes: [{cause: persistent_turning, sizes: [-2]}]', 'must be positive'),
    ('causes: [{cause: persistent_turning, sizes: [0]}]', 'must be positive'),
    ('robot: {leg_length_cm: {low: 2.6, high: 1.8}}', 'bad range, low 2.6 is above high 1.8'),
    ('robot: {leg_length_cm: {low: 1.8}}', 'a range is'),
    ('robot: {wheels: 4}', 'unknown key, text (6 characters, not shown); known'),
    ('robot: {cycle: 4}', 'unknown key, text (5 characters, not shown) (did you mean cycles?)'),
    ('runs: [20]', 'at least 40'),
    ('runs: {low: 10, high: 100}', 'at least 40 runs'),
    ('causes: [{cause: persistent_turning, sizes: [200]}]', 'outside [0, 90]'),
    ('causes: [{cause: persistent_turning, sizes: [2], sign: both}]', 'has no sign'),
    ('causes: [{cause: persistent_turning}]', 'either sizes'),
    ('causes: [{cause: initial_pose_error, sizes: [2], parameters: {heading_std_deg: 3}}]',
     'main parameter'),
    ('causes: [{together: {speed_decay: 0.1}}]', 'at least two'),
    ('causes: [persistent_turning]', 'write none'),
    ('replicates: 0', 'at least 1'),
    ('seed: -1', 'at least 0'),
    ('robot: {stride_frequency_hz: 20, sample_rate_hz: 50}', 'cannot follow'),
    ('robot: {spread_scale: 12}', 'must lie in'),
    ('robot: {touchdown_offset_deg: {low: -50, high: 5}}', 'must lie in'),
    ('damage: {cut_share: 1.5}', 'cut_share'),
    ('diagnosis: {speed: 3}', 'no setting text (5 characters, not shown); settable'),
    ('diagnosis: {bootstrap: 0}', 'diagnosis.bootstrap must be at least 2, got 0'),
    ('robot: [1, 2]', 'must be a mapping'),
    ('diagnosis: {limit_terms: lateral_slip}', 'must be a list of term names'),
    ('diagnosis: {limit_terms: [wobble]}', 'text (6 characters, not shown) is no term'),
    ('causes: [{cause: speed_decay, limit_multiples: [1]}]\n'
     'diagnosis: {limit_terms: [lateral_slip]}', 'add speed_decay to diagnosis.limit_terms'),
    ('causes: [{cause: speed_decay, limit_multiples: [1]}]\n'
     'diagnosis: {detection_limits: false}', 'detection_limits must not be false'),
])
def test_a_bad_spec_is_one_line_naming_what_is_wrong(text, reason):
    with pytest.raises(ParameterError, match=None) as caught:
        parse_spec(yaml.safe_load(text))
    message = str(caught.value)
    assert reason in message and '\n' not in message, message


# where a spec's text may stand: each place a function of the text, giving a whole spec
HOSTILE_PLACES = {
    'top-level key': lambda text: {text: 1},
    'robot key': lambda text: {'robot': {text: 1}},
    'diagnosis key': lambda text: {'diagnosis': {text: 1}},
    'seed': lambda text: {'seed': text},
    'replicates': lambda text: {'replicates': text},
    'cause': lambda text: {'causes': [{'cause': text, 'sizes': [1]}]},
    'extension': lambda text: {'causes': [{'extension': text, 'sizes': [1]}]},
    'causes entry': lambda text: {'causes': [text]},
    'sign': lambda text: {'causes': [{'cause': 'lateral_slip', 'sizes': [1], 'sign': text}]},
    'parameter name': lambda text: {'causes': [{'cause': 'initial_pose_error', 'sizes': [1],
                                                'parameters': {text: 1}}]},
    'limit term': lambda text: {'diagnosis': {'limit_terms': [text]}},
}


@seed(SEED)
@settings(max_examples=80, deadline=None, database=None)
@given(st.sampled_from(sorted(HOSTILE_PLACES)), st.text(max_size=300))
def test_a_spec_s_text_is_never_quoted_back_wherever_it_stands(place, tail):
    """
    A spec is a file, and an error never quotes a file's content: a refused text is described.

    Wherever it stands, any text (a terminal escape, a line of a private key) that is not a
    word of the spec's own gives one line that does not contain it; never another exception.
    """
    text = 'SECRET' + tail
    with pytest.raises(ParameterError) as caught:
        parse_spec(HOSTILE_PLACES[place](text))
    message = str(caught.value)
    assert 'SECRET' not in message and '\n' not in message, (place, message)


@pytest.mark.parametrize('path', sorted((REPO / 'studies').glob('*.yaml')),
                         ids=lambda path: path.name)
def test_every_spec_file_in_the_repository_is_valid(path):
    if 'looks' in yaml.safe_load(path.read_text()):      # a study of repeated looks
        from octoroach_model.studies.looks import load_looks

        looks = load_looks(path)
        assert looks.study.name == path.stem and looks.look_counts()[0] >= 40
        return
    spec = om.load_spec(path)
    assert spec.name == path.stem and build_tasks(spec)


def test_a_spec_file_that_is_not_yaml_or_missing_is_a_one_line_error(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('runs: [50\nseed: 1\n')
    with pytest.raises(ParameterError, match='not valid YAML'):
        om.load_spec(bad)
    with pytest.raises(ParameterError, match='the spec .*missing.yaml: cannot read'):
        om.load_spec(tmp_path / 'missing.yaml')
    # a spec is read no further than the YAML limit (/dev/zero states no size), and aliases,
    # which a 2 KB "billion laughs" expands to gigabytes, are refused
    with pytest.raises(ParameterError, match='the spec /dev/zero: larger than the 4 MiB'):
        om.load_spec('/dev/zero')
    laughs = tmp_path / 'laughs.yaml'
    levels = 'abcdefghi'
    laughs.write_text('a: &a [x, x, x, x, x, x, x, x, x]\n' + ''.join(
        f'{name}: &{name} [' + ', '.join(['*' + below] * 9) + ']\n'
        for below, name in zip(levels, levels[1:])))
    with pytest.raises(ParameterError, match=r'YAML aliases are not accepted \(line 2\)'):
        om.load_spec(laughs)
    with pytest.raises(ParameterError, match='the spec must be a file or folder name'):
        om.load_spec(5)


# --------------------------------------------------------------------------------------------
# seeding and draws

def test_each_replicate_draws_its_robot_from_the_study_seed_and_its_index_only():
    spec = spec_of(VARIED)
    draws = [draw_robot(spec, replicate) for replicate in range(4)]
    assert draws == [draw_robot(spec, replicate) for replicate in range(4)]
    assert len({draw.data_seed for draw in draws}) == 4
    for draw in draws:
        assert 1.8 <= draw.leg_length_cm <= 2.6 and 1.5 <= draw.stride_frequency_hz <= 3.5
        assert 8 <= draw.cycles <= 14 and draw.sample_rate_hz in (50, 100, 200)
        assert 150 <= draw.runs <= 1000
        offsets = np.subtract(draw.touchdown_angles_deg, spec.robot.touchdown_angles_deg)
        assert np.all(np.abs(offsets) <= 5)
        assert draw.parameters().liftoff_angles == (
            -min(draw.parameters().touchdown_angles[:2]),
            -min(draw.parameters().touchdown_angles[2:]))
    other_seed = spec_of(VARIED.replace('seed: 11', 'seed: 12'))
    assert draw_robot(other_seed, 0) != draws[0]


def test_fixing_one_robot_key_leaves_the_draws_of_the_others_unchanged():
    spec = spec_of(VARIED)
    fixed = spec_of(VARIED.replace('leg_length_cm: {low: 1.8, high: 2.6}', 'leg_length_cm: 2'))
    one, other = draw_robot(spec, 3), draw_robot(fixed, 3)
    assert other.leg_length_cm == 2.0
    assert (one.stride_frequency_hz, one.cycles, one.touchdown_angles_deg, one.data_seed) == (
        other.stride_frequency_hz, other.cycles, other.touchdown_angles_deg, other.data_seed)


def test_signs_are_drawn_per_replicate_and_both_signs_occur():
    spec = spec_of(VARIED)
    signs = [draw_signs(spec, replicate)['lateral_slip'] for replicate in range(40)]
    assert set(signs) == {1.0, -1.0}
    assert signs == [draw_signs(spec, replicate)['lateral_slip'] for replicate in range(40)]


# --------------------------------------------------------------------------------------------
# damage

def test_cut_runs_end_with_nan_tails_at_the_drawn_share_of_the_duration():
    paths = om.simulate(40, seed=SEED, cycles=4)
    poses, cut = cut_runs_short(paths.poses, paths.t, 0.25, Draw(0.7, 0.95),
                                np.random.default_rng(SEED))
    assert cut == 10
    finite = np.isfinite(poses).all(axis=2)
    ended = np.flatnonzero(~finite[:, -1])
    assert len(ended) == 10
    for run in range(40):
        last = np.flatnonzero(finite[run])[-1]
        assert finite[run, :last + 1].all(), 'a run ends once and never comes back'
        if run in ended:
            assert 0.7 * paths.t[-1] - 0.02 <= paths.t[last] <= 0.95 * paths.t[-1]
        np.testing.assert_array_equal(poses[run, :last + 1], paths.poses[run, :last + 1])


def test_dropped_frames_are_filled_as_the_bag_reader_fills_them():
    paths = om.simulate(12, seed=SEED, cycles=3)
    filled, dropped = drop_frames(paths.poses, 0.1, np.random.default_rng(SEED))
    changed = ~np.isclose(filled, paths.poses).all(axis=2)
    assert 0.05 * filled[:, 1:-1].size / 3 < dropped < 0.15 * filled[:, 1:-1].size / 3
    assert changed.sum() <= dropped
    # the reader's way: drop the lost frames and resample the runs onto their grid
    lost = np.random.default_rng(SEED).random(paths.poses.shape[:2]) < 0.1
    lost[:, 0] = lost[:, -1] = False
    with_gaps = paths.poses.copy()
    with_gaps[lost] = np.nan
    read = RunSet.from_paths(om.Paths(paths.t, with_gaps)).to_paths(paths.rate_hz)
    np.testing.assert_allclose(read.poses, filled, atol=1e-12)


def test_damage_is_the_same_for_every_arm_of_a_replicate_and_counted():
    damage = DamageSpec(cut_share=0.25, dropped_frames=0.02)
    plain = om.simulate(40, seed=SEED, cycles=3)
    turned = om.simulate(40, seed=SEED, cycles=3,
                         effects={'persistent_turning': {'yaw_rate_std_deg_s': 5}})
    one = damage_paths(plain, damage, np.random.SeedSequence([SEED, 2]))
    other = damage_paths(turned, damage, np.random.SeedSequence([SEED, 2]))
    np.testing.assert_array_equal(np.isnan(one.paths.poses), np.isnan(other.paths.poses))
    assert one.runs_cut == 10 and one.frames_dropped == other.frames_dropped > 0
    assert one.paths.info['damage'] == {'runs_cut': 10, 'frames_dropped': one.frames_dropped}


# --------------------------------------------------------------------------------------------
# the table

def a_row(**values):
    """Return a row given by its table columns (the others empty), through the converter."""
    cells = {'key': 'none/n50/r0', 'arm': 'none', 'kind': 'null', 'replicate': 0,
             'seed': 123, 'runs': 50, 'size': math.nan, 'true_causes': [],
             'named': ['lateral_slip', 'speed_decay'], 'false_causes': ['lateral_slip'],
             'named_lateral_slip': True, 'estimate_lateral_slip': 0.1 + 0.2,
             'status': 'ok', 'note': 'a, note\nover "two" lines', 'elapsed_s': 1.5, **values}
    kinds = dict(COLUMNS)
    return row_of({name: format_cell(value, kinds[name]) for name, value in cells.items()})


def test_a_row_reads_back_exactly_and_a_cut_off_last_line_is_dropped(tmp_path):
    table = tmp_path / TABLE_NAME
    start_table(table)
    append_row(table, a_row())
    append_row(table, a_row(key='none/n50/r1', replicate=1))
    with open(table, 'a') as stream:
        stream.write(row_line(a_row(key='none/n50/r2'))[:40])      # a kill mid-write
    rows, dropped = read_table(table)
    assert dropped == 1 and len(rows) == 2
    first = rows[0]
    assert first.terms['lateral_slip'].estimate == 0.1 + 0.2          # bit for bit
    assert first.outcome.named == ('lateral_slip', 'speed_decay')
    assert first.terms['lateral_slip'].named is True and first.terms['speed_decay'].named is None
    assert math.isnan(first.size) and first.note == 'a, note over "two" lines'
    assert first.seed == 123 and first.runs == 50
    assert first.kind is ArmKind.NULL and first.status is Status.OK
    assert row_cells(first) == row_cells(a_row())
    assert len(row_cells(first)) == len(COLUMN_NAMES)


def test_a_file_that_is_not_a_study_table_is_refused(tmp_path):
    other = tmp_path / 'other.csv'
    other.write_text('a,b\n1,2\n')
    with pytest.raises(DataError, match='columns'):
        read_table(other)


# --------------------------------------------------------------------------------------------
# the diagnosis adapter

def a_report(causes=(), candidates=(), extensions=(), extension_candidates=(), steps=(),
             adequate=True, unexplained=(), discrepancies=(), adequacy_bound_z=3.0,
             critical_t=3.0):
    """
    Return what a study reads of a DiagnosisReport, its records written out by hand.

    Each record holds the fields the study reads, so that its columns can be checked by hand;
    a candidate without a held-out t given was not scored (screened), and every step asked
    for a t of `critical_t`.
    """
    def records(entries):
        return tuple(SimpleNamespace(**entry) for entry in entries)

    def scored(entries):
        return tuple(SimpleNamespace(**{'held_out_t': None, 't_scoring_se': None,
                                        'first_t': None, 'clears_floor': False,
                                        'detectable_power': {}, **entry})
                     for entry in entries)

    return SimpleNamespace(
        causes=records(causes), candidates=scored(candidates),
        extensions=records(extensions), extension_candidates=scored(extension_candidates),
        critical_t=lambda candidate: critical_t,
        steps=tuple(SimpleNamespace(chosen=step['chosen'], rival=step['rival'] and
                                    SimpleNamespace(**step['rival'])) for step in steps),
        adequate=adequate, unexplained=records(unexplained),
        discrepancies=records(discrepancies), adequacy_bound_z=adequacy_bound_z)


def test_the_adapter_reads_a_typed_report_with_several_causes_and_intervals():
    report = a_report(
        causes=[{'cause': 'speed_decay', 'parameters': {'fraction': 0.21},
                 'interval': {'fraction': [0.18, 0.24]}},
                {'cause': 'measurement_noise', 'parameters': {'position_std_cm': 0.1},
                 'interval': {'position_std_cm': [0.08, 0.12]}}],
        candidates=[{'cause': 'lateral_slip', 'parameters': {'velocity_cm_s': 0.01},
                     'detectable': {'velocity_cm_s': 0.2}, 'held_out_t': 1.25,
                     't_scoring_se': 0.5, 'first_t': 2.5, 'clears_floor': True,
                     'detectable_power': {'size_bound': 0.85, 'held_out_test': 0.94}},
                    {'cause': 'persistent_turning', 'parameters': {'yaw_rate_std_deg_s': 0.0},
                     'detectable': {'yaw_rate_std_deg_s': 2.0}}],
        adequate=False, unexplained=[{'statistic': 'heading_rate_spread', 'z': 5.0}],
        discrepancies=[{'statistic': 'heading_rate_spread', 'z': 5.0, 'material': True}])
    outcome, terms = read_report(report, {'speed_decay': {'fraction': 0.2},
                                          'initial_pose_error': {'heading_std_deg': 4.0,
                                                                 'position_std_cm': 0.0}})
    assert outcome.named == ('speed_decay', 'measurement_noise')
    assert outcome.false_causes == ('measurement_noise',)
    assert outcome.all_true_named is False and outcome.adequate is False
    assert outcome.baseline_adequate is False
    assert (terms['speed_decay'].low, terms['speed_decay'].high) == (0.18, 0.24)
    assert terms['speed_decay'].true == 0.2 and terms['initial_pose_error'].named is False
    assert outcome.unexplained == ('heading_rate_spread',)
    assert terms['lateral_slip'].limit == 0.2 and terms['lateral_slip'].estimate == 0.01
    # how far each scored term's held-out test got, against what it had to pass
    slip = terms['lateral_slip']
    assert (slip.t, slip.t_critical, slip.t_scoring_se, slip.first_t) == (1.25, 3.0, 0.5, 2.5)
    # what its limit predicted of each part of the decision, and what the bound did
    assert (slip.clears_floor, slip.bound_power, slip.test_power) == (True, 0.85, 0.94)
    turning = terms['persistent_turning']
    assert turning.clears_floor is False and math.isnan(turning.bound_power)
    assert terms['speed_decay'].clears_floor is None    # named, not among the candidates
    assert all(math.isnan(value) for value in (
        terms['persistent_turning'].t, terms['persistent_turning'].t_critical,
        terms['persistent_turning'].first_t, terms['speed_decay'].t))


# --------------------------------------------------------------------------------------------
# the summary

def test_wilson_intervals_are_the_textbook_formula():
    for successes, trials in ((0, 20), (3, 20), (20, 20), (117, 250)):
        rate = wilson(successes, trials)
        z, p = 1.959963984540054, successes / trials
        centre = (p + z * z / (2 * trials)) / (1 + z * z / trials)
        half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials ** 2)) \
            / (1 + z * z / trials)
        assert rate.interval == pytest.approx((max(centre - half, 0), min(centre + half, 1)))
    assert wilson(0, 0).rate is None


def test_the_summary_counts_false_positives_power_recovery_and_errors():
    spec = spec_of('runs: [50]\ncauses: [none, {cause: persistent_turning, sizes: [5]}, '
                   '{together: {persistent_turning: 5, lateral_slip: 1}}]')
    rows = []
    for replicate in range(10):
        rows.append(a_row(key=f'n{replicate}', replicate=replicate, arm='none', kind='null',
                          true_causes=[], named=['speed_decay'] if replicate < 2 else [],
                          adequate=None if replicate == 9 else replicate != 4))
        rows.append(a_row(key=f't{replicate}', arm='persistent_turning=5', kind='absolute',
                          true_causes=['persistent_turning'], false_causes=[],
                          named_persistent_turning=replicate < 7,
                          true_persistent_turning=5.0,
                          rel_error_persistent_turning=0.1 * (replicate - 3),
                          low_persistent_turning=4.0, high_persistent_turning=6.0))
        rows.append(a_row(key=f'b{replicate}', arm=spec.arms[2].label, kind='together',
                          true_causes=['persistent_turning', 'lateral_slip'],
                          false_causes=['speed_decay'] if replicate == 2 else [],
                          all_true_named=replicate % 2 == 0,
                          status='ok' if replicate < 8 else 'error'))
    summary = summarize(spec, rows, wall_time_s=12.0)
    assert summary.false_positive.overall.successes == 2
    assert summary.false_positive.overall.trials == 10
    assert summary.false_positive.causes_named == {'speed_decay': 2}
    inadequate = summary.inadequate_on_nulls.overall
    assert (inadequate.successes, inadequate.trials) == (1, 9)   # one not judged
    power = summary.power[0]
    assert (power.named.successes, power.named.trials, power.runs) == (7, 10, 50)
    estimation = next(e for e in summary.estimation if e.arm == 'persistent_turning=5')
    assert estimation.named == 7
    assert estimation.median_relative_error == pytest.approx(0.0)
    assert estimation.interval_coverage.successes == 7
    recovery = summary.two_cause_recovery[0]
    assert (recovery.all_named.successes, recovery.all_named.trials) == (4, 8)
    assert (recovery.other_named.successes, recovery.other_named.trials) == (1, 8)
    assert summary.status.counts == {'ok': 28, 'error': 2}
    plain = json.loads(dumps(summary))          # summary.json: the rates' keys, in place
    assert plain['false_positive']['count'] == 2 and plain['power'][0]['data_sets'] == 10
    assert list(plain['power'][0]) == ['cause', 'parameter', 'size', 'sign', 'runs', 'count',
                                       'data_sets', 'rate', 'interval_95']


def test_limit_terms_reach_the_nulls_alone_and_the_summary_lists_their_limits_alone():
    spec = spec_of('runs: [50]\ncauses: [none, {cause: speed_decay, limit_multiples: [2]}]\n'
                   'diagnosis: {limit_terms: [speed_decay, change_point, speed_decay]}')
    assert dict(spec.diagnosis)['limit_terms'] == ('change_point', 'speed_decay')
    null, relative = build_tasks(spec)
    assert task_settings(null, spec, 1).limit_terms == ('change_point', 'speed_decay')
    assert not task_settings(relative, spec, 1).detection_limits
    rows = [a_row(key=f'n{replicate}', replicate=replicate, arm='none', kind='null',
                  true_causes=[], named=[]) for replicate in range(3)]
    limits = summarize(spec, rows).detection_limits
    assert [entry.cause for entry in limits] == ['speed_decay', 'change_point']


def test_power_at_a_limit_multiple_counts_the_misses_and_which_were_not_silent():
    spec = spec_of('runs: [50]\ncauses: [none, {cause: speed_decay, limit_multiples: [1]}]')
    arm = spec.arms[1].label
    rows = [a_row(key=f'd{replicate}', replicate=replicate, arm=arm, kind='relative',
                  true_causes=['speed_decay'], false_causes=[], true_speed_decay=0.02,
                  named_speed_decay=replicate < 7,
                  adequate=None if replicate == 9 else replicate in (0, 1, 2, 3, 4, 5, 6, 8))
            for replicate in range(10)]
    entry = summarize(spec, rows).power_at_limit_multiples[0]
    assert (entry.named.successes, entry.named.trials, entry.missed) == (7, 10, 3)
    assert entry.missed_not_adequate == 1        # replicate 7 (8 was adequate, 9 not judged)
    assert entry.meets_target is True
    assert entry.median_t_margin is None and entry.close_calls is None   # no t columns
    # t against its critical value: margins -1.0, 0.5, 1.0, 2.5 (the others not scored);
    # within two scoring errors (0.6 each) of it: the margins -1.0, 0.5 and 1.0
    scored = {0: 2.0, 1: 3.5, 2: 4.0, 3: 5.5}
    rows = [replace(row, terms={**row.terms, 'speed_decay': replace(
        row.terms['speed_decay'], t=scored[row.replicate], t_critical=3.0, t_scoring_se=0.6)})
            if row.replicate in scored else row for row in rows]
    entry = summarize(spec, rows).power_at_limit_multiples[0]
    assert entry.median_t_margin == pytest.approx(0.75) and entry.close_calls == 3
    assert entry.turned == 0
    # close calls scored again (first_t given) count whatever their t now: replicate 4 was
    # turned (2.9 below 3.0 at first, 3.2 on the runs scored again), replicate 5 was not;
    # margins now -1.0, 0.2, 0.5, 1.0, 2.0, 2.5
    again = {4: (3.2, 2.9), 5: (5.0, 3.1)}
    rows = [replace(row, terms={**row.terms, 'speed_decay': replace(
        row.terms['speed_decay'], t=again[row.replicate][0], first_t=again[row.replicate][1],
        t_critical=3.0, t_scoring_se=0.3)}) if row.replicate in again else row for row in rows]
    entry = summarize(spec, rows).power_at_limit_multiples[0]
    assert entry.median_t_margin == pytest.approx(0.75)
    assert (entry.close_calls, entry.turned) == (5, 1)


# --------------------------------------------------------------------------------------------
# plan's search

def a_plan_row(runs, replicate, named):
    """Return a diagnosed row of a plan: speed_decay named or not at `runs` runs."""
    return StudyRow('', '', ArmKind.ABSOLUTE, replicate, 0, runs, status=Status.OK,
                    terms={'speed_decay': TermOutcome(named=named)})


@pytest.mark.parametrize('replicates, plans, bound', [(6, 60, 49), (60, 40, 32)])
def test_the_power_fit_finds_the_run_count_of_a_known_power_curve(replicates, plans, bound):
    """
    Check the nominal 95 % interval of the run count over many simulated plans.

    One plan alone misses the truth 5 % of the time: a single draw would be a flaky test.
    `benchmarks/bench_plan_coverage.py` measured plan's interval on this curve at 93.2 % (6
    replicates, plan's default) and 95.5 % (60) over 400 plans each; the percentile bootstrap
    plan used before held the truth in 59.5 % and 91.8 % (it fails the first case: at 60 %
    coverage, 49 of 60 has a chance below 1e-3). The bounds fail with a chance of 0.06 % and
    0.01 % at the measured coverage.
    """
    true_a, true_b = -13.0, 2.5          # 80 % power at exp((ln 4 + 13) / 2.5) = 316 runs
    truth = math.exp((math.log(4) - true_a) / true_b)
    counts = (100, 200, 400, 800, 1600)
    covered, errors = 0, []
    for study in range(plans):
        rng = np.random.default_rng([SEED, replicates, study])
        rows = []
        for replicate in range(replicates):
            u = rng.random()             # one draw per replicate: nested data sets (CRN)
            for runs in counts:
                power = 1 / (1 + math.exp(-(true_a + true_b * math.log(runs))))
                rows.append(a_plan_row(runs, replicate, u < power))
        fit = fit_power_curve(rows, 'speed_decay', 0.8)
        covered += fit.interval_95[0] < truth < fit.interval_95[1]
        errors.append(abs(math.log(fit.runs_at_target / truth)))
    assert covered >= bound, (SEED, covered)
    assert float(np.median(errors)) < 0.6 / math.sqrt(replicates / 6), (SEED, errors)


@seed(SEED)
@settings(max_examples=60, deadline=None, database=None)
@given(st.lists(st.lists(st.booleans(), min_size=3, max_size=3), min_size=1, max_size=12),
       st.sampled_from([0.5, 0.8, 0.9]))
@example([[False, True, True], [False, False, True], [False, True, True]], 0.8)
def test_the_power_fits_interval_holds_its_answer_whatever_the_outcomes(outcomes, target):
    rows = [a_plan_row(runs, replicate, named) for replicate, seen in enumerate(outcomes)
            for runs, named in zip((50, 100, 200), seen)]
    fit = fit_power_curve(rows, 'speed_decay', target)
    low, high = fit.interval_95
    assert 0.0 <= low <= fit.runs_at_target <= high, fit
    assert 0.0 <= fit.slope <= 20.0
    if all(not seen[0] and seen[2] for seen in outcomes):    # every replicate turns between
        assert 50 < fit.runs_at_target < 200, fit
    if all(all(seen) for seen in outcomes):          # named everywhere: below the counts
        assert fit.runs_at_target < 50 and low == 0.0
    if not any(any(seen) for seen in outcomes):      # named nowhere: no upper end
        assert fit.runs_at_target > 200 and high == math.inf


def test_plan_grids_start_around_the_guess_and_grow_toward_the_answer():
    assert _coarse_grid(400, 40, 2000) == [100, 200, 400, 800]
    assert _coarse_grid(10, 40, 2000) == [40, 80, 160]
    assert _coarse_grid(2000, 40, 2000) == [500, 1000, 2000]
    assert _coarse_grid(5000, 40, 2000) == [625, 1250, 2000]
    fit = fit_power_curve([a_plan_row(n, r, False) for n in (100, 200) for r in range(4)],
                          'speed_decay', 0.8)
    assert _next_counts(fit, [100, 200], 40, 2000) == [400]
    assert _next_counts(fit, [100, 2000], 40, 2000) == []


# --------------------------------------------------------------------------------------------
# extension families in studies

def test_a_spec_puts_extension_families_beside_the_causes():
    spec = spec_of('runs: [50]\ncauses:\n'
                   '  - {extension: run_order_drift, parameter: yaw_rate, sizes: [4], '
                   'sign: negative}\n'
                   '  - {extension: change_point, limit_multiples: [2], sign: both}\n'
                   '  - {extension: run_mixture, sizes: [8], parameters: {fraction: 0.4}}\n'
                   '  - together: {persistent_turning: 3, heading_random_walk: 1.5}\n')
    assert [arm.label for arm in spec.arms] == [
        'none', 'run_order_drift:yaw_rate=-4', 'change_point@+-2x', 'run_mixture=8',
        'persistent_turning=3+heading_random_walk=1.5']
    for text, reason in (
            ('{extension: run_order_drift, sizes: [1]}', 'needs parameter'),
            ('{extension: wobble, sizes: [1]}', 'unknown extension, text'),
            ('{extension: heading_random_walk, parameter: yaw_rate, sizes: [1]}',
             'belongs to run_order_drift'),
            ('{extension: heading_random_walk, sizes: [1], sign: both}', 'has no sign'),
            ('{extension: run_mixture, sizes: [100]}', 'outside')):
        with pytest.raises(ParameterError, match=reason):
            spec_of(f'runs: [50]\ncauses: [{text}]')


def test_a_task_puts_its_family_into_the_data_at_the_spec_s_size():
    from octoroach_model.studies.design import build_tasks
    from octoroach_model.studies.replicate import task_effects

    spec = spec_of('runs: [50]\ncauses:\n'
                   '  - {extension: change_point, sizes: [0.25], sign: negative}\n'
                   '  - {extension: periodic_heading, sizes: [4]}\n'
                   '  - {extension: run_mixture, sizes: [8], sign: negative}\n')
    tasks = {task.arm.label: task for task in build_tasks(spec)}
    change = task_effects(tasks['change_point=-0.25'], spec, None, 5.0)
    assert change == {'change_point': {'time_s': 2.5, 'speed_factor': 0.75}}
    periodic = task_effects(tasks['periodic_heading=4'], spec, None, 5.0)
    assert periodic == {'periodic_heading': {'amplitude_deg': 4.0, 'frequency_hz': 0.6}}
    mixture = task_effects(tasks['run_mixture=-8'], spec, None, 5.0)
    assert mixture == {'run_mixture': {'fraction': 0.3, 'yaw_rate_deg_s': -8.0}}


def test_a_multiple_of_a_limit_past_what_the_model_takes_is_skipped_with_its_reason():
    """speed_decay's limit at 0.6 is a fraction of 1.2 at 2x: no data set, a skip that says so."""
    from octoroach_model.studies.design import build_tasks
    from octoroach_model.studies.replicate import Skip, task_effects

    spec = spec_of('runs: [50]\ncauses: [none, {cause: speed_decay, limit_multiples: [1, 2], '
                   'sign: positive}]')
    tasks = {task.arm.label: task for task in build_tasks(spec) if task.replicate == 0}
    null = a_row(key='n', replicate=0, arm='none', kind='null', true_causes=[],
                 false_causes=[], limit_speed_decay=0.6)
    once = task_effects(tasks['speed_decay@1x'], spec, null, 5.0)
    assert once['speed_decay']['fraction'] == pytest.approx(0.6)
    with pytest.raises(Skip, match=r'2 times the detection limit .* past what the model takes'):
        task_effects(tasks['speed_decay@2x'], spec, null, 5.0)


def test_the_adapter_reads_extensions_and_the_confusion_table_counts_them():
    from octoroach_model.studies.summary import confusion

    report = a_report(
        extensions=[{'family': 'change_point', 'term': 'change_point',
                     'parameters': {'time_s': 2.4, 'speed_factor': 0.72},
                     'interval': {'speed_factor': [0.7, 0.74]}}],
        extension_candidates=[{'cause': 'run_mixture', 'parameters': {
            'fraction': 0.3, 'yaw_rate_deg_s': 1.0}, 'detectable': {'yaw_rate_deg_s': 5.0}}])
    outcome, terms = read_report(report, {'change_point': {'time_s': 2.5, 'speed_factor': 0.7}})
    assert outcome.named == ('change_point',) and outcome.false_causes == ()
    assert terms['change_point'].named is True and outcome.baseline_adequate is True
    assert terms['change_point'].rel_error == pytest.approx(-0.02 / 0.3)   # of 1 - factor
    assert terms['run_mixture'].limit == 5.0
    rows = [a_row(true_causes=['change_point'], named=['change_point']),
            a_row(true_causes=['change_point'], named=['speed_decay']),
            a_row(true_causes=['run_order_drift:yaw_rate'], named=[]),
            a_row(true_causes=[], named=['run_mixture'])]
    table = confusion(rows)
    assert table.named == {'change_point': {'change_point': 1, 'speed_decay': 1},
                           'run_order_drift:yaw_rate': {'nothing': 1},
                           'none': {'run_mixture': 1}}
    assert table.data_sets == {'change_point': 2, 'run_order_drift:yaw_rate': 1, 'none': 1}
    drifts = confusion([a_row(true_causes=['run_order_drift:yaw_rate'],
                              named=['run_order_drift:touchdown_angle_3'])])
    assert drifts.named == {'run_order_drift:yaw_rate': {'run_order_drift:touchdown_angle_3': 1}}


def test_a_term_the_runs_cannot_tell_from_the_named_one_is_counted_apart():
    """A change point reported beside a named speed decay is undecided, not named."""
    from octoroach_model.studies.summary import confusion

    rival = {'cause': 'change_point', 'family': 'change_point', 'gain': 1.9,
             'parameters': {'time_s': 2.5, 'speed_factor': 1.03}, 'p_difference': 0.4}
    report = a_report(causes=[{'cause': 'speed_decay', 'parameters': {'fraction': -0.04},
                               'interval': {}}],
                      steps=[{'step': 1, 'chosen': 'speed_decay', 'rival': rival},
                             {'step': 2, 'chosen': None, 'rival': None}])
    outcome, _ = read_report(report, {'change_point': {'time_s': 2.5, 'speed_factor': 1.03}})
    assert outcome.named == ('speed_decay',) and outcome.undecided == ('change_point',)
    spec = spec_of('runs: [50]\ncauses: [none, {extension: change_point, '
                   'limit_multiples: [1]}]')
    arm = spec.arms[1].label
    rows = [a_row(key=f'c{replicate}', replicate=replicate, arm=arm, kind='relative',
                  true_causes=['change_point'], true_change_point=1.03,
                  named=['change_point'] if replicate < 5 else ['speed_decay'],
                  named_change_point=replicate < 5,
                  undecided=['change_point'] if replicate in (5, 6) else [])
            for replicate in range(10)]
    entry = summarize(spec, rows).power_at_limit_multiples[0]
    assert (entry.named.successes, entry.named_or_undecided.successes) == (5, 7)
    table = confusion(rows)
    assert table.named['change_point'] == {'change_point': 5, 'speed_decay': 5}
    assert table.undecided['change_point'] == {'change_point': 2}


def test_plan_takes_an_extension_term_as_its_cause():
    from octoroach_model.commands.plan import parser
    from octoroach_model.studies.plan import _base_spec

    args = parser().parse_args(['--cause', 'run_order_drift:yaw_rate', '--size', '4'])
    spec = _base_spec(args.cause, args.size, None, None, 2, 0, None, 40, 400, 0.8)
    assert [arm.label for arm in spec.arms] == ['run_order_drift:yaw_rate=4']
    assert spec.arms[0].effect_dict() == {'run_order_drift:yaw_rate': {'change': 4.0}}


def test_plans_statement_says_the_power_asked_and_an_open_interval_in_words():
    """99.9999 % is not rounded to 100 %, and an interval open above reads as words."""
    assert [_power_text(p) for p in (0.8, 0.95, 0.999999, 0.5)] == [
        '80%', '95%', '99.9999%', '50%']
    assert runs_interval_text(150.2, 399.6) == '150 to 400 runs'
    assert runs_interval_text(352, math.inf) == '352 runs to more than any run count tried'
    assert runs_interval_text(math.inf, math.inf) == 'more than any run count tried'
    # plan's progress lines say an answer in the same words
    assert runs_answer_text(120, (80, 400)) == '120 runs (95 % 80 to 400 runs)'
    assert runs_answer_text(math.inf, (300, math.inf)) == (
        'more than any run count tried (95 % 300 runs to more than any run count tried)')
