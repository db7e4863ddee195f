"""Parameters of the switching four-bar model (NOTES.md section 2), SI units throughout.

The nominal values (Table II) live in config/table2.yaml; `ModelParameters.nominal()` reads
them from the installed share directory or, in a source checkout, from the repository.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from octoroach_model.errors import ParameterError

CONFIG_NAME = 'table2.yaml'


def config_path(name: str = CONFIG_NAME) -> Path:
    """Where a config file is: the ament share directory when installed, else the checkout."""
    try:
        from ament_index_python.packages import get_package_share_directory

        shared = Path(get_package_share_directory('octoroach_model')) / 'config' / name
        if shared.is_file():
            return shared
    except Exception:  # noqa: BLE001 - not installed through ament: fall back to the checkout
        pass
    return Path(__file__).resolve().parents[2] / 'config' / name


@dataclass(frozen=True)
class ModelParameters:
    """Geometry, nominal angles and timing of the model.

    Angles are in radians; touchdown_angles = (phi1, phi2, phi3, phi4), liftoff_angles =
    (phi_R, phi_L). stride_frequency counts full gait cycles (right + left stance) per second.
    """

    hip_distance: float = 0.13
    leg_length: float = 0.021
    touchdown_angles: tuple[float, float, float, float] = (
        0.790634, 0.691150, 0.696386, 0.820305)
    liftoff_angles: tuple[float, float] = (-0.691150, -0.696386)
    stride_frequency: float = 2.0
    sample_rate: float = 50.0

    def __post_init__(self) -> None:
        if not (self.hip_distance > 0 and self.leg_length > 0):
            raise ParameterError('hip_distance and leg_length must be positive metres')
        if not (self.stride_frequency > 0 and self.sample_rate > 0):
            raise ParameterError('stride_frequency and sample_rate must be positive (Hz)')
        if len(self.touchdown_angles) != 4 or len(self.liftoff_angles) != 2:
            raise ParameterError('need 4 touchdown angles and 2 liftoff angles (rad)')

    @classmethod
    def nominal(cls) -> ModelParameters:
        """Table II of the paper (from config/table2.yaml)."""
        return _load_nominal()

    @property
    def nominal_angles(self) -> np.ndarray:
        """eta^n of eq. (12): (6,) touchdown then liftoff angles, radians."""
        return np.array(self.touchdown_angles + self.liftoff_angles, dtype=float)

    def with_paper_liftoff(self) -> ModelParameters:
        """Liftoff angles from the touchdown angles by eqs. (7)-(8)."""
        phi = self.touchdown_angles
        return replace(self, liftoff_angles=(-min(phi[0], phi[1]), -min(phi[2], phi[3])))

    def duration(self, cycles: float) -> float:
        """Seconds that `cycles` gait cycles take."""
        return cycles / self.stride_frequency

    def time_grid(self, cycles: float) -> np.ndarray:
        """Sample times of a run of `cycles` cycles, both ends included, at sample_rate."""
        n_samples = int(round(self.duration(cycles) * self.sample_rate)) + 1
        return np.arange(n_samples) / self.sample_rate

    def table(self) -> dict:
        """The parameters as the paper prints them (cm, deg), for reports."""
        return {
            'hip_distance_cm': float(self.hip_distance * 100),
            'leg_length_cm': float(self.leg_length * 100),
            'touchdown_angles_deg': [float(math.degrees(a)) for a in self.touchdown_angles],
            'liftoff_angles_deg': [float(math.degrees(a)) for a in self.liftoff_angles],
            'stride_frequency_hz': float(self.stride_frequency),
        }


@lru_cache(maxsize=1)
def _load_nominal() -> ModelParameters:
    import yaml

    path = config_path()
    try:
        values = yaml.safe_load(path.read_text())['octoroach_model']
    except (OSError, KeyError, TypeError, yaml.YAMLError) as error:
        raise ParameterError(f'cannot read nominal parameters from {path}: {error}') from None
    return ModelParameters(
        hip_distance=float(values['hip_distance']),
        leg_length=float(values['leg_length']),
        touchdown_angles=tuple(float(a) for a in values['touchdown_angles']),
        liftoff_angles=tuple(float(a) for a in values['liftoff_angles']),
        stride_frequency=float(values['stride_frequency']),
        sample_rate=float(values['sample_rate']),
    )


def nominal_sigmas() -> tuple[float, float]:
    """(sigma1, sigma2) of Table III, radians, from config/table2.yaml."""
    import yaml

    values = yaml.safe_load(config_path().read_text())['octoroach_model']
    return float(values['sigma1']), float(values['sigma2'])
