"""
validator: the paper's probabilistic validation (and the diagnosis) as ROS services.

A thin adapter. `~/validate` and `~/diagnose` (std_srvs/srv/Trigger) take the parameters in
force at the call, hand the work to a worker thread and answer with the JSON result; the
statistics of the last validation are latched on `~/violation`. What a call does, without ROS,
is `octoroach_model.validation_jobs`: the measured runs are read at the first call and again
whenever `bags`, `topic`, the axes, `gap_s`, `min_duration_s` or the files behind them change,
so a bag that a recorder is still writing is validated as it is at each call.

Why a worker thread: a validation takes seconds to minutes, and the node must keep answering
parameter requests meanwhile. The node spins a MultiThreadedExecutor; both services sit in a
ReentrantCallbackGroup, so the first call's callback waits on its own executor thread while
the other threads answer parameter requests and tell a second caller that the node is busy.
One job (validation or diagnosis) runs at a time: both are CPU-bound.

`validator --call validate` (or `diagnose`) is the client side: it calls the service of a
running validator and prints the JSON answer, for machines without the `ros2` command.

Live guidance: with `question` set (a cause or extension term and `question_size`, or
`validation`), a thread of its own watches the files behind `bags` every `guidance_period_s`
and, when they change, reads the runs and asks `octoroach_model.guidance.Guide` what is known
so far and how many runs the question still needs; the answer is latched on `~/guidance` and
joins `~/diagnose`'s answer. The guide fits its baselines in a worker process (forkserver,
like the diagnosis's pool inside a node), so a look never waits for one.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from datetime import datetime
import json
import math
from pathlib import Path
import sys
import threading
import time
from typing import Any

from octoroach_model.errors import OctoroachError, OutputError, ParameterError
from octoroach_model.fileio import check_writable
from octoroach_model.guidance import (
    check_question, guidance_fields, GuidanceQuestion, GuidanceSettings, Guide, QuestionKind)
from octoroach_model.jsonio import dumps, jsonable
from octoroach_model.nodes.common import (
    current_values, declare_parameters, fail, field_specs, node_parser, ParamSpec, ParamValue,
    rejected_override, run_node, set_parameters_callback, split_ros_args, start_exit_code,
    UsageError)
from octoroach_model.nodes.messages import (
    diagnosis_fields, diagnosis_status, guidance_array, status_fields, validation_status,
    violation_array)
from octoroach_model.settings import settings_of, shown
from octoroach_model.validation_jobs import (
    Cancelled, Job, JobAnswer, JobKind, Progress, run_diagnosis, run_validation, Workbench)

SUMMARY = ("ROS node: the paper's probabilistic validation of the OctoRoACH model on measured "
           'runs, as a service. ~/validate fits the nominal model (eq. 9) to the runs named in '
           '`bags` and finds the widest (sigma1, sigma2) whose estimated probability of '
           'violation stays below rho (eq. 15), or with sigma1, sigma2 >= 0 only estimates it '
           'there; ~/diagnose runs the diagnosis (cause of the discrepancies). Answers are '
           'JSON; the statistics of the last validation are latched on ~/violation. With '
           '--call, calls the service of a running validator instead and prints its answer.')
NOTES = """
Each call uses the parameters in force when it starts; changes apply to the next call.
Runs are (re)read at a call when `bags`, `topic`, `gap_s`, `min_duration_s` or the files
changed, so `bags` may name a bag a recorder is still writing (each call validates what is
on disk then; set min_duration_s just under the run length to leave out the run in progress)
or the data set (.npz) it exports. A call answers success=true with the JSON result (its
field `accepted` is the verdict) or success=false with {"error": "..."}; while a job runs,
another call answers at once with {"error": "busy: ..."}. ~/violation is reliable,
transient_local (latched), depth 1. `bags` is a string array (to clear it from rclpy, give
the type: Parameter('bags', Parameter.Type.STRING_ARRAY, [])). Params file:
config/validator.yaml (share/octoroach_model/config when installed).
Live guidance: set question (a cause or extension term, with question_size in its unit;
or validation) and ~/guidance (DiagnosticArray, latched) says after every new run what is
named so far and how many more runs the question needs (runs_needed, 95 % interval);
~/diagnose's answer carries it too. Changing a question parameter starts the question anew.
Example: python -m octoroach_model validator --ros-args -p bags:=[bags/] -p k:=11
         ... -p question:=persistent_turning -p question_size:=3.0
"""
TOPICS = (
    ('service', '~/validate', 'std_srvs/srv/Trigger: run the validation, JSON result'),
    ('service', '~/diagnose', 'std_srvs/srv/Trigger: run the diagnosis, JSON report'),
    ('publishes', '~/violation', 'diagnostic_msgs/msg/DiagnosticArray, latched, last result'),
    ('publishes', '~/guidance', 'diagnostic_msgs/msg/DiagnosticArray, latched: the live '
     'answer to `question` after each new run'),
)
GUIDANCE_STATUS_NAME = 'octoroach_model/guidance'
GUIDANCE_PARAMETERS = tuple(settings_of(GuidanceSettings))
STATUS_NAME = 'octoroach_model/validation'
DIAGNOSIS_STATUS_NAME = 'octoroach_model/diagnosis'
HARDWARE_ID = 'octoroach'
EXECUTOR_THREADS = 4        # a waiting job callback, parameter services, busy answers
PROGRESS_PERIOD_S = 2.0     # progress is logged at most this often
POLL_S = 0.05               # how often a waiting callback looks for shutdown
SERVICES = {'validate': JobKind.VALIDATION, 'diagnose': JobKind.DIAGNOSIS}  # service -> kind
DISCOVERY_TIMEOUT_S = 30.0  # --call: longest wait for the service to appear
BUSY_RETRY_S = 10.0         # "call again in" before the first job of a kind has finished

BAGS = ParamSpec('bags', [], 'bag directories, .mcap files or .npz data sets to validate on; '
                 'at run time only inside data_dirs')
DATA_DIRS = ParamSpec('data_dirs', [], 'folders `bags` may name when set at run time; empty: '
                      'the folders of the bags given at start', read_only=True)
ARRAYS = (BAGS, DATA_DIRS)      # string arrays, declared apart (an empty list has no type)
SERVICE_QUEUE_DEPTH = 1000  # requests kept while the threads are busy: every caller is answered


def validator_specs() -> list[ParamSpec]:
    """
    List every parameter but the string arrays (declared apart: an empty list has no type).

    Those of a call are the fields of `validation_jobs.Job` and of `ValidationSettings`, the
    live guidance's those of `guidance.GuidanceSettings` (their help, unit, range and default).
    """
    from octoroach_model.validation import ValidationSettings

    return [
        *field_specs(Job, ('topic', 'forward_axis', 'up_axis', 'gap_s', 'min_duration_s',
                           'nominal', 'draws')),
        *field_specs(ValidationSettings, tuple(settings_of(ValidationSettings))),
        *field_specs(Job, ('sigma1', 'sigma2', 'simulation_draws', 'limits', 'report_dir')),
        *field_specs(GuidanceSettings, GUIDANCE_PARAMETERS),
    ]


def _reject_reason(values: dict[str, ParamValue]) -> str | None:
    try:
        Job.from_values(values)
    except OctoroachError as error:
        return str(error)
    return check_question(values)


def _bags_reason(value: Any) -> str | None:
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
        return f'bags must be a string array, e.g. [bags/run1, data.npz], got {shown(value)}'
    if any(not v.strip() for v in value):
        return 'bags must not contain empty names'
    return None


def allowed_roots(data_dirs: Sequence[str], bags: Sequence[str]) -> tuple[Path, ...]:
    """
    Folders `bags` may name at run time: `data_dirs`, else those of the bags given at start.

    Resolved once at start (links followed then), so a later link cannot widen them.
    """
    if data_dirs:
        return tuple(Path(folder).resolve() for folder in data_dirs)
    return tuple(dict.fromkeys(
        (Path(bag).resolve() if Path(bag).is_dir() else Path(bag).resolve().parent)
        for bag in bags))


def outside_roots(bags: Sequence[str], roots: Sequence[Path]) -> str | None:
    """Why `bags` cannot be set at run time (a path outside every root), or None."""
    for bag in bags:
        resolved = Path(bag).resolve()
        if not any(resolved.is_relative_to(root) for root in roots):
            allowed = ', '.join(map(str, roots)) or 'none (set data_dirs at start)'
            return (f'bags: {bag} is outside the folders allowed at run time ({allowed}); '
                    'the operator sets data_dirs when the node starts')
    return None


def make_report_dir(folder: str) -> None:
    """Create `report_dir` at start and check that reports can be written there."""
    try:
        Path(folder).mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise OutputError(f'report_dir {folder}: cannot create it '
                          f'({error.strerror or error})') from None
    check_writable(Path(folder) / 'report', 'report_dir')


def _one_line(error: BaseException) -> str:
    text = ' '.join(str(error).split())
    if isinstance(error, OctoroachError):
        return text or type(error).__name__
    return f'{type(error).__name__}: {text}' if text else type(error).__name__


def error_json(reason: str) -> str:
    """Make the answer of a call that failed: {"error": reason}."""
    return dumps({'error': reason})


# -- the node -------------------------------------------------------------------------------

try:  # the node class needs rclpy; --help and the functions above do not
    from rclpy.callback_groups import ReentrantCallbackGroup
    from rclpy.node import Node
except ImportError:  # pragma: no cover - rclpy missing: main() reports it
    Node = object  # type: ignore[assignment,misc]


@dataclass
class _Running:
    """The job in progress: what it is, since when, and its outcome once done."""

    kind: JobKind
    started: float                 # time.monotonic()
    started_at: str                # wall clock, ISO 8601
    done: threading.Event
    success: bool = False
    message: str = ''


class Validator(Node):
    """Validation and diagnosis services; see the module docstring."""

    def __init__(self, **node_options: Any) -> None:
        super().__init__('validator', **node_options)
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
        from std_srvs.srv import Trigger

        self._specs = validator_specs()
        self._declare_arrays()
        self._roots = allowed_roots(self._array('data_dirs'), self.bags())
        values = declare_parameters(self, self._specs)
        if values['report_dir']:
            make_report_dir(values['report_dir'])
        job = Job.from_values({**values, 'bags': self.bags()})
        job.sigmas()  # at start-up both spreads come together: a half-set pair is a mistake
        reason = _reject_reason(values)
        if reason:
            raise ParameterError(reason)
        check = set_parameters_callback(self, self._specs, _reject_reason)
        self.add_on_set_parameters_callback(lambda params: self._check_parameters(params, check))
        latched = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._violation = self.create_publisher(DiagnosticArray, '~/violation', latched)
        self._guidance = self.create_publisher(DiagnosticArray, '~/guidance', latched)
        self._guide_lock = threading.Lock()
        self._guide: Any = None
        self._refits: Any = None
        self._guidance_thread: threading.Thread | None = None
        self._bench = Workbench()
        self._statuses: dict[JobKind, Any] = {}
        self._lock = threading.Lock()
        self._running: _Running | None = None
        self._stop = threading.Event()
        self._durations: dict[JobKind, float] = {}   # seconds the last job of a kind took
        group = ReentrantCallbackGroup()
        queue = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=SERVICE_QUEUE_DEPTH,
                           reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.VOLATILE)
        self.create_service(Trigger, '~/validate', self._on_validate, callback_group=group,
                            qos_profile=queue)
        self.create_service(Trigger, '~/diagnose', self._on_diagnose, callback_group=group,
                            qos_profile=queue)
        self._guidance_thread = threading.Thread(target=self._watch, name='validator-guidance',
                                                 daemon=True)
        self._guidance_thread.start()
        self.get_logger().info(
            f'ready: {len(job.sources)} source(s) in bags; services ~/validate, ~/diagnose; '
            f'statistics on ~/violation'
            + (f'; live guidance for {values["question"]} on ~/guidance'
               if values['question'] else ''))

    # parameters

    def _declare_arrays(self) -> None:
        """Declare `bags` and `data_dirs` typed as string arrays (an empty default has none)."""
        from rclpy.exceptions import ParameterException
        from rclpy.parameter import Parameter

        for spec in ARRAYS:
            try:
                self.declare_parameter(spec.name, Parameter.Type.STRING_ARRAY,
                                       spec.descriptor())
            except ParameterException:
                raise ParameterError(rejected_override(self, spec.name, _bags_reason)
                                     or f'{spec.name} must be a string array, e.g. -p '
                                     f'"{spec.name}:=[a.npz, bags/]"') from None
            reason = _bags_reason(self._array(spec.name))
            if reason:
                raise ParameterError(reason.replace('bags', spec.name, 1))

    def _array(self, name: str) -> list[str]:
        """Return a string-array parameter; [] while unset (typed, without a value)."""
        from rclpy.exceptions import ParameterUninitializedException

        try:
            value = self.get_parameter(name).value
        except ParameterUninitializedException:
            return []
        return [str(v) for v in value] if value is not None else []

    def bags(self) -> list[str]:
        """Return the `bags` parameter; [] while unset (a typed parameter without a value)."""
        return self._array('bags')

    def _check_parameters(self, parameters: list[Any], check: Callable[[list[Any]], Any]) -> Any:
        from rcl_interfaces.msg import SetParametersResult

        for parameter in parameters:
            if parameter.name == 'data_dirs':
                return SetParametersResult(successful=False, reason='data_dirs is read-only')
            if parameter.name == 'bags':
                reason = _bags_reason(parameter.value) or outside_roots(
                    [str(v) for v in parameter.value], self._roots)
                if reason:
                    return SetParametersResult(successful=False, reason=reason)
        return check(parameters)

    def _job(self) -> Job:
        return Job.from_values({**current_values(self, self._specs), 'bags': self.bags()})

    # services

    def _on_validate(self, request: Any, response: Any) -> Any:
        return self._serve(SERVICES['validate'], run_validation, response)

    def _on_diagnose(self, request: Any, response: Any) -> Any:
        return self._serve(SERVICES['diagnose'], run_diagnosis, response)

    @property
    def running(self) -> JobKind | None:
        """Return what the node is busy with, or None."""
        running = self._running
        return running.kind if running is not None else None

    def _serve(self, kind: JobKind, work: Callable[[Job, Workbench, Progress], JobAnswer],
               response: Any) -> Any:
        """Start `work` on a worker thread and wait for it on this (reentrant) thread."""
        with self._lock:
            running = self._running
            if running is not None:
                ago = time.monotonic() - running.started
                wait = max(1.0, self._durations.get(running.kind, BUSY_RETRY_S) - ago)
                response.success = False
                response.message = dumps({
                    'error': f'busy: a {running.kind} started at {running.started_at} '
                             f'({ago:.1f} s ago) is running; call again in about '
                             f'{wait:.0f} s', 'busy': True, 'retry_after_s': round(wait, 1)})
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

    def _work(self, running: _Running, work: Callable[[Job, Workbench, Progress], JobAnswer],
              job: Job) -> None:
        """Worker thread: run the job, publish the statistics, hand back the answer."""
        logger = self.get_logger()
        try:
            result = work(job, self._bench, self._progress(running.kind))
            elapsed = round(time.monotonic() - running.started, 3)
            result = replace(result, started_at=running.started_at, elapsed_s=elapsed)
            if running.kind == JobKind.DIAGNOSIS:
                result = self._with_guidance(result)
            answer = jsonable(result)            # the JSON answered and published
            self._publish(running.kind, answer)
            running.success, running.message = True, dumps(answer)
            outcome = (status_fields(answer)[1] if running.kind == JobKind.VALIDATION
                       else diagnosis_fields(answer)[1])
            logger.info(f'{running.kind} done in {elapsed:.1f} s: {outcome}')
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
                self._durations[running.kind] = time.monotonic() - running.started
            running.done.set()

    def _progress(self, kind: JobKind) -> Progress:
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

    def _publish(self, kind: JobKind, result: Mapping[str, Any]) -> None:
        """Latch the newest validation and diagnosis statuses (JSON) together on ~/violation."""
        if kind == JobKind.VALIDATION:
            self._statuses[kind] = validation_status(result, STATUS_NAME, HARDWARE_ID)
        else:
            self._statuses[kind] = diagnosis_status(result, DIAGNOSIS_STATUS_NAME, HARDWARE_ID)
        self._violation.publish(violation_array(list(self._statuses.values()),
                                                self.get_clock().now().nanoseconds))

    # live guidance

    def _with_guidance(self, answer: JobAnswer) -> JobAnswer:
        """Tell the guide what the diagnosis named; return the answer with the guidance."""
        from octoroach_model.diagnosis import DiagnosisReport

        report = answer.result
        assert isinstance(report, DiagnosisReport)
        with self._guide_lock:
            guide = self._guide
            if guide is None:
                return answer
            guide.diagnosed(report, report.paths)
            latest = guide.latest
        return replace(answer, guidance=latest)

    def _watch(self) -> None:
        """
        Guidance thread: decide again whenever the runs or the question change.

        Polls the stamps of the files behind `bags` (validation_jobs.source_stamps) every
        guidance_period_s; a baseline fitted apart is taken up at the next poll.
        """
        from octoroach_model.validation_jobs import source_stamps

        logger = self.get_logger()
        bench = Workbench()
        question_key: tuple | None = None
        seen: tuple | None = None
        while not self._stop.is_set() and self.context.ok():
            try:
                values = current_values(self, self._specs)
                job = Job.from_values({**values, 'bags': self.bags()})
                question = GuidanceQuestion.from_values(values)
            except OctoroachError:    # parameters mid-change: the set callback refuses
                self._stop.wait(0.1)     # what does not fit; read again in a moment
                continue
            period = values['guidance_period_s']
            assert isinstance(period, float)      # the spec's type, rclpy enforces it
            key = (question, job.sources, job.topic, job.gap_s, job.min_duration_s)
            if key != question_key:
                question_key, seen = key, None
                term = question.kind == QuestionKind.TERM
                with self._guide_lock:
                    self._guide = Guide(question, self._refit_pool() if term else None) \
                        if question.asked else None
            guide = self._guide
            if guide is None:
                self._stop.wait(period)
                continue
            stamps = source_stamps(job.sources)
            if stamps != seen or (guide.live is not None and guide.live.ready):
                seen = stamps
                self._decide(guide, bench, job, logger)
            self._stop.wait(period)

    def _decide(self, guide: Any, bench: Workbench, job: Job, logger: Any) -> None:
        """Read the runs, ask the guide, latch the answer on ~/guidance."""
        measured, problem = None, None
        try:
            if job.sources:
                measured = bench.measured(job)
            else:
                problem = 'no measured runs: set the parameter bags'
        except OctoroachError as error:
            problem = _one_line(error)
        except Exception as error:  # noqa: BLE001 - a bug must not end the guidance thread
            problem = _one_line(error)
            logger.error(f'guidance: reading the runs failed: {problem}')
        try:
            with self._guide_lock:
                # the count and the runs still needed follow a new run at once; the look
                # on it (a second or two for a term fitted with the geometry) follows
                carried = guide.refresh(measured.n_paths) if measured is not None else None
            if carried is not None:
                self._guidance.publish(guidance_array(carried, guidance_fields(carried),
                                                      self.get_clock().now().nanoseconds))
            with self._guide_lock:
                answer = guide.update(measured, problem)
        except Exception as error:  # noqa: BLE001 - a bug must not take the node down
            logger.error(f'guidance failed: {_one_line(error)}')
            return
        self._guidance.publish(guidance_array(answer, guidance_fields(answer),
                                              self.get_clock().now().nanoseconds))

    def _refit_pool(self) -> Any:
        """Return the one worker process the guide fits its baselines in (made once)."""
        if self._refits is None:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            from octoroach_model.workers import one_blas_thread

            server = multiprocessing.get_context('forkserver')
            server.set_forkserver_preload(['octoroach_model.diagnosis.live'])
            self._refits = ProcessPoolExecutor(max_workers=1, mp_context=server,
                                               initializer=one_blas_thread)
        return self._refits

    def stop_jobs(self) -> None:
        """Ask a running job to stop at its next progress report; waiting callbacks return."""
        self._stop.set()

    def destroy_node(self) -> None:
        self.stop_jobs()
        thread = self._guidance_thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=5.0)
        if self._refits is not None:
            # a baseline being fitted is not worth waiting for: its process is ended (the
            # pool has no public way to), then the pool is shut down cleanly
            for process in list(getattr(self._refits, '_processes', {}).values()):
                process.terminate()
            self._refits.shutdown(wait=True, cancel_futures=True)
        super().destroy_node()


# -- command line ---------------------------------------------------------------------------

LONG_LIST = 20   # --call: number lists longer than this are summarized (--raw: all of them)


def readable_json(message: str) -> str:
    """
    Return the answer of a call as a person reads it: indented, long grids summarized.

    A validation's answer holds its whole search grid (17 x 17 estimates and more): printed
    in full on one line it is 10 kB that no one reads. Text that is not JSON is returned as
    it is.
    """
    try:
        value = json.loads(message)
    except ValueError:
        return message
    return json.dumps(_summarized(value), indent=2)


def _summarized(value: Any) -> Any:
    if isinstance(value, dict):
        return {key: _summarized(item) for key, item in value.items()}
    if isinstance(value, list):
        numbers = _numbers(value)
        if numbers is not None and len(numbers) > LONG_LIST:
            shape = ' x '.join(str(n) for n in _shape(value))
            finite = [number for number in numbers if number is not None]
            span = f' from {min(finite):.4g} to {max(finite):.4g}' if finite else ''
            return f'<{shape} numbers{span}; --raw prints them all>'
        return [_summarized(item) for item in value]
    return value


def _numbers(value: Any) -> list[float | None] | None:
    """All numbers of a (nested) list of numbers or nulls; None if anything else is in it."""
    if isinstance(value, list):
        found: list[float | None] = []
        for item in value:
            inner = _numbers(item)
            if inner is None:
                return None
            found.extend(inner)
        return found
    if value is None or (isinstance(value, (int, float)) and not isinstance(value, bool)):
        return [value]
    return None


def _shape(value: Any) -> list[int]:
    shape = []
    while isinstance(value, list):
        shape.append(len(value))
        value = value[0] if value else None
    return shape


def call_service(service: str, node_name: str, timeout_s: float,
                 ros_args: Sequence[str], raw: bool = False) -> int:
    """
    Call `~/<service>` of the validator `node_name` and print its JSON answer; exit code.

    What `ros2 service call /validator/validate std_srvs/srv/Trigger` does on a full ROS
    install, for machines with rclpy only: the answer goes to stdout (indented, long grids
    summarized; with `raw` as received), a failed call also gives one `error:` line on stderr
    and exit code 1.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node as ClientNode
    from std_srvs.srv import Trigger

    try:
        rclpy.init(args=['validator', *ros_args])
    except Exception as error:  # noqa: BLE001 - RCLError for malformed --ros-args
        return fail(f'bad ROS arguments: {str(error).splitlines()[0]}')
    name = f'{node_name.rstrip("/")}/{service}'
    node = ClientNode('validator_call')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        client = node.create_client(Trigger, name)
        discovery_s = min(timeout_s, DISCOVERY_TIMEOUT_S)
        if not client.wait_for_service(timeout_sec=discovery_s):
            return fail(f'no service {name} within {discovery_s:g} s: is the validator '
                        'running, on the same ROS_DOMAIN_ID?', 1)
        future = client.call_async(Trigger.Request())
        executor.spin_until_future_complete(future, timeout_sec=timeout_s)
        if not future.done():
            return fail(f'{name} did not answer within {timeout_s:g} s', 1)
        response = future.result()
    except KeyboardInterrupt:
        return fail('interrupted', 130)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    sys.stdout.write((response.message if raw else readable_json(response.message)) + '\n')
    if response.success:
        return 0
    try:
        reason = json.loads(response.message).get('error', response.message)
    except (ValueError, AttributeError):
        reason = response.message
    return fail(f'{name}: {reason}', 1)


def main(argv: Sequence[str] | None = None) -> int:
    """Run `validator [--help] [--call SERVICE] [--ros-args ...]`; return the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        own, ros = split_ros_args(argv)
        parser = node_parser('validator', SUMMARY, [*ARRAYS, *validator_specs()], TOPICS, NOTES,
                             '[--call {validate,diagnose} [--node NAME] [--timeout S]]')
        parser.add_argument('--call', choices=tuple(SERVICES), metavar='SERVICE',
                            help='call ~/SERVICE (validate or diagnose) of a running validator '
                            'and print its JSON answer, instead of starting the node')
        parser.add_argument('--node', default='/validator',
                            help='--call: the validator node (default: /validator)')
        parser.add_argument('--raw', action='store_true',
                            help='--call: print the answer as received (one line, every '
                            'number), not indented with long grids summarized')
        parser.add_argument('--timeout', type=float, default=3600.0, metavar='S',
                            help='--call: longest wait for the answer, seconds (for the service '
                            f'to appear: at most {DISCOVERY_TIMEOUT_S:g}; default: 3600)')
        args = parser.parse_args(own)
        if args.call is None and (args.node != '/validator' or args.timeout != 3600.0
                                  or args.raw):
            raise UsageError('--node, --timeout and --raw go with --call')
        if not (math.isfinite(args.timeout) and args.timeout > 0):
            raise UsageError(f'--timeout must be a positive number of seconds, got '
                             f'{args.timeout}')
    except SystemExit as stop:  # --help
        return int(stop.code or 0)
    except (UsageError, OctoroachError) as error:
        return fail(str(error), start_exit_code(error))
    if args.call is not None:
        return call_service(args.call, args.node, args.timeout, ros, raw=args.raw)
    return run_node(Validator, ros, prog='validator', executor_threads=EXECUTOR_THREADS)


if __name__ == '__main__':
    sys.exit(main())
