"""
The Python API's entry points take a value or refuse it in one line, before any work.

The programs' options and the nodes' parameters are typed and ranged where they are parsed;
`om.simulate`, `om.diagnose`, `om.fit_nominal`, `om.validate` and `om.plan_runs` are called
with whatever a script holds, so each checks its own arguments and raises a ParameterError
whose one line says what to give (never a TypeError or AttributeError from deep inside, and
never an allocation the machine cannot hold: limits.MAX_SIMULATED_SAMPLES). A callback
(`progress`), an `executor` and a flag (`plots`, `resume`, ...) are checked as well, before
any work: `progress=5` is not a TypeError when it is first called, `plots='no'` is not true.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
import importlib
import math
import tracemalloc

from hidden_effects import SEED
from hypothesis import given, seed, settings, strategies as st
import numpy as np
import pytest

import octoroach_model as om
from octoroach_model.errors import DataError, ParameterError


@pytest.mark.parametrize('arguments, reason', [
    ({'n_paths': 2.5}, 'n_paths must be a positive whole number, got 2.5'),
    ({'n_paths': '3'}, 'n_paths must be a positive whole number, got text'),
    ({'n_paths': True}, 'n_paths must be a positive whole number, got True'),
    ({'n_paths': math.inf}, 'n_paths must be a positive whole number, got inf'),
    ({'seed': math.nan}, 'seed must be a non-negative whole number or None, got nan'),
    ({'seed': -1}, 'seed must be a non-negative whole number'),
    ({'sigma1': 'wide'}, 'sigma1 must be a number, got text'),
    ({'cycles': math.inf}, 'cycles must be a positive finite number, got inf'),
    ({'t': [[0.0, 0.02]]}, 't must be a 1-D array of finite sample times'),
    ({'effects': ['lateral_slip']}, 'effects must be a mapping'),
    ({'effects': {'lateral_slip': [1.0]}}, 'effect lateral_slip: its parameters must be a '
                                           'mapping'),
    ({'effects': {'lateral_slip': {'velocity_cm_s': 'fast'}}},
     'lateral_slip.velocity_cm_s must be a number, got text'),
    ({'effects': {'heading_random_walk': {'step_std_deg': None}}},
     'heading_random_walk.step_std_deg must be a number, got None'),
    ({'extensions': {'change_point': {'time_s': 1.0, 'speed_factor': '0.9'}}},
     r'change_point.speed_factor must be a number, got text \(3 characters, not shown\)'),
    ({'extensions': [('run_order_drift', {'parameter': 'yaw_rate', 'change': True})]},
     'run_order_drift:yaw_rate.change must be a number, got True'),
])
def test_simulate_refuses_a_bad_argument_in_one_line(arguments, reason):
    arguments = {'n_paths': 3, **arguments}
    with pytest.raises(ParameterError, match=reason) as caught:
        om.simulate(arguments.pop('n_paths'), **arguments)
    assert '\n' not in str(caught.value)


def test_simulate_takes_numpy_numbers_and_numpys_seed_forms():
    runs = om.simulate(np.int64(2), seed=np.int64(7), cycles=np.float64(3.0))
    assert runs.poses.shape[0] == 2
    assert np.array_equal(om.simulate(2, seed=[7, 1], cycles=3).poses,
                          om.simulate(2, seed=[7, 1], cycles=3).poses)


def test_a_simulation_too_large_for_one_call_is_refused_before_it_allocates():
    """A billion runs (894 GiB) or a billion cycles used to fail in numpy's allocation."""
    tracemalloc.start()
    try:
        for arguments in ({'n_paths': 10 ** 9}, {'n_paths': 2, 'cycles': 1e9}):
            with pytest.raises(ParameterError, match='above the 40 000 000 one call simulates'):
                om.simulate(**arguments)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16 << 20, peak


def test_the_simulation_limit_takes_a_call_at_it_and_refuses_one_sample_more(monkeypatch):
    """The bound is inclusive, counted over every run's samples (a small limit stands in)."""
    samples = om.ModelParameters.nominal().samples(2)
    module = importlib.import_module('octoroach_model.model.simulate')
    monkeypatch.setattr(module, 'MAX_SIMULATED_SAMPLES', 3 * samples)
    assert om.simulate(3, seed=1, cycles=2).poses.shape[:2] == (3, samples)
    with pytest.raises(ParameterError, match=f'4 runs of {samples} samples are'):
        om.simulate(4, seed=1, cycles=2)
    t = np.arange(3 * samples + 1) * 0.02
    with pytest.raises(ParameterError, match=f'above the {3 * samples} one call simulates'):
        om.simulate(1, seed=1, t=t)


@pytest.mark.parametrize('call', [
    lambda: om.diagnose('bags/'),
    lambda: om.fit_nominal(None),
    lambda: om.validate(np.zeros((3, 10, 3))),
])
def test_the_entry_points_that_take_runs_refuse_anything_else(call):
    with pytest.raises(ParameterError, match='the runs must be Paths .*om.load_measured'):
        call()


def test_validate_refuses_a_model_that_is_not_a_plug_in():
    with pytest.raises(ParameterError, match='model must be a plug-in'):
        om.validate(om.simulate(3, seed=1), model='four_bar')
    from octoroach_model.validation import validate_measured

    with pytest.raises(ParameterError, match=r"nominal must be 'fit' or 'table2', got text "
                                             r'\(6 characters, not shown\)$'):
        validate_measured(om.simulate(3, seed=1), nominal='SECRET')


@pytest.mark.parametrize('arguments, reason', [
    ({'cause': 'wobble'}, 'cause must be a cause of the table or an extension term'),
    ({'size': 'large'}, 'size must be a number, got text'),
    ({'size': math.nan}, 'size must be a finite number, got nan'),
    ({'workers': 2.5}, 'workers must be a whole number, 0 .* or more, got 2.5'),
    ({'workers': -1}, 'workers must be a whole number, 0 .* or more, got -1'),
    ({'method': 'simulat'}, r'method must be one of model, simulate, got text \(7 characters, '
                            r'not shown\) \(did you mean simulate\?\)$'),
])
def test_plan_refuses_a_bad_question_before_any_work(arguments, reason):
    arguments = {'cause': 'persistent_turning', 'size': 3.0, 'workers': 0, **arguments}
    with pytest.raises(ParameterError, match=reason) as caught:
        om.plan_runs(arguments.pop('cause'), arguments.pop('size'), **arguments)
    assert '\n' not in str(caught.value)


@pytest.mark.parametrize('call, reason', [
    (lambda: om.write_report(None, 'out'), 'report must be a DiagnosisReport'),
    (lambda: om.save_dataset(5, om.simulate(2, seed=1)),
     'the data set file must be a file or folder name .*, got 5'),
    (lambda: om.save_dataset('runs.npz', None), 'the runs must be Paths'),
    (lambda: om.load_dataset(None), 'the data set file must be a file or folder name'),
    (lambda: om.write_paths_bag(['bag'], om.simulate(2, seed=1)),
     'the bag folder must be a file or folder name .*, got a list'),
    (lambda: om.load_measured(5), 'the inputs must be a file or folder name, or a list of them'),
    (lambda: om.load_measured([None]), 'an input must be a file or folder name'),
    (lambda: om.read_runs(3.5), 'the inputs must be a file or folder name'),
    (lambda: om.run_study({}, 7), 'the study folder must be a file or folder name'),
])
def test_the_entry_points_that_take_file_names_refuse_anything_else(call, reason, tmp_path,
                                                                    monkeypatch):
    monkeypatch.chdir(tmp_path)             # nothing may be written, but never in the repo
    with pytest.raises(ParameterError, match=reason) as caught:
        call()
    assert '\n' not in str(caught.value)
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize('arguments, reason', [
    ({'progress': 5}, r'progress must be a function, called as progress\(fraction, message\), '
                      'or None, got 5'),
    ({'progress': 'say'}, 'progress must be a function, .*, got text'),
    ({'executor': 'x'}, 'executor must be None or have a submit method .*, got text'),
    ({'executor': 4}, 'executor must be None or have a submit method .*, got 4'),
    ({'executor': ThreadPoolExecutor},
     r'executor must be an executor, not the class ThreadPoolExecutor: give one, '
     r'ThreadPoolExecutor\(...\)'),
])
def test_diagnose_refuses_a_progress_or_executor_it_cannot_call_before_any_work(arguments,
                                                                                reason):
    """Three runs are too few (a DataError): the argument is refused before that check."""
    with pytest.raises(ParameterError, match=reason) as caught:
        om.diagnose(om.simulate(3, seed=1), **arguments)
    assert '\n' not in str(caught.value)


def test_diagnose_takes_any_executor_with_a_submit_and_a_dask_clients_executor():
    """The executor is not asked its kind: a thread pool, and a Dask client's, pass the check."""
    distributed = pytest.importorskip('distributed')
    runs = om.simulate(3, seed=1)
    with ThreadPoolExecutor(1) as pool:
        with pytest.raises(DataError, match='at least 40 runs'):
            om.diagnose(runs, progress=lambda fraction, message: None, executor=pool)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        with pytest.raises(DataError, match='at least 40 runs'):
            om.diagnose(runs, executor=client.get_executor())


@pytest.mark.parametrize('call, reason', [
    (lambda out: om.validate(om.simulate(3, seed=1), progress=1.5),
     'progress must be a function, called as progress.*, got 1.5'),
    (lambda out: om.plan_runs('persistent_turning', 3.0, workers=0, progress=[]),
     'progress must be a function, .*, got a list'),
    (lambda out: om.run_study({}, out, progress='print'),
     r'progress must be a function, called as progress\(rows done, rows in the study, row '
     r'or None\), or None, got text'),
    (lambda out: om.run_study({}, out, plots='no'), 'plots must be true or false, got text'),
    (lambda out: om.run_study({}, out, resume=1), 'resume must be true or false, got 1'),
    (lambda out: om.load_measured(out, progress=True), 'progress must be a function'),
    (lambda out: om.read_runs(out, use_markers='no'),
     'use_markers must be true or false, got text'),
    (lambda out: om.save_dataset(out / 'runs.npz', om.simulate(2, seed=1), replace='yes'),
     'replace must be true or false, got text'),
])
def test_the_other_entry_points_refuse_a_callback_or_flag_of_another_kind(call, reason,
                                                                          tmp_path):
    """'no' would have read as true (a study's plots drawn, a data set replaced)."""
    with pytest.raises(ParameterError, match=reason) as caught:
        call(tmp_path / 'out')
    assert '\n' not in str(caught.value)
    assert not any(tmp_path.iterdir())


def test_write_report_refuses_plots_that_are_not_true_or_false_and_runs_that_are_not_paths(
        tmp_path):
    """Both are refused before the report is read or a file written (`report` is empty)."""
    from octoroach_model.diagnosis.records import DiagnosisReport

    report = object.__new__(DiagnosisReport)
    for arguments, reason in (({'plots': 'yes'}, 'plots must be true or false, got text'),
                              ({'plots': None}, 'plots must be true or false, got None'),
                              ({'measured': 'runs.npz'}, 'the runs must be Paths')):
        with pytest.raises(ParameterError, match=reason) as caught:
            om.write_report(report, tmp_path / 'report', **arguments)
        assert '\n' not in str(caught.value)
    assert not any(tmp_path.iterdir())


def test_a_numpy_bool_is_a_flag(tmp_path):
    """A flag a script computed with numpy (np.True_) is true, as Python's is."""
    runs = om.simulate(2, seed=1)
    target = om.save_dataset(tmp_path / 'runs.npz', runs, replace=np.False_)
    with pytest.raises(om.OctoroachError, match='exists'):
        om.save_dataset(target, runs, replace=np.False_)
    assert om.save_dataset(target, runs, replace=np.True_) == target


@pytest.mark.parametrize('values, reason', [
    ({'leg_length': '2'}, r'leg_length must be a number \(metres\), got text'),
    ({'hip_distance': True}, 'hip_distance must be a number .*, got True'),
    ({'stride_frequency': None}, r'stride_frequency must be a number \(Hz\), got None'),
    ({'sample_rate': [50.0]}, 'sample_rate must be a number .*, got a list'),
    ({'touchdown_angles': 5}, r'touchdown_angles must be a tuple of 4 numbers \(rad\), got 5'),
    ({'touchdown_angles': [0.8, 0.7, 0.7, 0.8]}, 'touchdown_angles must be .*, got a list'),
    ({'touchdown_angles': (0.8, 0.7, 0.7)}, 'touchdown_angles must be .*, got 3 of them'),
    ({'liftoff_angles': (-0.7, 'x')}, r'liftoff_angles must be a tuple of 2 numbers \(rad\), '
                                      'got text .* among them'),
    ({'leg_length': -0.02}, 'hip_distance and leg_length must be positive metres'),
])
def test_model_parameters_refuse_a_field_of_another_kind_in_one_line(values, reason):
    """Once a TypeError from `'2' > 0` or `len(5)`; numpy's numbers are numbers."""
    nominal = om.ModelParameters.nominal()
    with pytest.raises(ParameterError, match=reason) as caught:
        replace(nominal, **values)
    assert '\n' not in str(caught.value)
    taken = replace(nominal, leg_length=np.float32(0.02), sample_rate=np.int64(100),
                    touchdown_angles=tuple(np.asarray(nominal.touchdown_angles)))
    assert taken.samples(2) == 101


@pytest.mark.parametrize('values, reason', [
    ({'accept_loose_fit': 'no'}, 'accept_loose_fit must be true or false, got text'),
    ({'topic': 5}, 'topic must be text or none, got 5'),
    ({'markers': 'LF,RF,B'}, r'markers must be a list of marker names \(not one text'),
    ({'markers': 3}, 'markers must be a list of marker names'),
    ({'up_axis': 'SECRET'}, r'up axis must be one of z, y, -y, x, -x, -z, got text \(6 '
                            r'characters, not shown\)$'),
    ({'forward_axis': '+y'}, r'forward axis must be one of .*, got text \(2 characters, not '
                             r'shown\) \(did you mean y\?\)'),
    ({'forward_axis': 5}, 'forward_axis must be text, got 5'),
])
def test_read_options_refuse_a_value_of_another_kind(values, reason):
    """'no' would have read as true, and 'A,B' as the markers A, ',' and B."""
    from octoroach_model.recordings.options import ReadOptions

    with pytest.raises(ParameterError, match=reason) as caught:
        ReadOptions(**values)
    assert 'SECRET' not in str(caught.value) and '\n' not in str(caught.value)
    assert ReadOptions(markers=['LF', 'RF']).markers == ('LF', 'RF')


def test_paths_take_lists_of_numbers_and_say_in_one_line_what_they_need():
    """A user's own arrays (their motion capture, read their way) become Paths directly."""
    runs = om.Paths([0.0, 0.02], [[[0.0, 0.0, 1.57], [0.001, 0.0, 1.57]]])
    assert runs.poses.dtype == float and runs.n_paths == 1
    for t, poses, reason in (([0.0, 0.02], [[[0.0, 0.0]] * 2], r'poses must be \(n, T, 3\)'),
                             ([[0.0, 0.02]], np.zeros((1, 2, 3)), r't must be \(T,\)'),
                             ('t', np.zeros((1, 2, 3)), 't must be an array of numbers'),
                             ([0.0], np.zeros((1, 2, 3)), '1 times but 2 samples per run')):
        with pytest.raises(om.DataError, match=reason) as caught:    # the package's error,
            om.Paths(t, poses)
        assert isinstance(caught.value, ValueError)       # and a ValueError, as it was


ODD = st.one_of(st.none(), st.booleans(), st.text(max_size=4), st.lists(st.integers(), max_size=2),
                st.floats(allow_nan=True, allow_infinity=True), st.integers(-10, 10))
NAMES = st.sampled_from([*om.EFFECT_NAMES, 'heading_random_walk', 'wobble'])


@seed(SEED)                                      # the suite's: OCTOROACH_TEST_SEED replays it
@settings(max_examples=120, deadline=None, database=None)
@given(n_paths=st.one_of(st.integers(1, 6), ODD), run_seed=st.one_of(st.integers(0, 99), ODD),
       cycles=st.one_of(st.floats(0.5, 6.0), ODD), sigma1=st.one_of(st.floats(0.0, 0.3), ODD),
       effects=st.one_of(ODD, st.dictionaries(NAMES, st.one_of(ODD, st.dictionaries(
           st.sampled_from(['velocity_cm_s', 'fraction', 'step_std_deg', 'x']), ODD)),
           max_size=2)))
def test_simulate_returns_runs_or_refuses_in_one_line_whatever_it_is_given(
        n_paths, run_seed, cycles, sigma1, effects):
    """Any mix of odd arguments: runs of the asked shape, or one ParameterError line."""
    try:
        runs = om.simulate(n_paths, seed=run_seed, cycles=cycles, sigma1=sigma1,
                           effects=effects)
    except ParameterError as error:
        assert '\n' not in str(error) and str(error), repr(error)
        return
    assert runs.poses.shape[0] == n_paths and np.all(np.isfinite(runs.poses[:, 0]))


@pytest.mark.parametrize('call, reason', [
    (lambda runs: om.diagnose(runs, {'seed': 1}),
     r'settings must be a DiagnosisSettings \(or None for the defaults\), got a dict'),
    (lambda runs: om.validate(runs, settings=om.DiagnosisSettings()),
     'settings must be a ValidationSettings'),
    (lambda runs: om.fit_nominal(runs, settings='fast'),
     'settings must be a NominalFitSettings'),
])
def test_the_entry_points_refuse_settings_of_another_record(call, reason):
    runs = om.simulate(3, seed=1, cycles=2)
    with pytest.raises(ParameterError, match=reason) as caught:
        call(runs)
    assert '\n' not in str(caught.value)


@pytest.mark.parametrize('options, error, reason', [
    ({'gap_s': '0.5'}, ParameterError, 'gap_s must be a number, got text'),
    ({'rate_hz': None}, ParameterError, 'rate_hz must be a number, got None'),
    ({'min_duration_s': [1.0]}, ParameterError, 'min_duration_s must be a number'),
    ({'rate_hz': 0.0}, om.DataError, 'sample rate must be a positive number of Hz'),
    ({'min_duration_s': math.inf}, om.DataError, 'min_duration_s must be a non-negative'),
])
def test_reading_refuses_a_bad_grid_before_it_reads(options, error, reason, monkeypatch):
    def no_reading(*args, **kwargs):
        raise AssertionError('the inputs were read before the options were checked')

    monkeypatch.setattr('octoroach_model.recordings.runs.run_set.expand_sources', no_reading)
    with pytest.raises(error, match=reason) as caught:
        om.load_measured(['bags/'], **options)
    assert '\n' not in str(caught.value)
