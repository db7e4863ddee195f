"""
What one call of the validator does, without ROS: its inputs, the runs it reads, its work.

The validator node answers `~/validate` and `~/diagnose` on measured runs that may still be
growing (a recorder writing the bag it names). A `Job` holds one call's inputs, taken from the
node's parameter values when the call starts; a `Workbench` keeps the measured runs between
calls and reads them again when the inputs or the files behind them changed.

What "changed" means is `source_stamps`: the path, modification time and size of every file
under the named sources. A bag directory's own time stamp is not enough: a recorder appends to
the .mcap inside it, which changes the file's size and time but not the directory's (a
directory only changes when an entry is added or removed), so runs recorded after the first
call would go unseen.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from enum import StrEnum
import os
from pathlib import Path
from typing import Any, TYPE_CHECKING

from octoroach_model.errors import ParameterError
from octoroach_model.jsonio import OMIT_NONE
from octoroach_model.limit_setting import LIMITS, read_limits
from octoroach_model.model import DRAWS
from octoroach_model.model.parameters import SIGMA_LIMIT
from octoroach_model.paths import Paths
from octoroach_model.recordings import DEFAULT_GAP_S
from octoroach_model.recordings.options import (
    FORWARD_AXIS, GAP_S, ReadOptions, TOPIC, UP_AXIS)
from octoroach_model.redraw_setting import SIMULATION_DRAWS
from octoroach_model.run_settings import ANGLE_DRAWS
from octoroach_model.settings import check_fields, Progress, setting, settings_of
from octoroach_model.validation import ValidationSettings
from octoroach_model.validation.validate import NOMINAL_MODELS, ValidationResult

if TYPE_CHECKING:
    from octoroach_model.diagnosis import DiagnosisReport
    from octoroach_model.guidance import GuidanceAnswer

__all__ = ['Cancelled', 'Job', 'JobAnswer', 'JobKind', 'Progress', 'Workbench',
           'diagnosis_settings', 'run_diagnosis', 'run_validation', 'source_stamps']

# Files whose change means the measured runs must be read again: bag data and metadata,
# multisample data sets, motion-capture files and trajectory tables.
WATCHED_SUFFIXES = ('.mcap', '.db3', '.yaml', '.npz', '.bag', '.csv', '.c3d', '.tsv', '.txt')
FileStamp = tuple[str, int, int]  # path, modification time [ns], size [bytes]


class Cancelled(Exception):
    """Raised from a progress callback when the job must stop (the node shuts down)."""


class JobKind(StrEnum):
    """What a call runs: the validation (~/validate) or the diagnosis (~/diagnose)."""

    VALIDATION = 'validation'
    DIAGNOSIS = 'diagnosis'


@dataclass(frozen=True)
class JobAnswer:
    """
    What a call answers (JSON through jsonio, where the node answers and publishes).

    The result's own fields; then, each only where set, the files a diagnosis wrote
    (`report_files`, with report_dir), when the call started and how long it took (set by
    the node; `elapsed_s` takes the place of the report's own) and the live guidance
    (~/diagnose, with a question asked).
    """

    result: ValidationResult | DiagnosisReport = field(metadata={'json_inline': True})
    report_files: dict[str, str] | None = field(default=None, metadata=OMIT_NONE)
    started_at: str | None = field(default=None, metadata=OMIT_NONE)
    elapsed_s: float | None = field(default=None, metadata=OMIT_NONE)
    guidance: GuidanceAnswer | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True)
class Job:
    """
    One call's inputs, taken from the parameter values when it starts.

    Each field with a `settings.setting` is one of the validator's parameters (help, unit and
    range come from here); `settings` holds the paper's constants.
    """

    sources: tuple[str, ...]
    topic: str = setting('', TOPIC)
    forward_axis: str = setting('x', FORWARD_AXIS)
    up_axis: str = setting('z', UP_AXIS)
    gap_s: float = setting(DEFAULT_GAP_S, GAP_S)
    min_duration_s: float = setting(0.0, 'runs shorter than this are left out (0: none; all '
                                    'runs are compared on their common duration)', unit='s',
                                    low=0.0, high=3600.0)
    nominal: str = setting('fit', 'nominal model: fitted to the runs (eq. 9) or Table II',
                           choices=NOMINAL_MODELS)
    draws: str = setting(DRAWS[0], ANGLE_DRAWS)
    sigma1: float = setting(-1.0, 'evaluate at this touchdown spread; negative: search',
                            unit='rad', low=-1.0, high=SIGMA_LIMIT, open_high=True)
    sigma2: float = setting(-1.0, 'evaluate at this liftoff spread; negative: search',
                            unit='rad', low=-1.0, high=SIGMA_LIMIT, open_high=True)
    simulation_draws: int = setting(1, SIMULATION_DRAWS)    # ~/diagnose only
    limits: str = setting('all', LIMITS)                    # ~/diagnose only
    report_dir: str = setting('', '~/diagnose also writes each report (report.json, '
                              'summary.md, plots) into a new folder here; empty: no files',
                              read_only=True)
    settings: ValidationSettings = field(default_factory=ValidationSettings)

    def __post_init__(self) -> None:
        check_fields(self)
        read_limits(self.limits)

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> Job:
        """Make a job from parameter values; ParameterError where they do not fit together."""
        names = settings_of(ValidationSettings)
        settings = ValidationSettings(**{name: values[name] for name in names})
        ReadOptions(forward_axis=values['forward_axis'], up_axis=values['up_axis'])  # checked
        return cls(sources=tuple(values.get('bags', ())), topic=str(values['topic']),
                   forward_axis=str(values['forward_axis']), up_axis=str(values['up_axis']),
                   gap_s=float(values['gap_s']),
                   min_duration_s=float(values['min_duration_s']),
                   nominal=values['nominal'], draws=values['draws'],
                   sigma1=float(values['sigma1']), sigma2=float(values['sigma2']),
                   simulation_draws=int(values['simulation_draws']),
                   limits=str(values['limits']), report_dir=values['report_dir'],
                   settings=settings)

    def sigmas(self) -> tuple[float, float] | None:
        """Return the fixed point to evaluate, or None for the search (15)."""
        if self.sigma1 < 0 and self.sigma2 < 0:
            return None
        if self.sigma1 < 0 or self.sigma2 < 0:
            raise ParameterError(
                f'sigma1 = {self.sigma1:g} and sigma2 = {self.sigma2:g} rad: set both >= 0 to '
                'evaluate at a fixed point, or both negative to search')
        return self.sigma1, self.sigma2

    def require_sources(self) -> None:
        """Raise ParameterError when no source is named."""
        if not self.sources:
            raise ParameterError('no measured runs: set the parameter bags (bag directories, '
                                 '.mcap files or .npz data sets)')


def source_stamps(sources: Sequence[str]) -> tuple[FileStamp, ...]:
    """
    Return (path, mtime, size) of every bag or data-set file under `sources`, sorted.

    A file source is stamped itself; a directory (a bag, or a folder of bags) by every file
    ending in WATCHED_SUFFIXES below it. A missing source has no stamp, so its appearance
    counts as a change too.
    """
    stamps: list[FileStamp] = []
    for source in sources:
        path = Path(source)
        if path.is_dir():
            files = [Path(folder) / name for folder, _, names in os.walk(path)
                     for name in names if name.endswith(WATCHED_SUFFIXES)]
        else:
            files = [path]
        for file in files:
            try:
                stat = file.stat()
            except OSError:
                continue  # gone meanwhile, or never there: the reader says what is wrong
            stamps.append((str(file), stat.st_mtime_ns, stat.st_size))
    return tuple(sorted(stamps))


class Workbench:
    """
    The measured runs, kept between calls and read again when inputs or files change.

    Only the running job uses it (one at a time), so it needs no lock.
    """

    def __init__(self) -> None:
        self._key: tuple[Any, ...] | None = None
        self._measured: Paths | None = None

    def measured(self, job: Job, progress: Progress | None = None) -> Paths:
        """
        Return the runs of `job.sources`, read again when a name, setting or file changed.

        They are read as every program reads them (`recordings.load_measured`); `progress`
        hears how far the reading has got.
        """
        from octoroach_model.recordings import load_measured

        job.require_sources()
        key = (job.sources, job.topic, job.forward_axis, job.up_axis, job.gap_s,
               job.min_duration_s, source_stamps(job.sources))
        if key != self._key or self._measured is None:
            options = ReadOptions(topic=job.topic or None, forward_axis=job.forward_axis,
                                  up_axis=job.up_axis)
            self._measured = load_measured(
                list(job.sources), gap_s=job.gap_s, options=options,
                min_duration_s=job.min_duration_s or None,
                progress=(lambda fraction, message: progress(0.0, message))
                if progress is not None else None)
            self._key = key
        return self._measured


def run_validation(job: Job, bench: Workbench, progress: Progress) -> JobAnswer:
    """Run the offline `validate` chain (load, nominal model, validate)."""
    from octoroach_model.validation import validate_measured

    progress(0.0, 'loading the measured runs')
    measured = bench.measured(job, progress)
    progress(0.0, f'{measured.n_paths} runs loaded; nominal model: {job.nominal}')
    result = validate_measured(measured, job.settings, nominal=job.nominal, draws=job.draws,
                               sigmas=job.sigmas(), sources=list(job.sources),
                               progress=progress)
    return JobAnswer(result)


def run_diagnosis(job: Job, bench: Workbench, progress: Progress) -> JobAnswer:
    """Run `diagnose` on the measured runs; and write its files with report_dir."""
    from dataclasses import replace

    from octoroach_model.diagnosis import diagnose

    progress(0.0, 'loading the measured runs')
    measured = bench.measured(job, progress)
    report = diagnose(measured, diagnosis_settings(job), progress=progress)
    report = replace(report, sources=tuple(job.sources))
    files: dict[str, str] = {}
    if job.report_dir:
        from octoroach_model.diagnosis import write_report

        try:
            written = write_report(report, new_report_folder(job.report_dir), measured=measured,
                                   plots=True)
            files = {str(k): str(v) for k, v in dict(written or {}).items()}
        except Cancelled:
            raise
        except Exception as error:  # noqa: BLE001 - the report is still worth returning
            files = {'error': ' '.join(f'{type(error).__name__}: {error}'.split())}
    return JobAnswer(report, files if job.report_dir else None)


def diagnosis_settings(job: Job) -> Any:
    """
    Return the diagnosis settings of a call: the library's, with the node's own settings.

    The seed, the validation settings (rho, epsilon, delta, k, gamma, the search grid) the
    diagnosis's validations of the baseline and the extended model use, the draws of the
    simulations the decision is made on (redraws.py) and the detection limits computed.
    """
    from octoroach_model.diagnosis import DiagnosisSettings

    detection_limits, limit_terms = read_limits(job.limits)
    return DiagnosisSettings(seed=job.settings.seed, validation=job.settings,
                             simulation_draws=job.simulation_draws,
                             detection_limits=detection_limits, limit_terms=limit_terms)


def new_report_folder(report_dir: str) -> Path:
    """
    Return a new folder in `report_dir` for one call's report: diagnosis_YYYYmmdd_HHMMSS[_N].

    Each call writes a folder of its own (atomically, `write_report`), so no file of an
    earlier report, nor anything else in report_dir, is ever replaced.
    """
    base = Path(report_dir) / datetime.now().strftime('diagnosis_%Y%m%d_%H%M%S')
    folder, number = base, 1
    while os.path.lexists(folder):
        folder, number = base.with_name(f'{base.name}_{number}'), number + 1
    return folder
