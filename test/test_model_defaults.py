"""
One source of defaults: the paper's values come from config/table2.yaml and nowhere else.

The shipped file holds Table II and III; an edited copy, named by OCTOROACH_MODEL_TABLE2 or
passed as a path, changes every default of the model at once (docs/model.md, "Where the
numbers live").
"""
from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
import yaml

import octoroach_model as om
from octoroach_model.errors import ParameterError
from octoroach_model.model import parameters as parameters_module
from octoroach_model.model.parameters import (
    CONFIG_ENVIRONMENT, config_path, load_nominal, ModelParameters, nominal_sigmas)
from octoroach_model.validation import FourBarModel

REPO = Path(__file__).resolve().parents[1]

# An edited Table II/III, every value moved from the paper's (SI units, as in the file).
EDITED = {
    'hip_distance': 0.11,
    'leg_length': 0.025,
    'touchdown_angles': [0.70, 0.75, 0.72, 0.78],
    'liftoff_angles': [-0.70, -0.72],
    'stride_frequency': 2.5,
    'sample_rate': 40.0,
    'sigma1': 0.0937,
    'sigma2': 0.0441,
}


def shipped_values() -> dict:
    """Read the section of the repository's config/table2.yaml."""
    return yaml.safe_load((REPO / 'config' / 'table2.yaml').read_text())['octoroach_model']


def write_table(path: Path, values: dict) -> Path:
    """Write a table2.yaml of the shipped form with `values` in its section."""
    path.write_text(yaml.safe_dump({'octoroach_model': values}, sort_keys=False))
    return path


@pytest.fixture
def edited_copy(tmp_path) -> Path:
    """Write a copy of the shipped file with every value changed."""
    return write_table(tmp_path / 'table2.yaml', {**shipped_values(), **EDITED})


@pytest.fixture(autouse=True)
def shipped_file(monkeypatch):
    """Every test starts from the shipped file, whatever the calling environment says."""
    monkeypatch.delenv(CONFIG_ENVIRONMENT, raising=False)


def edited_parameters() -> ModelParameters:
    return ModelParameters(
        hip_distance=EDITED['hip_distance'], leg_length=EDITED['leg_length'],
        touchdown_angles=tuple(EDITED['touchdown_angles']),
        liftoff_angles=tuple(EDITED['liftoff_angles']),
        stride_frequency=EDITED['stride_frequency'], sample_rate=EDITED['sample_rate'])


# --------------------------------------------------------------------------------------------
# The shipped file is the paper's

def test_the_shipped_file_holds_table_ii_in_si_units():
    table = ModelParameters.nominal().table()
    assert table['hip_distance_cm'] == pytest.approx(13.0)
    assert table['leg_length_cm'] == pytest.approx(2.1)
    np.testing.assert_allclose(table['touchdown_angles_deg'], [45.3, 39.6, 39.9, 47.0],
                               atol=1e-4)
    np.testing.assert_allclose(table['liftoff_angles_deg'], [-39.6, -39.9], atol=1e-4)


def test_the_shipped_liftoff_angles_follow_from_touchdown_by_eqs_7_and_8():
    nominal = ModelParameters.nominal()
    np.testing.assert_allclose(nominal.liftoff_angles,
                               nominal.with_paper_liftoff().liftoff_angles, rtol=0, atol=1e-12)


def test_the_shipped_file_holds_table_iii_and_the_chosen_timing():
    assert nominal_sigmas() == (0.12, 0.15)
    nominal = ModelParameters.nominal()
    assert (nominal.stride_frequency, nominal.sample_rate) == (2.0, 50.0)
    assert load_nominal().source == config_path()


def test_no_field_of_the_model_parameters_has_a_default_of_its_own():
    assert all(field.default is dataclasses.MISSING
               and field.default_factory is dataclasses.MISSING
               for field in dataclasses.fields(ModelParameters))
    with pytest.raises(TypeError):
        ModelParameters()


def test_simulate_without_spreads_is_table_iii():
    runs = om.simulate(20, seed=4)
    explicit = om.simulate(20, seed=4, sigma1=0.12, sigma2=0.15)
    assert (runs.info['sigma1'], runs.info['sigma2']) == (0.12, 0.15)
    np.testing.assert_array_equal(runs.poses, explicit.poses)


# --------------------------------------------------------------------------------------------
# An edited copy changes every path

def check_every_path_follows(edited: ModelParameters, **where) -> None:
    """
    Check that every reader of the defaults gives the edited values.

    ModelParameters.nominal, nominal_sigmas, simulate and the validation's default model;
    `where` is the path argument, or nothing for the environment.
    """
    assert ModelParameters.nominal(**where) == edited
    assert nominal_sigmas(**where) == (EDITED['sigma1'], EDITED['sigma2'])
    if where:
        return
    runs = om.simulate(30, seed=11)
    assert (runs.info['sigma1'], runs.info['sigma2']) == (EDITED['sigma1'], EDITED['sigma2'])
    # 10 cycles at 2.5 Hz are 4 s; at 40 Hz that is 161 samples
    np.testing.assert_allclose(runs.t, np.arange(161) / 40.0, rtol=0, atol=1e-12)
    assert runs.info['parameters'] == edited.table()
    assert FourBarModel().parameters == edited


def test_an_edited_copy_named_by_the_environment_changes_every_default(
        edited_copy, monkeypatch):
    shipped_runs = om.simulate(30, seed=11)
    monkeypatch.setenv(CONFIG_ENVIRONMENT, str(edited_copy))
    edited = edited_parameters()
    check_every_path_follows(edited)
    assert load_nominal().source == edited_copy
    runs = om.simulate(30, seed=11)
    # exactly the model with those values passed explicitly (same seed, same draws) ...
    monkeypatch.delenv(CONFIG_ENVIRONMENT)
    explicit = om.simulate(30, seed=11, parameters=edited, sigma1=EDITED['sigma1'],
                           sigma2=EDITED['sigma2'])
    np.testing.assert_array_equal(runs.poses, explicit.poses)
    # ... and not the shipped one: the path has another shape and length
    assert runs.t.shape != shipped_runs.t.shape
    assert abs(runs.poses[:, -1, 1].mean() - shipped_runs.poses[:, -1, 1].mean()) > 0.01


def test_an_edited_copy_passed_as_a_path_changes_the_loaders(edited_copy):
    check_every_path_follows(edited_parameters(), path=edited_copy)
    # ... without touching the process-wide default
    assert nominal_sigmas() == (0.12, 0.15)


def test_the_offline_programs_take_their_defaults_from_the_named_file(edited_copy):
    env = dict(os.environ, **{CONFIG_ENVIRONMENT: str(edited_copy)})
    helped = subprocess.run([sys.executable, '-m', 'octoroach_model', 'simulate', '--help'],
                            env=env, capture_output=True, text=True, timeout=120)
    assert helped.returncode == 0, helped.stderr
    assert '0.0937' in helped.stdout and '0.0441' in helped.stdout, helped.stdout


def test_a_file_edited_in_place_is_read_again(edited_copy, monkeypatch):
    monkeypatch.setenv(CONFIG_ENVIRONMENT, str(edited_copy))
    assert nominal_sigmas() == (EDITED['sigma1'], EDITED['sigma2'])
    write_table(edited_copy, {**shipped_values(), **EDITED, 'sigma1': 0.2})
    stamp = edited_copy.stat().st_mtime_ns + 10 ** 9   # a coarse clock cannot hide the edit
    os.utime(edited_copy, ns=(stamp, stamp))
    assert nominal_sigmas() == (0.2, EDITED['sigma2'])
    assert om.simulate(2, seed=1).info['sigma1'] == 0.2


# --------------------------------------------------------------------------------------------
# A bad file is one clear reason

@pytest.mark.parametrize('change, message', [
    ({'leg_length': None}, r'octoroach_model\.leg_length is missing'),
    ({'touchdown_angles': [0.7, 0.7, 0.7]}, r'touchdown_angles must be a list of 4 finite'),
    ({'liftoff_angles': -0.7}, r'liftoff_angles must be a list of 2 finite'),
    ({'stride_frequency': 'SECRET'}, r'stride_frequency must be a finite number, got text '
                                     r'\(6 characters, not shown\)'),
    ({'touchdown_angles': [0.7, 'SECRET', 0.7, 0.7]}, r'touchdown_angles must be .*, got a list'),
    ({'sample_rate': True}, r'sample_rate must be a finite number'),
    ({'hip_distance': float('nan')}, r'hip_distance must be a finite number'),
    ({'hip_distance': -0.13}, r'hip_distance and leg_length must be positive'),
    ({'sigma2': 2.0}, r'sigma2 = 2\.0 is outside \[0, 1\.5\) rad'),
], ids=['missing key', 'three touchdown angles', 'liftoff not a list', 'text for a number',
        'text among the angles', 'boolean for a number', 'not finite', 'negative length',
        'sigma out of range'])
def test_a_bad_file_raises_a_parameter_error_naming_the_file_and_the_key(
        tmp_path, change, message):
    values = {**shipped_values(), **change}
    values = {key: value for key, value in values.items() if value is not None}
    path = write_table(tmp_path / 'bad.yaml', values)
    with pytest.raises(ParameterError, match=message) as raised:
        load_nominal(path)
    assert str(path) in str(raised.value)
    assert '\n' not in str(raised.value) and 'SECRET' not in str(raised.value)


def test_a_file_without_the_section_or_not_yaml_is_one_reason(tmp_path):
    no_section = tmp_path / 'no_section.yaml'
    no_section.write_text('other_package:\n  leg_length: 0.02\n')
    with pytest.raises(ParameterError, match="no 'octoroach_model' section"):
        load_nominal(no_section)
    broken = tmp_path / 'broken.yaml'
    broken.write_text('octoroach_model: [unclosed\n')
    with pytest.raises(ParameterError, match='cannot read nominal parameters from') as raised:
        load_nominal(broken)
    assert '\n' not in str(raised.value)


def test_a_missing_file_named_by_the_environment_says_so(tmp_path, monkeypatch):
    missing = tmp_path / 'nowhere.yaml'
    monkeypatch.setenv(CONFIG_ENVIRONMENT, str(missing))
    for default in (ModelParameters.nominal, nominal_sigmas, lambda: om.simulate(2, seed=1)):
        with pytest.raises(ParameterError, match=f'{missing}.*from {CONFIG_ENVIRONMENT}'):
            default()


def test_an_empty_environment_variable_means_the_shipped_file(monkeypatch):
    monkeypatch.setenv(CONFIG_ENVIRONMENT, '  ')
    assert parameters_module.table2_path() == config_path()
    assert math.isclose(ModelParameters.nominal().leg_length, 0.021)
