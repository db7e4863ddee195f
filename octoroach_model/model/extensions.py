"""
Extension families: generic model terms for effects that no cause of the table names.

Each family is defined on a run of the paper's model (docs/extensions.md, same notation as the
table of causes). Runs are numbered i = 0..n-1 in the order they were recorded, and run i sits
at `position` q_i = i / (n - 1) in the recording (0 for the first run, 1 for the last). A heading
perturbation a(t) turns heading and velocity together: theta'(t) = theta(t) + a(t),
p'(t) = p(0) + integral_0^t R(a(s)) p_dot(s) ds.

- run_order_drift (parameter, change): a parameter moves linearly with the run's place:
  stride_frequency (relative): run i is p((1 + change q_i) t); yaw_rate (deg/s):
  a(t) = change q_i t; lateral_velocity (cm/s): as lateral_slip at change q_i;
  touchdown_angle_k, k = 1..4 (deg, a leg that wears): run i strides with phi_k + change
  (q_i - 1/2), its pair's liftoff angle following by eqs. (7)-(8) (centred, so that the
  geometry fitted to the mean path is the session's middle run's). phi1, phi2 are the right
  pair's rear and front legs, phi3, phi4 the left pair's (Table II's order).
- heading_random_walk (step_std_deg): at each stance after the first the heading takes an
  independent N(0, s^2) step that stays.
- periodic_heading (amplitude_deg, frequency_hz): a(t) = A (sin(2 pi f t + phi) - sin(phi)),
  phi uniform per run.
- change_point (time_s, speed_factor): the gait clock runs at speed_factor times its rate from
  time_s on.
- run_mixture (fraction, yaw_rate_deg_s): a share `fraction` of the runs (drawn
  independently) turns at yaw_rate: a(t) = w t.
- yaw_rate_ramp (final_yaw_rate_deg_s): every run turns at a yaw rate that rises linearly
  from 0 at t = 0 to w at t = T (the runs' full duration): a(t) = w t^2 / (2 T).

In an effects mapping a family is a *term*: `run_order_drift` is four terms, one per parameter
it moves (`run_order_drift:stride_frequency`, ...), each with the single parameter `change`,
so that two drifts can sit in one model; every other family is one term of its own name.
`family_terms` converts the family form ({family: {parameter: value}}, the form of the CLI
and of the report) into terms. Each term draws from its own random stream (RandomStreams), so
adding one leaves every other draw unchanged.

Adding a family: one `ExtensionTerm` entry below with its function (one of five stages: the
shared gait clock, each run's clock stretch, each run's touchdown angle, a heading
perturbation, or a sideways drift), and its declaration in `diagnosis/causes.py`. A new term
goes last: a term's random stream is its place in the list.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
import math
from typing import Protocol

import numpy as np
from scipy import special

from octoroach_model.arrays import FloatArray
from octoroach_model.errors import ParameterError
from octoroach_model.settings import number, unknown_name

DRIFT = 'run_order_drift'
# the touchdown angle each wear moves, as its column in (phi1, phi2, phi3, phi4)
WORN_ANGLES = {f'touchdown_angle_{leg}': leg - 1 for leg in (1, 2, 3, 4)}
# each leg in words, by its column
LEG_NAMES = ("the right pair's rear leg", "the right pair's front leg",
             "the left pair's rear leg", "the left pair's front leg")
DRIFTED = ('stride_frequency', 'yaw_rate', 'lateral_velocity', *WORN_ANGLES)
DRIFT_UNITS = {'stride_frequency': '', 'yaw_rate': 'deg/s', 'lateral_velocity': 'cm/s',
               **dict.fromkeys(WORN_ANGLES, 'deg')}


def drift_term(parameter: str) -> str:
    """Return the term of a run-order drift of `parameter`."""
    return f'{DRIFT}:{parameter}'


# each worn leg's term (run_order_drift:touchdown_angle_k) -> its column in (phi1 .. phi4)
WORN_TERMS = {drift_term(parameter): column for parameter, column in WORN_ANGLES.items()}


class NormalSource(Protocol):
    """Where an effect draws its normals: a numpy Generator, or one giving antithetic pairs."""

    def standard_normal(self, size: int | tuple[int, ...]) -> FloatArray:
        """Draw standard normals of shape `size`."""


@dataclass(frozen=True)
class TermContext:
    """
    What a term needs to know about the runs it acts on.

    t: (T,) sample times [s]; positions: (n,) place of each run in the recording, 0..1;
    phase: (n, T) or (T,) stance phase (2 x stride frequency x gait clock; stance k begins at
    phase k); duration: the runs' full duration T [s]; source: the term's random stream.
    """

    t: FloatArray
    positions: FloatArray
    duration: float
    source: NormalSource | None          # set for each term before it is applied
    phase: FloatArray | None = None
    clock_of: Callable[[FloatArray], FloatArray] | None = None   # the gait clock so far


@dataclass(frozen=True)
class ExtensionTerm:
    """
    One term of an extension family, as the simulator applies it.

    `stage`: 'clock' returns the shared gait clock (T,) changed from `context.clock_of` (the
    clock of the terms before it, a function of time); 'stretch' multiplies each run's gait
    clock by a factor (n,); 'angles' returns each run's change of the four touchdown angles
    [rad] (n, 4); 'heading' returns a heading perturbation a(t) (n, T); 'drift'
    returns each run's sideways velocity [m/s] (n,).
    """

    name: str
    family: str
    parameters: tuple[str, ...]
    units: tuple[str, ...]
    ranges: tuple[tuple[float, float], ...]
    stage: str
    function: Callable[[Mapping[str, float], TermContext], FloatArray]
    defaults: Mapping[str, float] = field(default_factory=dict)

    def checked(self, values: Mapping[str, float]) -> dict[str, float]:
        """Return all parameters of the term, missing ones at their default, ranges checked."""
        extra = set(values) - set(self.parameters)
        if extra:
            raise ParameterError(f'{self.name} has no parameter '
                                 f'{unknown_name(sorted(extra)[0], self.parameters)}; it takes '
                                 f'{", ".join(self.parameters)}')
        checked = {}
        for key, (low, high) in zip(self.parameters, self.ranges):
            value = number(f'{self.name}.{key}', values.get(key, self.defaults.get(key, 0.0)))
            if not (math.isfinite(value) and low <= value <= high):
                raise ParameterError(f'{self.name}.{key} = {value} is outside [{low}, {high}]')
            checked[key] = value
        return checked


def uniforms(source: NormalSource, size: int | tuple[int, ...]) -> FloatArray:
    """Uniform numbers in (0, 1) from a normal source (antithetic normals stay antithetic)."""
    uniform: FloatArray = special.ndtr(source.standard_normal(size))
    return uniform


def _drift_stretch(values: Mapping[str, float], context: TermContext) -> FloatArray:
    stretch: FloatArray = 1.0 + values['change'] * context.positions
    return stretch


def _drift_yaw(values: Mapping[str, float], context: TermContext) -> FloatArray:
    rate = math.radians(values['change']) * context.positions
    heading: FloatArray = rate[:, None] * context.t[None, :]
    return heading


def _drift_slip(values: Mapping[str, float], context: TermContext) -> FloatArray:
    velocity: FloatArray = values['change'] / 100.0 * context.positions
    return velocity


def _drift_touchdown(column: int) -> Callable[[Mapping[str, float], TermContext], FloatArray]:
    """Return the drift of the touchdown angle in `column`: (n, 4), zero in the others."""
    def offsets(values: Mapping[str, float], context: TermContext) -> FloatArray:
        # centred on the session's middle run, whose geometry a fit of the mean path finds
        moved = np.zeros((len(context.positions), 4))
        moved[:, column] = math.radians(values['change']) * (context.positions - 0.5)
        return moved
    return offsets


def _random_walk(values: Mapping[str, float], context: TermContext) -> FloatArray:
    """
    a(t) = sum of the steps of the stances begun after 0 and by t (stance k begins at phase k).

    The steps are drawn for a whole number of blocks of 64 stances, so that a slightly
    different stride frequency (a fit's next trial) keeps the same random numbers.
    """
    assert context.phase is not None, 'a heading random walk needs the stance phase'
    assert context.source is not None, 'a term draws from its own stream'
    phase = np.broadcast_to(context.phase, (len(context.positions), len(context.t)))
    begun = np.floor(phase + 1e-9).astype(int)               # steps taken by t
    stances = 64 * max(1, -(-int(begun.max()) // 64))
    steps = math.radians(values['step_std_deg']) * context.source.standard_normal(
        (len(context.positions), stances))
    walk = np.concatenate([np.zeros((len(context.positions), 1)), np.cumsum(steps, axis=1)],
                          axis=1)
    heading: FloatArray = np.take_along_axis(walk, np.clip(begun, 0, stances), axis=1)
    return heading


def _periodic(values: Mapping[str, float], context: TermContext) -> FloatArray:
    assert context.source is not None, 'a term draws from its own stream'
    phi = 2.0 * math.pi * uniforms(context.source, len(context.positions))
    angle = 2.0 * math.pi * values['frequency_hz'] * context.t[None, :] + phi[:, None]
    heading: FloatArray = math.radians(values['amplitude_deg']) * (np.sin(angle)
                                                                   - np.sin(phi)[:, None])
    return heading


def _change_point(values: Mapping[str, float], context: TermContext) -> FloatArray:
    """From time_s on, the clock runs at speed_factor times the rate it had: tau(t)."""
    clock_of = context.clock_of or (lambda times: times)
    clock = clock_of(context.t)
    at_change = clock_of(np.array([values['time_s']]))[0]
    after = context.t >= values['time_s']
    return np.where(after, at_change + values['speed_factor'] * (clock - at_change), clock)


def _mixture(values: Mapping[str, float], context: TermContext) -> FloatArray:
    assert context.source is not None, 'a term draws from its own stream'
    turning = uniforms(context.source, len(context.positions)) < values['fraction']
    rate = np.where(turning, math.radians(values['yaw_rate_deg_s']), 0.0)
    heading: FloatArray = rate[:, None] * context.t[None, :]
    return heading


def _ramp(values: Mapping[str, float], context: TermContext) -> FloatArray:
    rise = math.radians(values['final_yaw_rate_deg_s']) / max(context.duration, 1e-9)
    heading: FloatArray = np.broadcast_to(0.5 * rise * context.t ** 2,
                                          (len(context.positions), len(context.t)))
    return heading


TERMS: tuple[ExtensionTerm, ...] = (
    ExtensionTerm(drift_term('stride_frequency'), DRIFT, ('change',), ('',), ((-0.9, 0.9),),
                  'stretch', _drift_stretch),
    ExtensionTerm(drift_term('yaw_rate'), DRIFT, ('change',), ('deg/s',), ((-90.0, 90.0),),
                  'heading', _drift_yaw),
    ExtensionTerm(drift_term('lateral_velocity'), DRIFT, ('change',), ('cm/s',),
                  ((-50.0, 50.0),), 'drift', _drift_slip),
    ExtensionTerm('heading_random_walk', 'heading_random_walk', ('step_std_deg',), ('deg',),
                  ((0.0, 45.0),), 'heading', _random_walk),
    ExtensionTerm('periodic_heading', 'periodic_heading', ('amplitude_deg', 'frequency_hz'),
                  ('deg', 'Hz'), ((0.0, 90.0), (0.0, 100.0)), 'heading', _periodic,
                  {'frequency_hz': 0.5}),
    ExtensionTerm('change_point', 'change_point', ('time_s', 'speed_factor'), ('s', ''),
                  ((0.0, 1e4), (0.05, 5.0)), 'clock', _change_point, {'speed_factor': 1.0}),
    ExtensionTerm('run_mixture', 'run_mixture', ('fraction', 'yaw_rate_deg_s'), ('', 'deg/s'),
                  ((0.0, 1.0), (-90.0, 90.0)), 'heading', _mixture),
    ExtensionTerm('yaw_rate_ramp', 'yaw_rate_ramp', ('final_yaw_rate_deg_s',), ('deg/s',),
                  ((-90.0, 90.0),), 'heading', _ramp),
    # last, so that the streams of the terms before keep their places (they draw nothing)
    *(ExtensionTerm(drift_term(parameter), DRIFT, ('change',), ('deg',), ((-60.0, 60.0),),
                    'angles', _drift_touchdown(column))
      for parameter, column in WORN_ANGLES.items()),
)
TERM_BY_NAME = {term.name: term for term in TERMS}
TERM_NAMES = tuple(TERM_BY_NAME)
FAMILY_NAMES = tuple(dict.fromkeys(term.family for term in TERMS))
# the family form of each family's parameters (run_order_drift names what drifts)
FAMILY_PARAMETERS: dict[str, tuple[str, ...]] = {
    DRIFT: ('parameter', 'change'),
    **{term.family: term.parameters for term in TERMS if term.family != DRIFT}}

Extensions = Mapping[str, Mapping[str, object]] | Iterable[tuple[str, Mapping[str, object]]]


def family_terms(extensions: Extensions | None) -> dict[str, dict[str, float]]:
    """
    Convert extensions in family form into model terms (module docstring), checked.

    `extensions` is {family: {parameter: value}} or a sequence of (family, parameters) pairs
    (several run_order_drift entries, one per drifting parameter).
    """
    pairs = extensions.items() if isinstance(extensions, Mapping) else (extensions or ())
    terms: dict[str, dict[str, float]] = {}
    for family, given in pairs:
        if family not in FAMILY_PARAMETERS:
            raise ParameterError(f'unknown extension, {unknown_name(family, FAMILY_NAMES)}; '
                                 f'known: {", ".join(FAMILY_NAMES)}')
        values = dict(given)
        if family == DRIFT:
            drifted = values.pop('parameter', None)
            if drifted == 'touchdown_angle':
                raise ParameterError(f'{DRIFT}: touchdown_angle is touchdown_angle_3 (phi3) '
                                     'since each leg has its own, touchdown_angle_1 .. _4')
            if drifted not in DRIFTED:
                raise ParameterError(f'{DRIFT} needs parameter = one of {", ".join(DRIFTED)}, '
                                     f'got {unknown_name(drifted, DRIFTED)}')
            name = drift_term(str(drifted))
        else:
            name = family
        if name in terms:
            raise ParameterError(f'extension {name} is given twice')
        terms[name] = TERM_BY_NAME[name].checked(_numbers(name, values))
    return terms


def _numbers(name: str, values: Mapping[str, object]) -> dict[str, float]:
    """Return a term's parameters as floats; a text is refused, not parsed (the CLI parses)."""
    return {key: number(f'{name}.{key}', value) for key, value in values.items()}


def family_form(term: str, values: Mapping[str, float]) -> tuple[str, dict[str, float | str]]:
    """Return (family, parameters) of a term, as the CLI and the report write it."""
    family = TERM_BY_NAME[term].family
    if family == DRIFT:
        return family, {'parameter': term.split(':', 1)[1], **values}
    return family, dict(values)


def positions_in_order(n_runs: int) -> FloatArray:
    """Return q_i = i / (n - 1), each run's place in a recording of `n_runs` runs."""
    return np.linspace(0.0, 1.0, n_runs) if n_runs > 1 else np.zeros(n_runs)
