"""
A study spec: which robots, causes, sizes and run counts to diagnose, checked before work.

A spec is a YAML mapping (docs/studies.md lists every key, its default and unit). Loading it
gives a frozen `StudySpec` whose every value has been checked, so that a study never starts on
a spec that would fail half-way: an unknown cause, a negative size, a range whose low end lies
above its high end are one-line `ParameterError`s. `StudySpec.to_json()` is the normalised spec
(defaults filled in) and `spec_hash` its fingerprint, which `--resume` compares.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
import dataclasses
from dataclasses import dataclass, field
from enum import StrEnum
import hashlib
import math
from pathlib import Path
from typing import Any

from octoroach_model.diagnosis.diagnose import MIN_RUNS
from octoroach_model.errors import ParameterError
from octoroach_model.jsonio import dumps
from octoroach_model.limit_setting import check_term_names
from octoroach_model.model.effects import parameter_range
from octoroach_model.settings import number as real_number, shown, unknown_name
from octoroach_model.studies.terms import (
    main_parameter, parameters as term_parameters, signed, term_named, term_of, TERMS)

SIGNED_CAUSES = tuple(term for term in TERMS if signed(term))   # main parameter has a sign
NULL = 'none'
# DiagnosisSettings fields a spec may set (the seed comes from each replicate); a replicate
# is one Dask task, so its diagnosis runs in that task's process (workers: 1)
DIAGNOSIS_DEFAULTS: dict[str, Any] = {'validate_models': False, 'workers': 1}


@dataclass(frozen=True)
class Draw:
    """
    A value of the robot space.

    Fixed (low == high), uniform on [low, high], or one of `choices` with equal chances.
    `at(u)` maps one uniform number u in [0, 1) to the value, so every key consumes exactly
    one draw whatever its kind (draws of other keys stay put).
    """

    low: float
    high: float
    choices: tuple[float, ...] = ()

    @classmethod
    def fixed(cls, value: float) -> Draw:
        return cls(float(value), float(value))

    def at(self, u: float) -> float:
        if self.choices:
            return self.choices[min(int(u * len(self.choices)), len(self.choices) - 1)]
        return self.low + u * (self.high - self.low)

    @property
    def values(self) -> tuple[float, ...]:
        """Return both ends of the range (or every choice), for range checks."""
        return self.choices or (self.low, self.high)

    def to_json(self) -> Any:
        if self.choices:
            return {'choice': list(self.choices)}
        return self.low if self.low == self.high else {'low': self.low, 'high': self.high}


@dataclass(frozen=True)
class RobotSpec:
    """
    The robot space replicates are drawn from; every key a `Draw`, in the units named.

    touchdown_angles_deg are the base angles phi1..phi4 (default Table II); each gets its own
    draw of touchdown_offset_deg added. spread_scale multiplies Table III's (sigma1, sigma2).
    """

    leg_length_cm: Draw
    hip_distance_cm: Draw
    stride_frequency_hz: Draw
    cycles: Draw
    sample_rate_hz: Draw
    spread_scale: Draw
    touchdown_offset_deg: Draw
    touchdown_angles_deg: tuple[float, float, float, float]

    DRAWN = ('leg_length_cm', 'hip_distance_cm', 'stride_frequency_hz', 'cycles',
             'sample_rate_hz', 'spread_scale')

    def to_json(self) -> dict:
        plain = {name: getattr(self, name).to_json() for name in self.DRAWN}
        plain['touchdown_offset_deg'] = self.touchdown_offset_deg.to_json()
        plain['touchdown_angles_deg'] = list(self.touchdown_angles_deg)
        return plain


class ArmKind(StrEnum):
    """
    What an arm puts into data (see `Arm`).

    The paper's model (null), one cause at an absolute size, one cause at a multiple of the
    limit the diagnosis reported on the same replicate's null data (relative), or several
    causes at once (together).
    """

    NULL = 'null'
    ABSOLUTE = 'absolute'
    RELATIVE = 'relative'
    TOGETHER = 'together'


class Sign(StrEnum):
    """The sign of a cause's size in an arm: as given, negated, or drawn per replicate."""

    POSITIVE = 'positive'
    NEGATIVE = 'negative'
    BOTH = 'both'

    @property
    def mark(self) -> str:
        """Return the sign as an arm's label writes it before the size."""
        return {Sign.POSITIVE: '', Sign.NEGATIVE: '-', Sign.BOTH: '+-'}[self]

    @property
    def sides(self) -> tuple[float, ...]:
        """Return the factors a size may take (+1, -1 or both)."""
        return {Sign.POSITIVE: (1.0,), Sign.NEGATIVE: (-1.0,), Sign.BOTH: (1.0, -1.0)}[self]


@dataclass(frozen=True)
class Arm:
    """One kind of data set of the design: its kind, its label, and what it puts into data."""

    kind: ArmKind
    label: str
    effects: tuple[tuple[str, tuple[tuple[str, float], ...]], ...] = ()
    cause: str = ''
    size: float = math.nan
    limit_multiple: float = math.nan
    sign: Sign = Sign.POSITIVE

    @property
    def causes(self) -> tuple[str, ...]:
        return (self.cause,) if self.cause else tuple(name for name, _ in self.effects)

    def effect_dict(self) -> dict[str, dict[str, float]]:
        return {name: dict(params) for name, params in self.effects}


@dataclass(frozen=True)
class DamageSpec:
    """
    Damage applied to each simulated data set.

    A share of runs end early (poses NaN after their end) somewhere in `cut_at` of the
    duration, and a share of frames are dropped (filled by linear interpolation, as the bag
    readers fill them).
    """

    cut_share: float = 0.0
    cut_at: Draw = Draw(0.7, 0.95)
    dropped_frames: float = 0.0

    @property
    def active(self) -> bool:
        return self.cut_share > 0 or self.dropped_frames > 0

    def to_json(self) -> dict:
        return {'cut_share': self.cut_share, 'cut_at': self.cut_at.to_json(),
                'dropped_frames': self.dropped_frames}


@dataclass(frozen=True)
class StudySpec:
    """
    A whole study: robots, arms (causes and sizes), run counts, replicates, damage, seed.

    `runs` is either a tuple of run counts (a factor of the design: every arm at every count)
    or a `Draw` (each replicate draws its own count). Every arm is run on every replicate.
    """

    name: str
    seed: int
    replicates: int
    runs: tuple[int, ...] | Draw
    robot: RobotSpec
    arms: tuple[Arm, ...]
    damage: DamageSpec = DamageSpec()
    diagnosis: tuple[tuple[str, Any], ...] = ()
    source: str = field(default='', compare=False)

    @property
    def run_cells(self) -> tuple[int | None, ...]:
        """Return the run counts of the design; (None,) when each replicate draws its own."""
        return self.runs if isinstance(self.runs, tuple) else (None,)

    def diagnosis_settings(self, seed: int):
        """Return one replicate's DiagnosisSettings: the spec's overrides and its seed."""
        from octoroach_model.diagnosis import DiagnosisSettings

        return DiagnosisSettings(**{**DIAGNOSIS_DEFAULTS, **dict(self.diagnosis), 'seed': seed})

    def to_json(self) -> dict:
        return {
            'name': self.name, 'seed': self.seed, 'replicates': self.replicates,
            'runs': list(self.runs) if isinstance(self.runs, tuple) else self.runs.to_json(),
            'robot': self.robot.to_json(),
            'causes': [_arm_json(arm) for arm in self.arms],
            'damage': self.damage.to_json(),
            'diagnosis': {**DIAGNOSIS_DEFAULTS, **dict(self.diagnosis)},
        }

    @property
    def spec_hash(self) -> str:
        """Return the fingerprint of the normalised spec (comments and key order do not count)."""
        return hashlib.sha256(dumps(self.to_json()).encode()).hexdigest()[:16]


def _arm_json(arm: Arm) -> dict:
    plain: dict[str, Any] = {'kind': arm.kind, 'label': arm.label}
    if arm.cause:
        plain['cause'] = arm.cause
    if arm.effects:
        plain['effects'] = arm.effect_dict()
    if arm.kind == ArmKind.ABSOLUTE:
        plain['size'] = arm.size
    if arm.kind == ArmKind.RELATIVE:
        plain['limit_multiple'] = arm.limit_multiple
    if arm.cause:
        plain['sign'] = arm.sign
    return plain


# --------------------------------------------------------------------------------------------
# loading and checking

TOP_KEYS = ('name', 'seed', 'replicates', 'runs', 'robot', 'causes', 'damage', 'diagnosis')
ROBOT_KEYS = (*RobotSpec.DRAWN, 'touchdown_offset_deg', 'touchdown_angles_deg')
DAMAGE_KEYS = ('cut_share', 'cut_at', 'dropped_frames')
CAUSE_KEYS = ('cause', 'extension', 'parameter', 'sizes', 'limit_multiples', 'parameters',
              'sign', 'together')
# (low, high) accepted for each robot key, in its unit; high may be inf
ROBOT_LIMITS: dict[str, tuple[float, float]] = {
    'leg_length_cm': (0.1, 20.0), 'hip_distance_cm': (1.0, 100.0),
    'stride_frequency_hz': (0.05, 50.0), 'cycles': (1.0, 1000.0),
    'sample_rate_hz': (1.0, 10000.0), 'spread_scale': (0.0, 10.0),
    'touchdown_offset_deg': (-30.0, 30.0),
}
MAX_SIGMA_RAD = 1.5


def load_spec(path: str | Path) -> StudySpec:
    """Read and check a spec file; one-line ParameterError for anything wrong."""
    from octoroach_model.fileio import user_path
    from octoroach_model.safe_yaml import load_yaml_file

    path = user_path(path, 'the spec')
    data = load_yaml_file(path, ParameterError, f'the spec {path}')
    spec = parse_spec(data, default_name=path.stem)
    return dataclasses.replace(spec, source=str(path))


def parse_spec(data: Any, default_name: str = 'study') -> StudySpec:
    """Check the mapping a YAML spec holds and return it as a StudySpec."""
    data = _mapping(data, 'the spec')
    _known(data, TOP_KEYS, 'the spec')
    name = str(data.get('name', default_name))
    seed = _whole(data.get('seed', 0), 'seed', minimum=0)
    replicates = _whole(data.get('replicates', 1), 'replicates', minimum=1)
    runs = _runs(data.get('runs', [500]))
    robot = _robot(_mapping(data.get('robot', {}), 'robot'))
    arms = _arms(data.get('causes', [NULL]))
    damage = _damage(_mapping(data.get('damage', {}), 'damage'))
    diagnosis = _diagnosis(_mapping(data.get('diagnosis', {}), 'diagnosis'))
    spec = StudySpec(name, seed, replicates, runs, robot, arms, damage, diagnosis)
    _check_robot_space(spec)
    _check_limits_read(spec)
    return spec


def nominal_robot() -> RobotSpec:
    """Return Table II's robot (fixed values) as a RobotSpec."""
    return _robot({})


def robot_spec(values: Mapping[str, Any]) -> RobotSpec:
    """Check a mapping of robot keys (missing keys: Table II); return a RobotSpec."""
    robot = _robot(_mapping(values, 'robot'))
    _check_robot_space(StudySpec('robot', 0, 1, (100,), robot, (Arm(ArmKind.NULL, NULL),)))
    return robot


def _runs(value: Any) -> tuple[int, ...] | Draw:
    if isinstance(value, Mapping):
        draw = _draw(value, 'runs')
        if min(draw.values) < MIN_RUNS:
            raise ParameterError(f'runs: the diagnosis needs at least {MIN_RUNS} runs, '
                                 f'got {min(draw.values):g}')
        return draw
    counts = value if isinstance(value, list) else [value]
    if not counts:
        raise ParameterError('runs: give at least one run count')
    checked = tuple(_whole(count, 'runs', minimum=MIN_RUNS,
                           why=f'the diagnosis needs at least {MIN_RUNS} runs')
                    for count in counts)
    if len(set(checked)) != len(checked):
        raise ParameterError(f'runs: a run count is listed twice in {list(checked)}')
    return checked


def _robot(values: Mapping[str, Any]) -> RobotSpec:
    from octoroach_model.model import ModelParameters

    _known(values, ROBOT_KEYS, 'robot')
    nominal = ModelParameters.nominal()
    defaults = {'leg_length_cm': nominal.leg_length * 100,
                'hip_distance_cm': nominal.hip_distance * 100,
                'stride_frequency_hz': nominal.stride_frequency, 'cycles': 10.0,
                'sample_rate_hz': nominal.sample_rate, 'spread_scale': 1.0,
                'touchdown_offset_deg': 0.0}
    draws = {}
    for key, default in defaults.items():
        draw = _draw(values.get(key, default), f'robot.{key}')
        low, high = ROBOT_LIMITS[key]
        if not all(low <= value <= high for value in draw.values):
            raise ParameterError(f'robot.{key} must lie in [{low:g}, {high:g}], '
                                 f'got {draw.to_json()}')
        draws[key] = draw
    angles = values.get('touchdown_angles_deg',
                        [math.degrees(a) for a in nominal.touchdown_angles])
    if not (isinstance(angles, list) and len(angles) == 4):
        raise ParameterError('robot.touchdown_angles_deg must be a list of 4 angles (deg)')
    phi1, phi2, phi3, phi4 = (_number(a, 'robot.touchdown_angles_deg') for a in angles)
    base = (phi1, phi2, phi3, phi4)
    if not all(0 < a < 90 for a in base):
        raise ParameterError(f'robot.touchdown_angles_deg must lie in (0, 90), got {list(base)}')
    return RobotSpec(touchdown_angles_deg=base, **draws)


def _check_robot_space(spec: StudySpec) -> None:
    """Check every corner of the robot space: angles in range, spreads < 1.5, sampling."""
    from octoroach_model.model import nominal_sigmas

    robot = spec.robot
    offsets = robot.touchdown_offset_deg.values
    angles = [a + o for a in robot.touchdown_angles_deg for o in offsets]
    if not all(0 < a < 90 for a in angles):
        raise ParameterError('robot: touchdown angles plus touchdown_offset_deg leave (0, 90) '
                             'deg')
    widest = max(nominal_sigmas()) * max(robot.spread_scale.values)
    if widest >= MAX_SIGMA_RAD:
        raise ParameterError(f'robot.spread_scale: {max(robot.spread_scale.values):g} x Table '
                             f'III gives an angle spread of {widest:.2f} rad, above '
                             f'{MAX_SIGMA_RAD}')
    fastest = max(robot.stride_frequency_hz.values)
    slowest_rate = min(robot.sample_rate_hz.values)
    if slowest_rate < 4 * fastest:
        raise ParameterError(f'robot: a sample rate of {slowest_rate:g} Hz cannot follow a '
                             f'stride of {fastest:g} Hz (need at least 4 samples per cycle)')


def _arms(value: Any) -> tuple[Arm, ...]:
    items = value if isinstance(value, list) else [value]
    if not items:
        raise ParameterError('causes: give at least one entry (none, or a cause with sizes)')
    arms: list[Arm] = []
    for number, item in enumerate(items, 1):
        where = f'causes[{number}]'
        if item == NULL or item is None:
            arms.append(Arm(ArmKind.NULL, NULL))
            continue
        if isinstance(item, str):
            raise ParameterError(f'{where}: {unknown_name(item, (NULL,))}: write none, or a '
                                 f'mapping such as {{cause: persistent_turning, sizes: [...]}}')
        item = _mapping(item, where)
        _known(item, CAUSE_KEYS, where)
        if 'together' in item:
            arms.append(_together(item, where))
        else:
            arms.extend(_single(item, where))
    unique: list[Arm] = []
    for arm in arms:
        if any(other.label == arm.label for other in unique):
            if arm.kind == ArmKind.NULL:
                continue
            raise ParameterError(f'causes: {arm.label} is listed twice')
        unique.append(arm)
    if any(arm.kind == ArmKind.RELATIVE for arm in unique) and not any(
            arm.kind == ArmKind.NULL for arm in unique):
        # a limit multiple is read off the replicate's null data set: diagnose it as well
        unique.append(Arm(ArmKind.NULL, NULL))
    # the null arm first: relative arms need its limits, and tasks run in arm order
    return tuple(sorted(unique, key=lambda arm: arm.kind != ArmKind.NULL))


def _single(item: Mapping[str, Any], where: str) -> list[Arm]:
    cause = term_of(item, where)
    main = main_parameter(cause)
    raw = item.get('sign', Sign.POSITIVE)
    given = str(raw)
    if given not in tuple(Sign):
        raise ParameterError(f'{where}.sign must be one of {", ".join(Sign)}, got '
                             f'{unknown_name(raw, tuple(Sign))}')
    sign = Sign(given)
    if sign != Sign.POSITIVE and cause not in SIGNED_CAUSES:
        raise ParameterError(f'{where}.sign: {cause} has no sign (only '
                             f'{", ".join(SIGNED_CAUSES)} do)')
    extra = _parameters(cause, item.get('parameters', {}), f'{where}.parameters')
    if main in dict(extra):
        raise ParameterError(f'{where}.parameters: {main} is the main parameter; its values '
                             f'are the sizes')
    has_sizes, has_multiples = 'sizes' in item, 'limit_multiples' in item
    if has_sizes == has_multiples:
        raise ParameterError(f'{where}: give either sizes (in the unit of {main}) or '
                             f'limit_multiples (of the reported detection limit)')
    if has_sizes:
        sizes = _positive_list(item['sizes'], f'{where}.sizes')
        for size in sizes:
            _check_size(cause, size, sign, f'{where}.sizes')
        return [Arm(ArmKind.ABSOLUTE, f'{cause}={sign.mark}{size:g}',
                    ((cause, ((main, size), *extra)),), cause=cause, size=size, sign=sign)
                for size in sizes]
    multiples = _positive_list(item['limit_multiples'], f'{where}.limit_multiples')
    return [Arm(ArmKind.RELATIVE, f'{cause}@{sign.mark}{multiple:g}x', ((cause, extra),),
                cause=cause, limit_multiple=multiple, sign=sign) for multiple in multiples]


def _together(item: Mapping[str, Any], where: str) -> Arm:
    if set(item) != {'together'}:
        raise ParameterError(f'{where}: together takes no other key (got '
                             f'{", ".join(sorted(set(item) - {"together"}))})')
    causes = _mapping(item['together'], f'{where}.together')
    if len(causes) < 2:
        raise ParameterError(f'{where}.together: name at least two causes or extension terms')
    effects = []
    for cause, value in causes.items():
        cause = term_named(cause, f'{where}.together')
        main = main_parameter(cause)
        if isinstance(value, Mapping):
            params = _parameters(cause, value, f'{where}.together.{cause}')
            if main not in dict(params):
                raise ParameterError(f'{where}.together.{cause}: give its main parameter '
                                     f'{main}')
        else:
            size = _positive_list([value], f'{where}.together.{cause}')[0]
            params = ((main, size),)
            _check_parameter(cause, main, size, f'{where}.together.{cause}')
        effects.append((cause, params))
    label = '+'.join(f'{cause}={dict(params)[main_parameter(cause)]:g}'
                     for cause, params in effects)
    return Arm(ArmKind.TOGETHER, label, tuple(effects))


def _parameters(cause: str, value: Any, where: str) -> tuple[tuple[str, float], ...]:
    params = _mapping(value, where)
    checked = []
    for key, number in params.items():
        if key not in term_parameters(cause):
            raise ParameterError(f'{where}: {cause} has no parameter '
                                 f'{unknown_name(key, term_parameters(cause))}; it takes '
                                 f'{", ".join(term_parameters(cause))}')
        number = _number(number, f'{where}.{key}')
        _check_parameter(cause, key, number, f'{where}.{key}')
        checked.append((str(key), number))
    return tuple(checked)


def _check_parameter(cause: str, key: str, value: float, where: str) -> None:
    low, high = parameter_range(cause, key)
    if not low <= value <= high:
        raise ParameterError(f'{where}: {cause}.{key} = {value:g} is outside [{low:g}, '
                             f'{high:g}]')


def _check_size(cause: str, size: float, sign: Sign, where: str) -> None:
    """Check a size (a distance from the value of no effect, with the arm's signs)."""
    from octoroach_model.studies.terms import null_value

    main = main_parameter(cause)
    for side in sign.sides:
        _check_parameter(cause, main, null_value(cause) + side * size, where)


def _positive_list(value: Any, where: str) -> tuple[float, ...]:
    items = value if isinstance(value, list) else [value]
    if not items:
        raise ParameterError(f'{where}: give at least one value')
    numbers = tuple(_number(item, where) for item in items)
    for number in numbers:
        if number <= 0:
            raise ParameterError(f'{where}: sizes are magnitudes and must be positive, got '
                                 f'{number:g} (the model of the paper is the entry none; a '
                                 f'sign is set with sign:)')
    return numbers


def _damage(values: Mapping[str, Any]) -> DamageSpec:
    _known(values, DAMAGE_KEYS, 'damage')
    cut_share = _number(values.get('cut_share', 0.0), 'damage.cut_share')
    dropped = _number(values.get('dropped_frames', 0.0), 'damage.dropped_frames')
    cut_at = _draw(values.get('cut_at', {'low': 0.7, 'high': 0.95}), 'damage.cut_at')
    if not 0 <= cut_share <= 1:
        raise ParameterError(f'damage.cut_share must lie in [0, 1], got {cut_share:g}')
    if not 0 <= dropped < 0.5:
        raise ParameterError(f'damage.dropped_frames must lie in [0, 0.5), got {dropped:g}')
    if not all(0 < value <= 1 for value in cut_at.values):
        raise ParameterError(f'damage.cut_at must lie in (0, 1] (a share of the duration), '
                             f'got {cut_at.to_json()}')
    return DamageSpec(cut_share, cut_at, dropped)


def _diagnosis(values: Mapping[str, Any]) -> tuple[tuple[str, Any], ...]:
    from octoroach_model.diagnosis import DiagnosisSettings

    defaults = DiagnosisSettings()
    settable = {f.name: getattr(defaults, f.name) for f in dataclasses.fields(DiagnosisSettings)
                if f.name != 'seed' and isinstance(getattr(defaults, f.name), (bool, int, float))}
    settable['limit_terms'] = ()
    checked: list[tuple[str, Any]] = []
    for key, value in values.items():
        if key == 'limit_terms':
            checked.append((key, _limit_terms(value)))
            continue
        if key not in settable:
            raise ParameterError(f'diagnosis: no setting {unknown_name(key, list(settable))}; '
                                 f'settable: {", ".join(sorted(settable))}')
        default = settable[key]
        if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)            # YAML's 1 for 1.0: the same spec, the same hash
        checked.append((str(key), value))
    try:                                # each value's kind and range: the settings' own checks
        DiagnosisSettings(**dict(checked))
    except ParameterError as error:
        raise ParameterError(f'diagnosis.{error}') from None
    return tuple(sorted(checked))


def _limit_terms(value: Any) -> tuple[str, ...]:
    """Check diagnosis.limit_terms: a list of the terms whose whole limits nulls compute."""
    if not isinstance(value, list) or not all(isinstance(name, str) for name in value):
        raise ParameterError('diagnosis.limit_terms must be a list of term names')
    check_term_names(value, 'diagnosis.limit_terms')
    return tuple(sorted(set(value)))


def _check_limits_read(spec: StudySpec) -> None:
    """Refuse limit multiples of a term whose whole limit the null data sets would not compute."""
    settings = dict(spec.diagnosis)
    terms = settings.get('limit_terms', ())
    for arm in spec.arms:
        if arm.kind != ArmKind.RELATIVE:
            continue
        if settings.get('detection_limits') is False:
            raise ParameterError(f"causes: {arm.cause}'s limit_multiples are of the detection "
                                 'limit the null data sets compute: diagnosis.detection_limits '
                                 'must not be false')
        if terms and arm.cause not in terms:
            raise ParameterError(f"causes: {arm.cause}'s limit_multiples are of the detection "
                                 f'limit the null data sets compute: add {arm.cause} to '
                                 'diagnosis.limit_terms')


def _draw(value: Any, where: str) -> Draw:
    if isinstance(value, Mapping):
        if set(value) == {'choice'}:
            choices = value['choice']
            if not isinstance(choices, list) or not choices:
                raise ParameterError(f'{where}.choice must be a non-empty list')
            return Draw(math.nan, math.nan, tuple(_number(c, where) for c in choices))
        if set(value) != {'low', 'high'}:
            raise ParameterError(f'{where}: a range is {{low: A, high: B}} and a set of '
                                 f'values {{choice: [A, B, ...]}}; got keys '
                                 f'{", ".join(map(str, value))}')
        low, high = _number(value['low'], f'{where}.low'), _number(value['high'],
                                                                   f'{where}.high')
        if low > high:
            raise ParameterError(f'{where}: bad range, low {low:g} is above high {high:g}')
        return Draw(low, high)
    return Draw.fixed(_number(value, where))


def _number(value: Any, where: str) -> float:
    number = real_number(where, value)          # the kind; a text is not quoted from the file
    if not math.isfinite(number):
        raise ParameterError(f'{where} must be finite, got {number}')
    return number


def _whole(value: Any, where: str, minimum: int, why: str = '') -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ParameterError(f'{where} must be a whole number, got {shown(value)}')
    if value < minimum:
        reason = f' ({why})' if why else ''
        raise ParameterError(f'{where} must be at least {minimum}, got {value}{reason}')
    return int(value)


def _mapping(value: Any, where: str) -> Mapping[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ParameterError(f'{where} must be a mapping of keys to values, got '
                             f'{type(value).__name__}')
    return value


def _known(values: Mapping[str, Any], keys: Sequence[str], where: str) -> None:
    unknown = [key for key in values if key not in keys]
    if unknown:
        raise ParameterError(f'{where}: unknown key, {unknown_name(unknown[0], keys)}; known: '
                             f'{", ".join(keys)}')
