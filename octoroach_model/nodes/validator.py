"""validator: the paper's probabilistic validation (and the diagnosis) as ROS services.

A thin adapter. `~/validate` and `~/diagnose` (std_srvs/srv/Trigger) take the parameters in
force at the call, hand the work to a worker thread and answer with the JSON result; the
statistics of the last validation are latched on `~/violation`. The measured runs are loaded
from the `bags` parameter at the first call and again whenever `bags`, `topic`, `gap_s` or
the files themselves change; the nominal fit (eq. 9) is cached with them.

Why a worker thread: a validation takes seconds to minutes, and the node must keep answering
parameter requests meanwhile. The node spins a MultiThreadedExecutor; both services sit in a
ReentrantCallbackGroup, so the first call's callback waits on its own executor thread while
the other threads answer parameter requests and tell a second caller that the node is busy.
One job (validation or diagnosis) runs at a time: both are CPU-bound.
"""
from __future__ import annotations

import json
import math
import os
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from octoroach_model.errors import OctoroachError, ParameterError
from octoroach_model.nodes.common import (
    ParamSpec, ParamValue, UsageError, current_values, declare_parameters, fail, node_parser,
    run_node, set_parameters_callback, split_ros_args)

if TYPE_CHECKING:
    from octoroach_model.paths import Paths

SUMMARY = ("ROS node: the paper's probabilistic validation of the OctoRoACH model on measured "
           'runs, as a service. ~/validate fits the nominal model (eq. 9) to the runs named in '
           '`bags` and finds the widest (sigma1, sigma2) whose estimated probability of '
           'violation stays below rho (eq. 15), or with sigma1, sigma2 >= 0 only estimates it '
           'there; ~/diagnose runs the diagnosis (cause of the discrepancies). Answers are '
           'JSON; the statistics of the last validation are latched on ~/violation.')
NOTES = """
Each call uses the parameters in force when it starts; changes apply to the next call.
Runs are (re)loaded at a call when `bags`, `topic`, `gap_s` or the files changed, so `bags`
may name the data set (.npz) a recorder exports. A call answers success=true with the JSON
result (its field `accepted` is the verdict) or success=false with {"error": "..."}; while a
job runs, another call answers at once with {"error": "busy: ..."}. ~/violation is reliable,
transient_local (latched), depth 1. `bags` is a string array (to clear it from rclpy, give
the type: Parameter('bags', Parameter.Type.STRING_ARRAY, [])).
Example: python -m octoroach_model validator --ros-args -p bags:=[bags/] -p k:=11
"""
TOPICS = (
    ('service', '~/validate', 'std_srvs/srv/Trigger: run the validation, JSON result'),
    ('service', '~/diagnose', 'std_srvs/srv/Trigger: run the diagnosis, JSON report'),
    ('publishes', '~/violation', 'diagnostic_msgs/msg/DiagnosticArray, latched, last result'),
)
STATUS_NAME = 'octoroach_model/validation'
HARDWARE_ID = 'octoroach'
EXECUTOR_THREADS = 4        # a waiting job callback, parameter services, busy answers
PROGRESS_PERIOD_S = 2.0     # progress is logged at most this often
POLL_S = 0.05               # how often a waiting callback looks for shutdown

BAGS = ParamSpec('bags', [], 'bag directories, .mcap files or .npz data sets to validate on')


def validator_specs() -> list[ParamSpec]:
    """Every parameter but `bags` (declared apart: rclpy cannot type an empty list)."""
    from octoroach_model.model import DRAWS
    from octoroach_model.recordings import DEFAULT_GAP_S
    from octoroach_model.validation import ValidationSettings

    d = ValidationSettings()
    return [
        ParamSpec('topic', '', 'pose topic in the bags; empty: the VICON one found there'),
        ParamSpec('gap_s', float(DEFAULT_GAP_S), 'a pause in the poses longer than this '
                  'splits runs (bags without run markers)', 's', 0.05, 60.0),
        ParamSpec('nominal', 'fit', 'nominal model: fitted to the runs (eq. 9) or Table II',
                  choices=('fit', 'table2')),
        ParamSpec('draws', DRAWS[0], 'model angles drawn at every stance or once per run',
                  choices=tuple(DRAWS)),
        ParamSpec('rho', d.rho, 'acceptance level: largest admissible violation probability',
                  '', 0.01, 0.99),
        ParamSpec('epsilon', d.epsilon, 'accuracy of the estimate (eq. 16)', '', 0.01, 0.99),
        ParamSpec('delta', d.delta, 'confidence 1 - delta of the estimate (eq. 16)', '',
                  0.01, 0.99),
        ParamSpec('k', d.k, 'runs per multisample', '', 2, 1000),
        ParamSpec('gamma', d.gamma, 'confidence level of the prediction region', '',
                  0.5, 0.999),
        ParamSpec('seed', d.seed, 'seed of the multisamples, model runs and diagnosis', '',
                  0, 2**31 - 1),
        ParamSpec('sigma1_max', d.sigma1_max, 'largest touchdown spread searched', 'rad',
                  0.01, 1.5),
        ParamSpec('sigma2_max', d.sigma2_max, 'largest liftoff spread searched', 'rad',
                  0.01, 1.5),
        ParamSpec('grid_points', d.grid_points, 'grid points per spread in the search', '',
                  2, 101),
        ParamSpec('resolution_m', d.resolution_m, 'narrowest half-width of a region '
                  '(motion-capture resolution)', 'm', 0.0, 0.01),
        ParamSpec('sigma1', -1.0, 'evaluate at this touchdown spread; negative: search',
                  'rad', -1.0, 1.5),
        ParamSpec('sigma2', -1.0, 'evaluate at this liftoff spread; negative: search', 'rad',
                  -1.0, 1.5),
        ParamSpec('report_dir', '', '~/diagnose also writes report.json and plots here; '
                  'empty: no files'),
    ]


# -- what a call needs, from the parameter values -------------------------------------------

@dataclass(frozen=True)
class Job:
    """One call's inputs, taken from the parameters when it starts."""

    sources: tuple[str, ...]
    topic: str | None
    gap_s: float
    nominal: str
    draws: str
    sigma1: float
    sigma2: float
    report_dir: str
    settings: Any  # ValidationSettings

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> Job:
        """A job from parameter values; ParameterError where they do not fit together."""
        from octoroach_model.validation import ValidationSettings

        settings = ValidationSettings(
            rho=values['rho'], epsilon=values['epsilon'], delta=values['delta'],
            k=values['k'], gamma=values['gamma'], seed=values['seed'],
            sigma1_max=values['sigma1_max'], sigma2_max=values['sigma2_max'],
            grid_points=values['grid_points'], resolution_m=values['resolution_m'])
        return cls(sources=tuple(values.get('bags', ())), topic=values['topic'] or None,
                   gap_s=float(values['gap_s']), nominal=values['nominal'],
                   draws=values['draws'], sigma1=float(values['sigma1']),
                   sigma2=float(values['sigma2']), report_dir=values['report_dir'],
                   settings=settings)

    def sigmas(self) -> tuple[float, float] | None:
        """The fixed point to evaluate, or None for the search (15)."""
        if self.sigma1 < 0 and self.sigma2 < 0:
            return None
        if self.sigma1 < 0 or self.sigma2 < 0:
            raise ParameterError(
                f'sigma1 = {self.sigma1:g} and sigma2 = {self.sigma2:g} rad: set both >= 0 to '
                'evaluate at a fixed point, or both negative to search')
        return self.sigma1, self.sigma2

    def require_sources(self) -> None:
        if not self.sources:
            raise ParameterError('no measured runs: set the parameter bags (bag directories, '
                                 '.mcap files or .npz data sets)')


def _reject_reason(values: dict[str, ParamValue]) -> str | None:
    try:
        Job.from_values(values)
    except OctoroachError as error:
        return str(error)
    return None


def _bags_reason(value: Any) -> str | None:
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
        return f'bags must be a string array, e.g. [bags/run1, data.npz], got {value!r}'
    if any(not v.strip() for v in value):
        return 'bags must not contain empty names'
    return None


# -- the work: plain Python, no rclpy -------------------------------------------------------

class Cancelled(Exception):
    """Raised from the progress callback when the node shuts down during a job."""


class Workbench:
    """Measured runs, kept between calls and rebuilt when inputs change.

    Only the running job uses it (one at a time), so it needs no lock.
    """

    def __init__(self) -> None:
        self._measured_key: tuple | None = None
        self._measured: Paths | None = None

    def measured(self, job: Job) -> Paths:
        """The runs of `job.sources`, from the cache when neither names nor files changed."""
        from octoroach_model.recordings import load_measured

        job.require_sources()
        key = (job.sources, job.topic, job.gap_s, _file_stamps(job.sources))
        if key != self._measured_key or self._measured is None:
            self._measured = load_measured(list(job.sources), gap_s=job.gap_s, topic=job.topic)
            self._measured_key = key
        return self._measured


def _file_stamps(sources: Sequence[str]) -> tuple:
    """(path, mtime, size) of every input file, so rewritten or grown files are reloaded."""
    from octoroach_model.recordings import expand_sources

    try:
        files = expand_sources(list(sources), suffixes=('.mcap', '.npz'))
    except (OctoroachError, OSError):
        return ()  # load_measured will say what is wrong
    stamps = []
    for path in files:
        try:
            stat = os.stat(path)
        except OSError:
            continue
        stamps.append((str(path), stat.st_mtime_ns, stat.st_size))
    return tuple(stamps)


Progress = Callable[[float, str], None]


def run_validation(job: Job, bench: Workbench, progress: Progress) -> dict:
    """The offline `validate` command's chain (load, nominal, validate) as a JSON-ready dict."""
    from octoroach_model.validation import validate_measured

    progress(0.0, 'loading the measured runs')
    measured = bench.measured(job)
    progress(0.0, f'{measured.n_paths} runs loaded; nominal model: {job.nominal}')
    result = validate_measured(measured, job.settings, nominal=job.nominal, draws=job.draws,
                               sigmas=job.sigmas(), sources=list(job.sources),
                               progress=progress)
    return result.to_json()


def run_diagnosis(job: Job, bench: Workbench, progress: Progress) -> dict:
    """`diagnose` on the measured runs; report files too when `report_dir` is set."""
    from dataclasses import replace

    from octoroach_model.diagnosis import diagnose

    progress(0.0, 'loading the measured runs')
    measured = bench.measured(job)
    report = diagnose(measured, diagnosis_settings(job), progress=progress)
    report = replace(report, sources=tuple(job.sources))
    result = report.to_json()
    if job.report_dir:
        try:
            from octoroach_model.diagnosis import write_report

            written = write_report(report, Path(job.report_dir), measured=measured,
                                   plots=True)
            result['report_files'] = {str(k): str(v) for k, v in dict(written or {}).items()}
        except Cancelled:
            raise
        except Exception as error:  # noqa: BLE001 - the report is still worth returning
            result['report_files'] = {'error': _one_line(error)}
    return result


def diagnosis_settings(job: Job) -> Any:
    """DiagnosisSettings of a call: the library defaults with the node's seed."""
    from octoroach_model.diagnosis import DiagnosisSettings

    return DiagnosisSettings(seed=job.settings.seed)


def status_fields(result: Mapping[str, Any]) -> tuple[bool, str, list[tuple[str, str]]]:
    """(accepted, message in words, key/value pairs) of a validation result."""
    accepted = bool(result['accepted'])
    where = (f"sigma1 = {result['sigma1']:.3f} rad, sigma2 = {result['sigma2']:.3f} rad "
             f"(n = {result['n']}, k = {result['k']})")
    if accepted:
        message = (f"accepted: estimated violation {result['violation']:.3f} <= rho = "
                   f"{result['rho']} at {where}")
    elif result.get('mode') == 'search':
        message = (f"rejected: no spread on the grid keeps the violation below rho = "
                   f"{result['rho']}; at {where} it is {result['violation']:.3f}")
    else:
        message = (f"rejected: estimated violation {result['violation']:.3f} > rho = "
                   f"{result['rho']} at {where}")
    keys = ('n', 'k', 'sigma1', 'sigma2', 'violation', 'rho', 'epsilon', 'delta', 'gamma',
            'seed', 'paths_used', 'paths_available', 'accepted', 'mode', 'duration_s',
            'elapsed_s', 'started_at')
    values = [(key, _text(result[key])) for key in keys if key in result]
    return accepted, message, values


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return repr(value)
    return str(value)


def to_json(value: Any) -> str:
    """Strict JSON (NaN and infinities become null; numpy values become numbers)."""
    return json.dumps(_jsonable(value), allow_nan=False)


def _jsonable(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, bool) or value is None or isinstance(value, (int, str)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if hasattr(value, 'tolist'):          # numpy scalars and arrays
        return _jsonable(value.tolist())
    if isinstance(value, Path):
        return str(value)
    return str(value)


def _one_line(error: BaseException) -> str:
    text = ' '.join(str(error).split())
    if isinstance(error, OctoroachError):
        return text or type(error).__name__
    return f'{type(error).__name__}: {text}' if text else type(error).__name__


def error_json(reason: str) -> str:
    return json.dumps({'error': reason})


# -- the node -------------------------------------------------------------------------------

try:  # the node class needs rclpy; --help and the functions above do not
    from rclpy.callback_groups import ReentrantCallbackGroup
    from rclpy.node import Node
except ImportError:  # pragma: no cover - rclpy missing: main() reports it
    Node = object  # type: ignore[assignment,misc]


@dataclass
class _Running:
    """The job in progress: what it is, since when, and its outcome once done."""

    kind: str                      # 'validation' or 'diagnosis'
    started: float                 # time.monotonic()
    started_at: str                # wall clock, ISO 8601
    done: threading.Event
    success: bool = False
    message: str = ''


class Validator(Node):  # type: ignore[misc,valid-type]
    """Validation and diagnosis services; see the module docstring."""

    def __init__(self, **node_options: Any) -> None:
        super().__init__('validator', **node_options)
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
        from std_srvs.srv import Trigger

        self._specs = validator_specs()
        self._declare_bags()
        values = declare_parameters(self, self._specs)
        job = Job.from_values({**values, 'bags': self.bags()})
        job.sigmas()  # at start-up both spreads come together: a half-set pair is a mistake
        check = set_parameters_callback(self, self._specs, _reject_reason)
        self.add_on_set_parameters_callback(lambda params: self._check_parameters(params, check))
        latched = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._violation = self.create_publisher(DiagnosticArray, '~/violation', latched)
        self._bench = Workbench()
        self._lock = threading.Lock()
        self._running: _Running | None = None
        self._stop = threading.Event()
        group = ReentrantCallbackGroup()
        self.create_service(Trigger, '~/validate', self._on_validate, callback_group=group)
        self.create_service(Trigger, '~/diagnose', self._on_diagnose, callback_group=group)
        self.get_logger().info(
            f'ready: {len(job.sources)} source(s) in bags; services ~/validate, ~/diagnose; '
            f'statistics on ~/violation')

    # parameters

    def _declare_bags(self) -> None:
        from rclpy.exceptions import ParameterException
        from rclpy.parameter import Parameter

        try:
            self.declare_parameter('bags', Parameter.Type.STRING_ARRAY, BAGS.descriptor())
        except ParameterException:
            override = getattr(self, '_parameter_overrides', {}).get('bags')
            shown = override.value if override is not None else '?'
            raise ParameterError(f'bags must be a string array, e.g. -p "bags:=[a.npz, bags/]"'
                                 f', got {shown!r}') from None
        reason = _bags_reason(self.bags())
        if reason:
            raise ParameterError(reason)

    def bags(self) -> list[str]:
        """The `bags` parameter; [] while unset (rclpy's typed parameter without a value)."""
        from rclpy.exceptions import ParameterUninitializedException

        try:
            value = self.get_parameter('bags').value
        except ParameterUninitializedException:
            return []
        return [str(v) for v in value] if value is not None else []

    def _check_parameters(self, parameters: list[Any], check: Callable[[list[Any]], Any]) -> Any:
        from rcl_interfaces.msg import SetParametersResult

        for parameter in parameters:
            if parameter.name == 'bags':
                reason = _bags_reason(parameter.value)
                if reason:
                    return SetParametersResult(successful=False, reason=reason)
        return check(parameters)

    def _job(self) -> Job:
        return Job.from_values({**current_values(self, self._specs), 'bags': self.bags()})

    # services

    def _on_validate(self, request: Any, response: Any) -> Any:
        return self._serve('validation', run_validation, response)

    def _on_diagnose(self, request: Any, response: Any) -> Any:
        return self._serve('diagnosis', run_diagnosis, response)

    @property
    def running(self) -> str | None:
        """What the node is busy with ('validation', 'diagnosis'), or None."""
        running = self._running
        return running.kind if running is not None else None

    def _serve(self, kind: str, work: Callable[[Job, Workbench, Progress], dict],
               response: Any) -> Any:
        """Start `work` on a worker thread and wait for it on this (reentrant) thread."""
        with self._lock:
            running = self._running
            if running is not None:
                ago = time.monotonic() - running.started
                response.success = False
                response.message = error_json(
                    f'busy: a {running.kind} started at {running.started_at} ({ago:.1f} s ago)'
                    ' is running; call again when it is done')
                return response
            try:
                job = self._job()
            except OctoroachError as error:
                response.success, response.message = False, error_json(_one_line(error))
                return response
            running = self._running = _Running(
                kind, time.monotonic(), datetime.now().astimezone().isoformat(timespec='seconds'),
                threading.Event())
        self.get_logger().info(f'{kind} started ({len(job.sources)} source(s))')
        worker = threading.Thread(target=self._work, args=(running, work, job),
                                  name=f'validator-{kind}', daemon=True)
        worker.start()
        while not running.done.wait(POLL_S):
            if self._stop.is_set() or not self.context.ok():
                response.success = False
                response.message = error_json(f'{kind} cancelled: the node is shutting down')
                return response
        response.success, response.message = running.success, running.message
        return response

    def _work(self, running: _Running, work: Callable[[Job, Workbench, Progress], dict],
              job: Job) -> None:
        """Worker thread: run the job, publish the statistics, hand back the answer."""
        logger = self.get_logger()
        try:
            result = work(job, self._bench, self._progress(running.kind))
            elapsed = round(time.monotonic() - running.started, 3)
            result = {**result, 'started_at': running.started_at, 'elapsed_s': elapsed}
            if running.kind == 'validation':
                self._publish(result)
            running.success, running.message = True, to_json(result)
            logger.info(f'{running.kind} done in {elapsed:.1f} s'
                        + (f": {status_fields(result)[1]}" if running.kind == 'validation'
                           else f": cause {result.get('cause')}"))
        except Cancelled:
            running.message = error_json(f'{running.kind} cancelled: the node is shutting down')
        except OctoroachError as error:
            running.message = error_json(_one_line(error))
            logger.error(f'{running.kind} failed: {_one_line(error)}')
        except Exception as error:  # noqa: BLE001 - a bug must not take the node down
            running.message = error_json(_one_line(error))
            logger.error(f'{running.kind} failed: {_one_line(error)}')
            import traceback
            logger.debug(traceback.format_exc())
        finally:
            with self._lock:
                self._running = None
            running.done.set()

    def _progress(self, kind: str) -> Progress:
        """Progress callback: throttled log lines, and the way a job learns it must stop."""
        logger = self.get_logger()
        last = [-math.inf]

        def report(fraction: float, message: str) -> None:
            if self._stop.is_set():
                raise Cancelled()
            now = time.monotonic()
            if now - last[0] >= PROGRESS_PERIOD_S or fraction >= 1.0:
                last[0] = now
                logger.info(f'{kind} {100 * fraction:5.1f}%: {message}')

        return report

    def _publish(self, result: Mapping[str, Any]) -> None:
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

        accepted, message, values = status_fields(result)
        status = DiagnosticStatus(
            level=DiagnosticStatus.OK if accepted else DiagnosticStatus.WARN,
            name=STATUS_NAME, message=message, hardware_id=HARDWARE_ID,
            values=[KeyValue(key=key, value=value) for key, value in values])
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self._violation.publish(array)

    def stop_jobs(self) -> None:
        """Ask a running job to stop at its next progress report; waiting callbacks return."""
        self._stop.set()

    def destroy_node(self) -> None:
        self.stop_jobs()
        super().destroy_node()


# -- command line ---------------------------------------------------------------------------

def main(argv: Sequence[str] | None = None) -> int:
    """`validator [--help] [--ros-args ...]`; returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        own, ros = split_ros_args(argv)
        node_parser('validator', SUMMARY, [BAGS, *validator_specs()], TOPICS,
                    NOTES).parse_args(own)
    except SystemExit as stop:  # --help
        return int(stop.code or 0)
    except (UsageError, OctoroachError) as error:
        return fail(str(error))
    return run_node(Validator, ros, prog='validator', executor_threads=EXECUTOR_THREADS)


if __name__ == '__main__':
    sys.exit(main())
