"""
What one live run of the model needs, from plain parameter values (no ROS here).

The simulator node turns its ROS parameters into a `RunSettings` at the start of every run;
the run itself (`RunSettings.simulate`) and its seed (`RunSettings.run_seed`) come from here,
so a test or a benchmark can rebuild any run the node published from the same values.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
import math
import re
import secrets
from typing import Any

import numpy as np

from octoroach_model.errors import ParameterError
from octoroach_model.model import (
    check_effects, DRAWS, EFFECT_NAMES, EFFECT_PARAMETERS, ModelParameters, nominal_sigmas,
    PARAMETER_RANGES, simulate)
from octoroach_model.model.extensions import (
    DRIFT, DRIFTED, FAMILY_NAMES, FAMILY_PARAMETERS, family_terms, TERMS)
from octoroach_model.model.parameters import SIGMA_LIMIT
from octoroach_model.model.simulate import DEFAULT_START_POSE
from octoroach_model.paths import Paths
from octoroach_model.recordings import marker_topic, pose_topic
from octoroach_model.settings import check_fields, Setting, setting, shown

__all__ = ['ANGLE_DRAWS', 'EFFECT_PREFIX', 'EXTENSION_PREFIX', 'RunSettings', 'effect_settings',
           'extension_settings', 'marker_topic', 'pose_topic']

NAME = re.compile(r'^[A-Za-z][A-Za-z0-9_]*$')
FRAME = re.compile(r'^[A-Za-z0-9_/]+$')
EFFECT_PREFIX = 'effect_params.'  # effect parameter = EFFECT_PREFIX + the cause's key
EXTENSION_PREFIX = 'extension_params.'   # likewise for the extension family's keys
# the model's random leg angles, wherever a model runs (simulator, simulate, validator, validate)
ANGLE_DRAWS = Setting('the random leg angles: drawn anew at every stance, or once per run',
                      choices=DRAWS)


def _sigma(touchdown: bool) -> Any:
    """Return a field of an angle spread, its default Table III's (config/table2.yaml)."""
    return setting(default_factory=lambda: nominal_sigmas()[0 if touchdown else 1],
                   about=f'spread of the {"touchdown" if touchdown else "liftoff"} angles '
                   '(eq. 11)', unit='rad', low=0.0, high=SIGMA_LIMIT, open_high=True)


@dataclass(frozen=True)
class RunSettings:
    """
    The settings of one run of every robot, taken when the run starts.

    Lengths in metres, angles in radians, rates in Hz; `effect_params` keep the causes'
    own keys and units (`heading_std_deg`, `position_std_cm`, ...). Each field with a
    `settings.setting` is one of the simulator node's parameters (help, unit and range come
    from here); the defaults of the model's own values are Table II's (config/table2.yaml).
    """

    robots: int = setting(1, 'number of robots, each its own subject and topics', low=1,
                          high=100)
    subject: str = setting('octoroach', 'VICON subject name (robots > 1: SUBJECT_i)')
    segment: str = setting('', 'VICON segment name; empty: the subject name')
    world_frame: str = setting('vicon/world', 'header.frame_id of the poses')
    rate: float = setting(default_factory=lambda: ModelParameters.nominal().sample_rate,
                          about='publishing rate = model sample rate', unit='Hz', low=1.0,
                          high=1000.0)
    pause_s: float = setting(1.0, 'pause without poses between runs', unit='s', low=0.5,
                             high=3600.0)
    cycles: int = setting(10, 'gait cycles per run', low=1, high=1000)
    sigma1: float = _sigma(touchdown=True)
    sigma2: float = _sigma(touchdown=False)
    stride_frequency: float = setting(
        default_factory=lambda: ModelParameters.nominal().stride_frequency,
        about='gait cycles per second', unit='Hz', low=0.0, high=20.0, open_low=True)
    draws: str = setting(DRAWS[0], ANGLE_DRAWS)
    seed: int = setting(-1, 'run k uses a seed derived from (seed, k); -1: fresh entropy',
                        low=-1, high=2**31 - 1)
    start_x: float = setting(float(DEFAULT_START_POSE[0]), 'x at the start of every run',
                             unit='m', low=-1000.0, high=1000.0)
    start_y: float = setting(float(DEFAULT_START_POSE[1]), 'y at the start of every run',
                             unit='m', low=-1000.0, high=1000.0)
    start_heading: float = setting(float(DEFAULT_START_POSE[2]), 'heading at the start (pi/2: '
                                   'along +y)', unit='rad', low=-2 * math.pi, high=2 * math.pi)
    effect: str = setting('none', 'model extension: a cause (docs/ros.md) added to every run',
                          choices=('none', *EFFECT_NAMES))
    effect_params: Mapping[str, float] = field(default_factory=dict)
    runs: int = setting(0, 'runs to publish, then exit (0: go on until stopped)', low=0,
                        high=1_000_000)
    extension: str = setting('none', 'an extension family beyond the table of causes '
                             '(docs/extensions.md) added to the runs; run_order_drift needs '
                             'runs >= 2', choices=('none', *FAMILY_NAMES))
    extension_params: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        check_fields(self)

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> RunSettings:
        """Make settings from parameter values; ParameterError where they do not fit."""
        for key in ('subject', 'segment'):
            if values[key] and not NAME.match(values[key]):
                raise ParameterError(f'{key} must be a name: a letter, then letters, digits '
                                     f'or _; got {shown(values[key])}')
        if not values['subject']:
            raise ParameterError('subject must not be empty')
        if not FRAME.match(values['world_frame']):
            raise ParameterError('world_frame must be a frame name of letters, digits, _ and '
                                 f'/; got {shown(values["world_frame"])}')
        settings = cls(
            robots=int(values['robots']), subject=values['subject'],
            segment=values['segment'], world_frame=values['world_frame'],
            rate=float(values['rate']), pause_s=float(values['pause_s']),
            cycles=int(values['cycles']), sigma1=float(values['sigma1']),
            sigma2=float(values['sigma2']),
            stride_frequency=float(values['stride_frequency']), draws=values['draws'],
            seed=int(values['seed']),
            start_x=float(values['start_x']), start_y=float(values['start_y']),
            start_heading=float(values['start_heading']),
            effect=values['effect'],
            effect_params={key[len(EFFECT_PREFIX):]: float(value)
                           for key, value in values.items() if key.startswith(EFFECT_PREFIX)},
            runs=int(values.get('runs', 0)), extension=values.get('extension', 'none'),
            extension_params={key[len(EXTENSION_PREFIX):]: value for key, value in values.items()
                              if key.startswith(EXTENSION_PREFIX)})
        check_effects(settings.effects())
        family_terms(settings.extensions())
        if settings.extension == DRIFT and settings.runs < 2:
            raise ParameterError('extension run_order_drift needs runs >= 2: run k of the '
                                 'session sits at k / (runs - 1) of the drift')
        settings.model_parameters()  # ParameterError where rate or frequency cannot be used
        return settings

    @property
    def start_pose(self) -> tuple[float, float, float]:
        """Return (x, y, heading) at the start of every run."""
        return (self.start_x, self.start_y, self.start_heading)

    def subjects(self) -> list[tuple[str, str]]:
        """Return (subject, segment) of each robot."""
        if self.robots == 1:
            return [(self.subject, self.segment or self.subject)]
        return [(f'{self.subject}_{i}', f'{self.segment}_{i}' if self.segment
                 else f'{self.subject}_{i}') for i in range(self.robots)]

    def effects(self) -> dict[str, dict[str, float]] | None:
        """Return {effect: {key: value}} for `simulate`, None without an effect."""
        if self.effect == 'none':
            return None
        return {self.effect: {key: self.effect_params.get(key, 0.0)
                              for key in EFFECT_PARAMETERS[self.effect]}}

    def extensions(self) -> list[tuple[str, dict[str, Any]]]:
        """Return [(family, parameters)] for `simulate` (empty without an extension)."""
        if self.extension == 'none':
            return []
        keys = FAMILY_PARAMETERS[self.extension]
        return [(self.extension, {key: self.extension_params[key] for key in keys
                                  if key in self.extension_params})]

    def model_parameters(self) -> ModelParameters:
        """Return Table II with this stride frequency and sample rate."""
        return replace(ModelParameters.nominal(), stride_frequency=self.stride_frequency,
                       sample_rate=self.rate)

    def run_seed(self, run_index: int) -> int:
        """Return the seed of run `run_index`: from (seed, index), or fresh entropy (seed < 0)."""
        if self.seed < 0:
            return secrets.randbits(63)
        state = np.random.SeedSequence([self.seed, run_index]).generate_state(2, np.uint32)
        return int(state[0]) << 31 | int(state[1]) >> 1

    def simulate(self, seed: int, run_index: int = 0) -> Paths:
        """
        Draw one run per robot: Paths with poses (robots, T, 3).

        Run `run_index` of a session of `runs` sits at run_index / (runs - 1) of the
        recording (what a run-order drift reads).
        """
        place = min(run_index / (self.runs - 1), 1.0) if self.runs > 1 else 0.0
        return simulate(self.robots, seed=seed, sigma1=self.sigma1, sigma2=self.sigma2,
                        cycles=self.cycles, parameters=self.model_parameters(),
                        draws=self.draws, effects=self.effects(), start_pose=self.start_pose,
                        extensions=self.extensions(), positions=np.full(self.robots, place))


_EFFECT_UNITS = {'_deg_s': 'deg/s', '_cm_s': 'cm/s', '_deg': 'deg', '_cm': 'cm'}


def effect_settings() -> dict[str, tuple[float, Setting]]:
    """
    Return {effect_params.KEY: (default, Setting)}: the parameters of the causes.

    Made from the model's tables (PARAMETER_RANGES, EFFECT_PARAMETERS), their one source;
    the unit is the key's suffix (heading_std_deg: deg).
    """
    found = {}
    for key, (low, high) in PARAMETER_RANGES.items():
        users = ', '.join(name for name, keys in EFFECT_PARAMETERS.items() if key in keys)
        unit = next((unit for suffix, unit in _EFFECT_UNITS.items() if key.endswith(suffix)),
                    '1')
        found[EFFECT_PREFIX + key] = (0.0, Setting(f'parameter of {users}', unit, float(low),
                                                   float(high)))
    return found


def extension_settings() -> dict[str, tuple[Any, Setting]]:
    """
    Return {extension_params.KEY: (default, Setting)}: the parameters of the extension terms.

    Made from the terms (`model.extensions.TERMS`), their one source: a key several terms
    use gets the widest range.
    """
    found: dict[str, tuple[Any, Setting]] = {
        EXTENSION_PREFIX + 'parameter': (DRIFTED[0], Setting(
            f'what {DRIFT} moves over the session', choices=DRIFTED))}
    for key, (default, unit, low, high, users) in extension_parameter_table().items():
        found[EXTENSION_PREFIX + key] = (default, Setting(f'parameter of {users}', unit, low,
                                                          high))
    return found


def extension_parameter_table() -> dict[str, tuple[float, str, float, float, str]]:
    """
    Each numeric key of the extension terms: default, unit, widest range, terms using it.

    run_order_drift's `change` takes the unit of what drifts (relative, deg/s or cm/s).
    """
    table: dict[str, tuple[float, str, float, float, str]] = {}
    for term in TERMS:
        for key, unit, (low, high) in zip(term.parameters, term.units, term.ranges):
            default = float(term.defaults.get(key, 0.0))
            if key in table:
                old = table[key]
                table[key] = (old[0], old[1] if old[1] == unit else 'see the family',
                              min(old[2], low), max(old[3], high), f'{old[4]}, {term.name}')
            else:
                table[key] = (default, unit or '1', low, high, term.name)
    return table
