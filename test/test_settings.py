"""
One source for each setting: fields, node parameters, program options and params files agree.

A setting is a field of a settings record (`octoroach_model.settings`); the nodes' parameters,
the offline programs' options and config/NODE.yaml are made from it. These tests fail when
one of them drifts: a params file edited by hand, a parameter or option written out again
with a range of its own, a node parameter with no source.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import re

from hidden_effects import SEED
from hypothesis import example, given, seed, settings as hypothesis_settings, strategies as st
import numpy as np
import pytest

from octoroach_model.commands import diagnose, plan, simulate, validate
from octoroach_model.diagnosis import DiagnosisSettings
from octoroach_model.errors import ParameterError
from octoroach_model.guidance import GuidanceSettings
from octoroach_model.nodes import recorder, replay
from octoroach_model.nodes.common import SubscriberWait
from octoroach_model.nodes.recorder import RecorderSettings
from octoroach_model.nodes.replay import ReplaySettings
from octoroach_model.recordings.options import GAP_S, ReadOptions
from octoroach_model.run_settings import effect_settings, extension_settings, RunSettings
from octoroach_model.settings import Setting, settings_of
from octoroach_model.settings_yaml import comment, node_specs, params_files
from octoroach_model.studies.plan import PlanSettings
from octoroach_model.validation import ValidationSettings
from octoroach_model.validation_jobs import Job

from ros_helpers import REPO

# Where each node's parameters come from: records whose fields they are, the model's tables
# (name: (default, Setting)), and the parameters that are the node's alone (one ParamSpec, no
# option or record beside it: the validator's string arrays, declared apart).
SOURCES: dict[str, tuple[tuple[type, ...], dict[str, tuple[object, Setting]], tuple[str, ...]]]
SOURCES = {
    'validator': ((Job, ValidationSettings, GuidanceSettings), {}, ('bags', 'data_dirs')),
    'simulator': ((RunSettings, SubscriberWait), {**effect_settings(), **extension_settings()},
                  ()),
    'recorder': ((RecorderSettings,), {}, ()),
    'replay': ((ReplaySettings, SubscriberWait), {}, ()),
}


def source_of(node: str, name: str) -> tuple[object, Setting] | None:
    """Return (default, Setting) of a node parameter's field or table row; None: own."""
    records, tables, _ = SOURCES[node]
    for record in records:
        found = settings_of(record)
        if name in found:
            return found[name]
    return tables.get(name)


def same_setting(spec_setting: Setting, field_setting: Setting) -> bool:
    """Tell whether two settings say the same (the command-line option name aside)."""
    return spec_setting == Setting(**{**field_setting.__dict__, 'option': ''})


@pytest.mark.parametrize('name', sorted(params_files()))
def test_each_params_file_is_what_the_settings_write(name):
    on_disk = (REPO / 'config' / name).read_text()
    assert on_disk == params_files()[name], (
        f'config/{name} differs from the settings: run python -m octoroach_model.settings_yaml')


@pytest.mark.parametrize('node', sorted(SOURCES))
def test_every_node_parameter_is_its_fields_or_the_nodes_own(node):
    _, _, own = SOURCES[node]
    for spec in node_specs()[node]():
        source = source_of(node, spec.name)
        if source is None:
            assert spec.name in own, f'{node}.{spec.name} has no source'
            continue
        default, described = source
        assert same_setting(spec.setting, described), (node, spec.name, spec, described)
        expected = list(default) if isinstance(default, tuple) else default
        assert spec.default == ('' if default is None else expected), (node, spec.name)


def test_a_setting_shared_by_nodes_has_one_range():
    """Same name and help on two nodes is one setting (sigma1 the spread, or the search's)."""
    seen: dict[tuple[str, str], tuple[str, str]] = {}
    for node in SOURCES:
        for spec in node_specs()[node]():
            text = spec.range_text()
            first = seen.setdefault((spec.name, spec.description), (node, text))
            assert first[1] == text, (spec.name, node, first)


def test_the_simulator_and_replay_wait_for_subscribers_alike():
    specs = {node: {spec.name: spec for spec in node_specs()[node]()}
             for node in ('simulator', 'replay')}
    for name in settings_of(SubscriberWait):
        assert specs['simulator'][name] == specs['replay'][name], name


@pytest.mark.parametrize('node, records', [
    (recorder, (RecorderSettings,)),
    (replay, (ReplaySettings, SubscriberWait)),
])
def test_every_flag_of_a_node_is_its_parameters_setting(node, records):
    """A node's flag presets its parameter: same help, unit, range and choices."""
    found = {action.dest: action for action in node.parser()._actions
             if action.dest not in ('help',)}
    fields = {name: described for record in records
              for name, (_, described) in settings_of(record).items()}
    flags = [name for name in found if name in fields]
    assert len(flags) >= 3, flags
    for name in flags:
        action, described = found[name], fields[name]
        assert action.help == f'{described.help_text()} (parameter {name})', name
        assert action.default is None, name
        if described.choices:
            assert set(action.choices) == set(described.choices) - {''}, name


def options(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    """Return {dest: action} of a parser's options."""
    return {action.dest: action for action in parser._actions if action.option_strings}


# Options of an offline program that share a name with a field but are the program's own:
# simulate's --cycles may be fractional, its --seed seeds every draw of the one call, and its
# --effect and --extension repeat, each with its parameters (the simulator node publishes
# whole cycles, its seed -1 means fresh entropy for each run, and it adds one effect).
# diagnose's --workers sizes the pool the diagnosis is given (0: none, all in the program's
# process), where DiagnosisSettings.workers is the processes diagnose() starts itself.
PROGRAMS_OWN = {simulate: {'cycles', 'seed', 'effect', 'extension'}, diagnose: {'workers'}}


@pytest.mark.parametrize('program, records, least', [
    (validate, (ValidationSettings, Job, ReadOptions), 4),
    (simulate, (RunSettings,), 4),
    (diagnose, (DiagnosisSettings, ReadOptions), 4),
    (plan, (PlanSettings,), 6),
])
def test_every_option_of_a_setting_has_its_fields_range_and_default(program, records, least):
    parser = program.parser()
    found = options(parser)
    checked = 0
    for record in records:
        for name, (default, described) in settings_of(record).items():
            action = found.get(name)
            if action is None or name in PROGRAMS_OWN.get(program, ()):
                continue
            checked += 1
            assert described.description in action.help, (name, action.help)
            if described.choices:
                assert tuple(action.choices) == described.choices, name
            else:
                assert described.range_text() in action.help, (name, action.help)
            if action.default is not None and default is not None:
                assert action.default == default, name
    assert checked >= least


def test_validate_takes_every_setting_of_the_validation():
    found = options(validate.parser())
    missing = [name for name in settings_of(ValidationSettings) if name not in found]
    assert not missing, missing
    assert {'resolution_m', 'min_duration_s', 'draws', 'nominal'} <= set(found)


def test_the_gap_option_says_the_shared_range():
    action = options(validate.parser())['gap_s']
    assert GAP_S.range_text() in action.help


def test_the_ros_docs_give_each_parameter_its_range():
    text = (REPO / 'docs' / 'ros.md').read_text()
    for node, specs in node_specs().items():
        section = text[text.index(f'Parameters of `{node}`'):]
        section = section[:section.index('\n\n', section.index('| --- |'))]
        for spec in specs():
            if spec.choices or not spec.range_text():
                continue
            row = re.search(rf'^\| `{re.escape(spec.name)}` \| [^|]* \| ([^|]*) \|', section,
                            re.MULTILINE)
            assert row is not None, (node, spec.name)
            assert row.group(1).strip() == spec.range_text(), (node, spec.name)


@pytest.mark.parametrize('name', ['rho', 'epsilon', 'delta', 'gamma'])
def test_a_probability_excludes_both_ends_everywhere(name):
    described = settings_of(ValidationSettings)[name][1]
    assert described.range_text() == '(0, 1)'
    for end in (0.0, 1.0):
        with pytest.raises(ParameterError, match=rf'{name} must lie in \(0, 1\)'):
            ValidationSettings(**{name: end})
    spec = next(spec for spec in node_specs()['validator']() if spec.name == name)
    assert spec.check(1.0) == f'{name} = 1.0 is outside (0, 1)'
    assert spec.check(0.999) is None
    assert 'ends excluded' in comment(spec) or '(0, 1)' in comment(spec)


def test_a_descriptor_is_closed_and_says_its_ends_are_excluded():
    pytest.importorskip('rcl_interfaces')
    spec = next(spec for spec in node_specs()['validator']() if spec.name == 'rho')
    descriptor = spec.descriptor()
    bounds = descriptor.floating_point_range[0]
    assert (bounds.from_value, bounds.to_value) == (0.0, 1.0)
    assert 'ends excluded' in descriptor.additional_constraints
    seed = next(spec for spec in node_specs()['validator']() if spec.name == 'seed')
    assert seed.descriptor().integer_range[0].from_value == 0


@pytest.mark.parametrize('record, values, reason', [
    (DiagnosisSettings, {'bootstrap': 2.5}, 'bootstrap must be a whole number, got 2.5'),
    (DiagnosisSettings, {'score_runs': True}, 'score_runs must be a whole number, got True'),
    (DiagnosisSettings, {'alpha': '0.01'},
     r'alpha must be a number, got text \(4 characters, not shown\)'),
    (DiagnosisSettings, {'alpha': math.nan}, 'alpha must be a finite number, got nan'),
    (DiagnosisSettings, {'min_gain': math.inf}, 'min_gain must be a finite number, got inf'),
    (DiagnosisSettings, {'decision_alpha': 1.0}, r'decision_alpha must lie in \(0, 1\), got 1.0'),
    (DiagnosisSettings, {'validate_models': 1}, 'validate_models must be true or false, got 1'),
    (DiagnosisSettings, {'bootstrap': np.True_}, 'bootstrap must be a whole number, got True'),
    (DiagnosisSettings, {'split_seed': -1}, 'split_seed must be non-negative, got -1'),
    (DiagnosisSettings, {'rounds': 0}, 'rounds must be at least 1, got 0'),
    (DiagnosisSettings, {'validation': {'rho': 0.1}},
     'validation must be a ValidationSettings, got a dict'),
    (ValidationSettings, {'k': 3.0}, 'k must be a whole number, got 3.0'),
    (ValidationSettings, {'seed': np.int64(-1)}, 'seed must be non-negative, got -1'),
    (ValidationSettings, {'seed': [1]}, 'seed must be a whole number, got a list'),
])
def test_a_setting_of_the_wrong_kind_or_outside_its_range_is_refused_in_one_line(
        record, values, reason):
    """The Python API refuses what the programs' options and the nodes' parameters refuse."""
    with pytest.raises(ParameterError, match=f'^{reason}$'):
        record(**values)


def test_every_knob_of_the_diagnosis_is_a_setting_with_its_range():
    """A knob that is not a Setting would go unchecked: all are, but the nested records."""
    names = {item.name for item in dataclasses.fields(DiagnosisSettings)}
    assert set(settings_of(DiagnosisSettings)) == names - {'validation', 'limit_terms'}
    assert DiagnosisSettings(split_seed=None, alpha=1e-3, heading_weight_m=0).split_seed is None
    # numpy's bool is true or false, as the entry points' flags take it
    assert not DiagnosisSettings(validate_models=np.False_).validate_models


def test_plan_refuses_a_setting_of_the_wrong_kind_before_any_work():
    from octoroach_model.studies.plan import plan_runs

    for values, reason in (({'power': 'most'}, 'power must be a number'),
                           ({'seed': 1.5}, 'seed must be a whole number, got 1.5'),
                           ({'budget_s': math.nan}, 'budget_s must be a finite number'),
                           ({'max_runs': 10}, 'max_runs must be at least 40, got 10')):
        with pytest.raises(ParameterError, match=reason):
            plan_runs('persistent_turning', 1.0, workers=0, **values)


def test_the_diagnosis_docs_list_every_setting_with_its_default_unit_and_range():
    text = (REPO / 'docs' / 'diagnosis.md').read_text()
    section = text[text.index('## 14. Its settings'):]
    for name, (default, described) in settings_of(DiagnosisSettings).items():
        row = re.search(rf'^\| `{name}` \| ([^|]*) \| ([^|]*) \| ([^|]*) \| ([^|]*) \|$', section,
                        re.MULTILINE)
        assert row is not None, name
        written = 'none' if default is None else str(default).lower()     # True: true
        assert [part.strip() for part in row.groups()] == [
            written, described.unit, described.range_text(), described.description], name


ANY_VALUE = st.one_of(st.none(), st.booleans(), st.integers(-10 ** 12, 10 ** 12),
                      st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=20),
                      st.lists(st.integers(), max_size=2), st.binary(max_size=4))


@seed(SEED)                                      # the suite's: OCTOROACH_TEST_SEED replays it
@hypothesis_settings(max_examples=150, deadline=None, database=None)
@given(data=st.data())
def test_any_value_of_any_setting_is_taken_or_refused_in_one_line(data):
    """Through the Python API a record takes a value or says why not: never a traceback."""
    record = data.draw(st.sampled_from([DiagnosisSettings, ValidationSettings, RunSettings]))
    name = data.draw(st.sampled_from(sorted(settings_of(record))))
    value = data.draw(ANY_VALUE)
    try:
        made = record(**{name: value})
    except ParameterError as error:
        assert '\n' not in str(error) and str(error).startswith(name), str(error)
        return
    assert getattr(made, name) == value, (name, value)     # NaN among them: never taken


def test_names_from_a_file_are_listed_where_they_look_like_names_and_counted_otherwise():
    from octoroach_model.settings import listed_names, looks_like_name

    assert listed_names(['octo:LFHD', '/vicon/octo/octo', 'My Robot']) == \
        'octo:LFHD, /vicon/octo/octo, My Robot'
    assert listed_names(['ok', '\x1b[31m', 'x' * 101, ' lead', 'semi;colon']) == \
        'ok and 4 names not shown'
    assert listed_names(['\n']) == '1 name not shown' and listed_names([]) == ''
    assert listed_names(['a'] * 14 + ['\t'], limit=12) == \
        'a, a, a, a, a, a, a, a, a, a, a, a and 2 more and 1 name not shown'
    assert looks_like_name('x' * 100) and not looks_like_name('x' * 101)
    assert not looks_like_name(5) and not looks_like_name('')


def test_a_bag_s_topics_are_listed_in_an_error_where_they_look_like_names_at_most_twelve():
    from collections import namedtuple

    from octoroach_model.recordings.bagio.reader import describe_topics

    info = namedtuple('info', 'msgtype')
    assert describe_topics({'/a': info('x/msg/Y'), '/b\x1b[2J': info('x/msg/Y')}) == \
        'it has /a [x/msg/Y] and 1 topic not shown'
    many = describe_topics({f'/t{i:02d}': info('x/msg/Y') for i in range(15)})
    assert many.endswith('/t11 [x/msg/Y] and 3 more') and '/t12' not in many, many
    assert describe_topics({}) == 'it has no topics'


@seed(SEED)
@hypothesis_settings(max_examples=150, deadline=None, database=None)
@given(st.lists(st.text(max_size=120) | st.sampled_from(['octo', 'a and b', ' x', 'x' * 101]),
                max_size=20), st.integers(1, 15))
@example(['octo', '\x1b[2J', 'a and b'], 1)
def test_a_listed_name_is_one_that_looks_like_a_name_and_every_other_is_counted(names, limit):
    """
    listed_names shows the names that look like names, in order, and only words of its own.

    Whatever the texts (escapes, long lines, a name with 'and' in it), the message is the
    first `limit` such names, then how many more, then how many were not shown.
    """
    import re

    from octoroach_model.settings import listed_names, looks_like_name

    said = listed_names(names, limit)
    good = [name for name in names if looks_like_name(name)]
    hidden = len(names) - len(good)
    head = ', '.join(good[:limit])
    assert said.startswith(head), (names, said)
    rest = said[len(head):]
    more = f' and {len(good) - limit} more' if len(good) > limit else ''
    counted = f' and {hidden} name{"s" if hidden > 1 else ""} not shown' if hidden else ''
    assert rest == (more + counted if head else (more + counted)[len(' and '):]), (names, said)
    assert re.fullmatch(r'[A-Za-z0-9_.:/@+\- ,]*', said), said
