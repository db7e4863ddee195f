"""
Parameters of the switching four-bar model (docs/model.md), SI units throughout.

The paper's values are read from one file, in one place (`load_nominal`): Table II (geometry
and nominal angles), Table III (the angle spreads sigma1, sigma2) and the timing (the stride
frequency, which the paper leaves open, and the 50 Hz sample rate). The model's defaults come
from there: `ModelParameters.nominal()`, `nominal_sigmas()`, and through them `simulate()`,
the simulator node and the `simulate` program. No module of model/ repeats the numbers.

The file is config/table2.yaml: the installed share directory's, or in a source checkout the
repository's. The environment variable OCTOROACH_MODEL_TABLE2 names another file of the same
form instead (an edited copy, for a robot other than the paper's); `load_nominal`,
`ModelParameters.nominal` and `nominal_sigmas` also take that path as an argument. The file is
read again whenever it changes.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache
import math
import os
from pathlib import Path
from typing import NoReturn, TypedDict

import numpy as np

from octoroach_model.arrays import FloatArray
from octoroach_model.errors import ParameterError
from octoroach_model.settings import is_number, shown

CONFIG_NAME = 'table2.yaml'
CONFIG_ENVIRONMENT = 'OCTOROACH_MODEL_TABLE2'
CONFIG_SECTION = 'octoroach_model'
SIGMA_LIMIT = 1.5   # rad; spreads at or beyond it make the stances meaningless


def config_path(name: str = CONFIG_NAME) -> Path:
    """Where a config file is: the ament share directory when installed, else the checkout."""
    shared = _share_directory()
    if shared is not None and (shared / name).is_file():
        return shared / name
    return Path(__file__).resolve().parents[2] / 'config' / name


@lru_cache(maxsize=1)
def _share_directory() -> Path | None:
    try:
        from ament_index_python.packages import get_package_share_directory

        return Path(get_package_share_directory('octoroach_model')) / 'config'
    except Exception:  # noqa: BLE001 - not installed through ament: fall back to the checkout
        return None


def table2_path(path: str | os.PathLike[str] | None = None) -> Path:
    """
    Name the file the nominal values come from.

    That is `path` if given, else the file named by $OCTOROACH_MODEL_TABLE2, else the shipped
    config/table2.yaml (`config_path`).
    """
    if path is not None:
        return Path(path)
    named = os.environ.get(CONFIG_ENVIRONMENT, '').strip()
    if named:
        return Path(named)
    return config_path()


class ParameterTable(TypedDict):
    """The parameters as the paper prints them, for reports (`ModelParameters.table`)."""

    hip_distance_cm: float
    leg_length_cm: float
    touchdown_angles_deg: list[float]
    liftoff_angles_deg: list[float]
    stride_frequency_hz: float


class StartPoseTable(TypedDict):
    """A start pose as reports print it: position in cm, heading in degrees."""

    x_cm: float
    y_cm: float
    heading_deg: float


@dataclass(frozen=True)
class ModelParameters:
    """
    Geometry, nominal angles and timing of the model (every field required).

    Angles are in radians; touchdown_angles = (phi1, phi2, phi3, phi4), liftoff_angles =
    (phi_R, phi_L). stride_frequency counts full gait cycles (right + left stance) per second.
    `ModelParameters.nominal()` gives the paper's values.
    """

    hip_distance: float
    leg_length: float
    touchdown_angles: tuple[float, float, float, float]
    liftoff_angles: tuple[float, float]
    stride_frequency: float
    sample_rate: float

    def __post_init__(self) -> None:
        """
        Reject values of another kind, or that no model run can use, in one line.

        The fits build one at every evaluation of their residuals (`dataclasses.replace`), so
        the kinds are asked in one quick pass (`_kinds_hold`, about 0.5 us); only a refused
        value looks for which field it was.
        """
        if not self._kinds_hold():
            self._refuse_kind()
        if not (self.hip_distance > 0 and self.leg_length > 0):
            raise ParameterError('hip_distance and leg_length must be positive metres')
        if not (self.stride_frequency > 0 and self.sample_rate > 0):
            raise ParameterError('stride_frequency and sample_rate must be positive (Hz)')

    def _kinds_hold(self) -> bool:
        """Tell whether every field is a number, and the angles tuples of 4 and 2 numbers."""
        touchdown, liftoff = self.touchdown_angles, self.liftoff_angles
        return (isinstance(touchdown, tuple) and len(touchdown) == 4
                and isinstance(liftoff, tuple) and len(liftoff) == 2
                and all(map(is_number, (self.hip_distance, self.leg_length,
                                        self.stride_frequency, self.sample_rate)
                            + touchdown + liftoff)))

    def _refuse_kind(self) -> NoReturn:
        """Raise the ParameterError that names the first field of a wrong kind."""
        for name, unit in (('hip_distance', 'metres'), ('leg_length', 'metres'),
                           ('stride_frequency', 'Hz'), ('sample_rate', 'Hz')):
            value = getattr(self, name)
            if not is_number(value):
                raise ParameterError(f'{name} must be a number ({unit}), got {shown(value)}')
        for name, count in (('touchdown_angles', 4), ('liftoff_angles', 2)):
            angles = getattr(self, name)
            if not isinstance(angles, tuple):
                got = shown(angles)
            elif len(angles) != count:
                got = f'{len(angles)} of them'
            else:
                got = next((f'{shown(angle)} among them' for angle in angles
                            if not is_number(angle)), '')
            if got:
                raise ParameterError(f'{name} must be a tuple of {count} numbers (rad), got '
                                     f'{got}')
        raise AssertionError('_refuse_kind called on fields of the right kinds')

    @classmethod
    def nominal(cls, path: str | os.PathLike[str] | None = None) -> ModelParameters:
        """Table II of the paper, from config/table2.yaml (or `path`, see `table2_path`)."""
        return load_nominal(path).parameters

    @property
    def nominal_angles(self) -> FloatArray:
        """eta^n of eq. (12): (6,) touchdown then liftoff angles, radians."""
        return np.array(self.touchdown_angles + self.liftoff_angles, dtype=float)

    def with_paper_liftoff(self) -> ModelParameters:
        """Liftoff angles from the touchdown angles by eqs. (7)-(8)."""
        phi = self.touchdown_angles
        return replace(self, liftoff_angles=(-min(phi[0], phi[1]), -min(phi[2], phi[3])))

    def duration(self, cycles: float) -> float:
        """Seconds that `cycles` gait cycles take."""
        return cycles / self.stride_frequency

    def samples(self, cycles: float) -> int:
        """Return how many samples a run of `cycles` cycles has, both ends included."""
        return int(round(self.duration(cycles) * self.sample_rate)) + 1

    def time_grid(self, cycles: float) -> FloatArray:
        """Sample times of a run of `cycles` cycles, both ends included, at sample_rate."""
        return np.arange(self.samples(cycles)) / self.sample_rate

    def table(self) -> ParameterTable:
        """Give the parameters as the paper prints them (cm, deg), for reports."""
        return {
            'hip_distance_cm': float(self.hip_distance * 100),
            'leg_length_cm': float(self.leg_length * 100),
            'touchdown_angles_deg': [float(math.degrees(a)) for a in self.touchdown_angles],
            'liftoff_angles_deg': [float(math.degrees(a)) for a in self.liftoff_angles],
            'stride_frequency_hz': float(self.stride_frequency),
        }


@dataclass(frozen=True)
class NominalValues:
    """Everything config/table2.yaml holds: the nominal model and the spreads of Table III."""

    parameters: ModelParameters
    sigma1: float      # rad, spread of the touchdown angles (eq. 11)
    sigma2: float      # rad, spread of the liftoff angles (eq. 11)
    source: Path       # the file they were read from


def load_nominal(path: str | os.PathLike[str] | None = None) -> NominalValues:
    """Read the nominal values from `table2_path(path)`; a ParameterError says what is wrong."""
    where = table2_path(path)
    try:
        status = where.stat()
    except OSError as error:
        origin = f' (from {CONFIG_ENVIRONMENT})' if path is None and \
            os.environ.get(CONFIG_ENVIRONMENT, '').strip() else ''
        raise ParameterError(f'cannot read nominal parameters from {where}{origin}: '
                             f'{error.strerror or error}') from None
    return _read_nominal(str(where), status.st_mtime_ns, status.st_size)


def nominal_sigmas(path: str | os.PathLike[str] | None = None) -> tuple[float, float]:
    """(sigma1, sigma2) of Table III, radians, from config/table2.yaml (or `path`)."""
    values = load_nominal(path)
    return values.sigma1, values.sigma2


@lru_cache(maxsize=8)
def _read_nominal(path: str, mtime_ns: int, size: int) -> NominalValues:
    """Parse and check one version of the file (the cache key changes when the file does)."""
    from octoroach_model.safe_yaml import load_yaml_file

    document = load_yaml_file(Path(path), ParameterError,
                              f'cannot read nominal parameters from {path}')
    section = document.get(CONFIG_SECTION) if isinstance(document, dict) else None
    if not isinstance(section, dict):
        raise ParameterError(f'{path}: no {CONFIG_SECTION!r} section with the nominal values')

    def numbers(key: str, count: int | None = None) -> tuple[float, ...]:
        """section[key] as a tuple of `count` floats, or of its one float if count is None."""
        if key not in section:
            raise ParameterError(f'{path}: {CONFIG_SECTION}.{key} is missing')
        value = section[key]
        items = value if count is not None and isinstance(value, list) else [value]
        if (count is not None and (not isinstance(value, list) or len(value) != count)) or \
                not all(_is_finite_number(item) for item in items):
            kind = f'a list of {count} finite numbers' if count else 'a finite number'
            raise ParameterError(f'{path}: {CONFIG_SECTION}.{key} must be {kind}, '
                                 f'got {shown(value)}')
        return tuple(float(item) for item in items)

    def number(key: str) -> float:
        """section[key] as a float."""
        return numbers(key)[0]

    hip_distance, leg_length = number('hip_distance'), number('leg_length')
    phi1, phi2, phi3, phi4 = numbers('touchdown_angles', 4)
    phi_right, phi_left = numbers('liftoff_angles', 2)
    stride_frequency, sample_rate = number('stride_frequency'), number('sample_rate')
    try:
        parameters = ModelParameters(hip_distance, leg_length, (phi1, phi2, phi3, phi4),
                                     (phi_right, phi_left), stride_frequency, sample_rate)
    except ParameterError as error:
        raise ParameterError(f'{path}: {error}') from None
    sigma1, sigma2 = number('sigma1'), number('sigma2')
    for key, sigma in (('sigma1', sigma1), ('sigma2', sigma2)):
        if not 0.0 <= sigma < SIGMA_LIMIT:
            raise ParameterError(f'{path}: {CONFIG_SECTION}.{key} = {sigma} is outside '
                                 f'[0, {SIGMA_LIMIT}) rad')
    return NominalValues(parameters, sigma1, sigma2, Path(path))


def _is_finite_number(value: object) -> bool:
    """Tell a finite YAML int or float (YAML's true and false are not numbers here)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value)
