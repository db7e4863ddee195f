"""
What every node shares: parameters with ranges, the command line, spin and shutdown, QoS.

Parameters are declared from `ParamSpec` tables, so the same table gives the ROS descriptors
(description, FloatingPointRange / IntegerRange), the checks in the set-parameters callbacks,
the `--help` text and the params files (`settings_yaml`), and they cannot drift apart. A
parameter that is a field of a settings record is made from the field (`field_specs`), so the
record's checks and the offline programs' options say the same. Message conversion is in
`messages`.
"""
from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
import faulthandler
import math
import os
import signal
import sys
import textwrap
import threading
from typing import Any, NoReturn, TYPE_CHECKING

from octoroach_model.errors import exit_code, EXIT_USAGE, OctoroachError, ParameterError
from octoroach_model.settings import Setting, setting, settings_of, shown, unknown_name

if TYPE_CHECKING:
    from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile

# VICON stream QoS: reliable so a recorder loses nothing, keep_last 100 (2 s at 50 Hz) so a
# slow subscriber is not dropped at once while a publisher never blocks.
VICON_QOS_DEPTH = 100

ParamValue = bool | int | float | str | list[str]
MAX_RANGE_WIDTH = 24  # longer choice lists go into the description column of --help
INT64_MIN, INT64_MAX = -2**63, 2**63 - 1   # a ROS integer parameter's own range


class UsageError(OctoroachError):
    """Bad command line (flags or --ros-args)."""


# -- parameters -----------------------------------------------------------------------------

@dataclass(frozen=True)
class ParamSpec:
    """
    One ROS parameter: default, description, unit and allowed values.

    The type is the default's type (bool, int, float, str or list of str); `low`/`high` give a
    range for numbers (inclusive, or exclusive where `open_low`/`open_high`), `choices` the
    allowed strings. `preset` marks a default that came from a command-line flag
    (`with_defaults`): it wins over --ros-args and params files.
    """

    name: str
    default: ParamValue
    description: str
    unit: str = ''
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] = ()
    read_only: bool = False
    preset: bool = False
    open_low: bool = False
    open_high: bool = False

    @classmethod
    def of(cls, name: str, default: ParamValue, described: Setting) -> ParamSpec:
        """Make the parameter of a setting (`settings.Setting`) with its default."""
        return cls(name, default, described.description, described.unit, described.low,
                   described.high, described.choices, described.read_only,
                   open_low=described.open_low, open_high=described.open_high)

    @property
    def setting(self) -> Setting:
        """Return what the parameter allows as a `settings.Setting` (its range logic)."""
        return Setting(self.description, self.unit, self.low, self.high, self.open_low,
                       self.open_high, self.choices, self.read_only)

    @property
    def kind(self) -> str:
        """Parameter type as the user writes it."""
        value = self.default
        if isinstance(value, bool):
            return 'bool'
        if isinstance(value, int):
            return 'integer'
        if isinstance(value, float):
            return 'double'
        if isinstance(value, str):
            return 'string'
        return 'string array'

    def range_text(self) -> str:
        """Return the allowed values for humans: '[lo, hi]', '(0, 1)', 'a | b', or ''."""
        return self.setting.range_text()

    def descriptor(self) -> ParameterDescriptor:
        """Build the ROS descriptor: type, description with unit, range, read-only flag."""
        from rcl_interfaces.msg import (
            FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType)

        types = {'bool': ParameterType.PARAMETER_BOOL,
                 'integer': ParameterType.PARAMETER_INTEGER,
                 'double': ParameterType.PARAMETER_DOUBLE,
                 'string': ParameterType.PARAMETER_STRING,
                 'string array': ParameterType.PARAMETER_STRING_ARRAY}
        unit = f' [{self.unit}]' if self.unit else ''
        descriptor = ParameterDescriptor(name=self.name, type=types[self.kind],
                                         description=self.description + unit,
                                         read_only=self.read_only)
        if self.choices:
            descriptor.additional_constraints = 'one of: ' + ', '.join(self.choices)
        elif self.open_low or self.open_high:   # a ROS range is closed: the check does the rest
            descriptor.additional_constraints = f'in {self.range_text()}, ends excluded'
        if self.kind == 'double' and self.low is not None and self.high is not None:
            descriptor.floating_point_range = [FloatingPointRange(
                from_value=float(self.low), to_value=float(self.high), step=0.0)]
        elif self.kind == 'integer' and (self.low is not None or self.high is not None):
            descriptor.integer_range = [IntegerRange(
                from_value=INT64_MIN if self.low is None else int(self.low),
                to_value=INT64_MAX if self.high is None else int(self.high), step=1)]
        return descriptor

    def check(self, value: Any) -> str | None:
        """Why `value` is not allowed, or None when it is."""
        if not _has_kind(value, self.kind):
            return (f'{self.name} must be a {self.kind}, got {shown(value)}'
                    + (' (write doubles with a decimal point, e.g. 50.0)'
                       if self.kind == 'double' else ''))
        if self.kind == 'double' and not math.isfinite(value):
            return f'{self.name} must be finite, got {value}'
        if self.kind in ('double', 'integer') and not self.setting.allows(value):
            unit = f' {self.unit}' if self.unit else ''
            return f'{self.name} = {value}{unit} is outside {self.range_text()}'
        if self.choices and value not in self.choices:
            return (f'{self.name} must be one of {", ".join(self.choices)}, got '
                    f'{unknown_name(value, self.choices)}')
        return None


def field_specs(record: type, names: Sequence[str], **defaults: ParamValue
                ) -> list[ParamSpec]:
    """
    Return the parameters of the fields `names` of the settings record `record`, in order.

    Help, unit, range and default come from the field (`settings.setting`); `defaults` give
    a node's own default where it differs from the record's (the validator's sigma1 = -1:
    search). A record field whose default is None (unset) is the empty string here.
    """
    found = settings_of(record)
    specs = []
    for name in names:
        default, described = found[name]
        value = defaults.get(name, '' if default is None else default)
        specs.append(ParamSpec.of(name, list(value) if isinstance(value, tuple) else value,
                                  described))
    return specs


@dataclass(frozen=True)
class SubscriberWait:
    """
    How a publishing node waits for subscribers before its first message (simulator, replay).

    One record for both nodes, so that the parameters mean and allow the same on each.
    """

    wait_subscribers: int = setting(
        0, 'before the first message, wait until every topic published has this many '
        'subscribers (1: start a recorder first, lose nothing)', low=0, high=1000)
    wait_timeout_s: float = setting(10.0, 'longest wait for wait_subscribers, then start',
                                    unit='s', low=0.0, high=3600.0, option='--wait-timeout')


def _has_kind(value: Any, kind: str) -> bool:
    if kind == 'bool':
        return isinstance(value, bool)
    if kind == 'integer':
        return isinstance(value, int) and not isinstance(value, bool)
    if kind == 'double':
        return isinstance(value, float)
    if kind == 'string':
        return isinstance(value, str)
    return isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value)


def with_defaults(specs: Sequence[ParamSpec], defaults: dict[str, Any] | None
                  ) -> list[ParamSpec]:
    """
    Return the specs with some defaults replaced by command-line flags.

    A flag is the most specific thing a user says, so its value wins over the same parameter
    in --ros-args or in a params file (which may well hold the parameter's plain default).
    """
    defaults = defaults or {}
    return [replace(spec, default=defaults[spec.name], preset=True) if spec.name in defaults
            else spec for spec in specs]


def declare_parameters(node: Node, specs: Sequence[ParamSpec]) -> dict[str, Any]:
    """
    Declare every spec on `node`; the values in force (defaults or --ros-args overrides).

    Each value has its spec's type (rclpy enforces it), which only the spec knows: hence Any.

    Raises ParameterError with a one-line reason when an override has the wrong type or lies
    outside its range.
    """
    from rclpy.exceptions import ParameterException

    for spec in specs:
        try:
            node.declare_parameter(spec.name, spec.default, spec.descriptor(),
                                   ignore_override=spec.preset)
        except ParameterException as error:
            reason = (spec.check(spec.default) if spec.preset
                      else rejected_override(node, spec.name, spec.check))
            raise ParameterError(reason or f'parameter {spec.name}: {error}') from None
    values = current_values(node, specs)
    reason = check_values(specs, values)
    if reason:
        raise ParameterError(reason)
    warn_unknown_overrides(node)
    return values


def warn_unknown_overrides(node: Node) -> list[str]:
    """
    Warn about --ros-args or params-file values for parameters the node does not have.

    A mistyped name (`epsilonn:=0.3`) would otherwise be taken in silence, with the default
    in force. rclpy keeps the overrides given to a node in `Node._parameter_overrides` (no
    public accessor in Jazzy); call after every parameter is declared. Returns the names.
    """
    overrides = getattr(node, '_parameter_overrides', None) or {}
    unknown = sorted(name for name in overrides if not node.has_parameter(name))
    if unknown:
        node.get_logger().warning(
            f'unknown parameter(s) {", ".join(unknown)}: {node.get_name()} has no such '
            f'parameter (--help lists them); ignored')
    return unknown


def rejected_override(node: Node, name: str,
                      check: Callable[[ParamValue], str | None]) -> str | None:
    """
    Why the override of `name` (--ros-args, params file) was refused, in our words.

    rclpy refuses an override of the wrong type or range without handing back the value. To
    read it through the public API, the parameter is declared once more without type or range
    (dynamic typing), read, and undeclared again; `check` then says what is wrong with it.
    None when there is no override to read.
    """
    from rcl_interfaces.msg import ParameterDescriptor
    from rclpy.exceptions import ParameterException

    try:
        value = node.declare_parameter(name, None, ParameterDescriptor(dynamic_typing=True)).value
        node.undeclare_parameter(name)
    except ParameterException:
        return None
    return None if value is None else check(_plain(value))


def current_values(node: Node, specs: Iterable[ParamSpec]) -> dict[str, ParamValue]:
    """Name -> value of the declared parameters in `specs`."""
    return {spec.name: _plain(node.get_parameter(spec.name).value) for spec in specs}


def _plain(value: Any) -> ParamValue:
    """Make string arrays plain lists (rclpy hands them back as lists or array-likes)."""
    if isinstance(value, (bool, int, float, str)):
        return value
    return [str(v) for v in value]


def check_values(specs: Iterable[ParamSpec], values: Mapping[str, Any]) -> str | None:
    """First reason why one of `values` is not allowed by its spec, or None."""
    for spec in specs:
        if spec.name in values:
            reason = spec.check(values[spec.name])
            if reason:
                return reason
    return None


def set_parameters_callback(
        node: Node, specs: Sequence[ParamSpec],
        check_all: Callable[[dict[str, ParamValue]], str | None] | None = None,
) -> Callable[[list[Parameter]], SetParametersResult]:
    """
    Make a callback for `add_on_set_parameters_callback`: ranges, choices, `check_all`.

    `check_all` sees every value as it would be after the change (for checks across
    parameters) and returns a reason to reject, or None.
    """
    from rcl_interfaces.msg import SetParametersResult

    by_name = {spec.name: spec for spec in specs}

    def callback(parameters: list[Parameter]) -> SetParametersResult:
        values = current_values(node, specs)
        for parameter in parameters:
            spec = by_name.get(parameter.name)
            if spec is None:
                continue  # rclpy's own parameters (use_sim_time, ...)
            value = _plain(parameter.value)
            if spec.read_only:
                return SetParametersResult(successful=False,
                                           reason=f'{spec.name} is read-only')
            reason = spec.check(value)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
            values[spec.name] = value
        reason = check_all(values) if check_all else None
        if reason:
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    return callback


# -- command line ---------------------------------------------------------------------------

class NodeArgumentParser(argparse.ArgumentParser):
    """argparse that reports bad flags as one `error: ...` line (UsageError), not usage text."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(message)


def add_flag(parser: argparse.ArgumentParser, record: type, name: str, *flags: str,
             **overrides: Any) -> argparse.Action:
    """
    Add the command-line flag of parameter `name`, a field of the node's settings `record`.

    Help, unit and range come from the field (`settings.setting`); `flags` name it where it
    is not --NAME-WITH-DASHES or the field's `option` (a bare name: positional). A flag has
    no default: only the flags given replace their parameters' defaults (`with_defaults`),
    and the parameter's check says whether the value is allowed, as for --ros-args.
    `overrides` are argparse's keywords where the flag differs (a metavar).
    """
    default, described = settings_of(record)[name]
    keywords: dict[str, Any] = {'default': None,
                                'help': f'{described.help_text()} (parameter {name})'}
    if described.choices:
        keywords['choices'] = tuple(choice for choice in described.choices if choice)
    elif isinstance(default, bool):
        keywords['action'] = 'store_true'
    elif isinstance(default, (list, tuple)):
        keywords['nargs'] = '+'
    elif isinstance(default, (int, float)):
        keywords['type'] = type(default)
    flags = flags or (described.option or '--' + name.replace('_', '-'),)
    if flags[0].startswith('-'):
        keywords['dest'] = name
    keywords.update(overrides)
    return parser.add_argument(*flags, **keywords)


def flags_given(args: argparse.Namespace, *records: type) -> dict[str, Any]:
    """Return {parameter: value} of the flags given of the fields of `records` (`add_flag`)."""
    return {name: getattr(args, name) for record in records for name in settings_of(record)
            if getattr(args, name, None) is not None}


def node_parser(prog: str, summary: str, specs: Sequence[ParamSpec],
                topics: Sequence[tuple[str, str, str]], notes: str = '',
                arguments: str = '[options]') -> NodeArgumentParser:
    """Parser whose --help explains the node: what it does, parameters, topics."""
    return NodeArgumentParser(
        prog=f'python -m octoroach_model {prog}',
        usage=f'%(prog)s [--help] {arguments} [--ros-args -p NAME:=VALUE ...]',
        description=summary,
        epilog=help_epilog(specs, topics, notes),
        formatter_class=argparse.RawDescriptionHelpFormatter)


def help_epilog(specs: Sequence[ParamSpec], topics: Sequence[tuple[str, str, str]],
                notes: str = '') -> str:
    """Parameter and topic tables for --help."""
    def range_cell(spec: ParamSpec) -> str:
        text = spec.range_text() or '-'
        return text if len(text) <= MAX_RANGE_WIDTH else 'see description'

    def description(spec: ParamSpec) -> str:
        long_choices = len(spec.range_text()) > MAX_RANGE_WIDTH and spec.choices
        return (spec.description + (' (read-only)' if spec.read_only else '')
                + (f'; one of: {", ".join(spec.choices)}' if long_choices else ''))

    rows = [(s.name, _show(s.default), range_cell(s), s.unit or '-') for s in specs]
    widths = [max(len(r[i]) for r in rows + [('name', 'default', 'range', 'unit')])
              for i in range(4)]
    lines = ['ROS parameters (--ros-args -p NAME:=VALUE; doubles need a decimal point):',
             '  ' + '  '.join(h.ljust(w) for h, w in zip(('name', 'default', 'range', 'unit'),
                                                         widths)) + '  description']
    for spec, row in zip(specs, rows):
        lines.append('  ' + '  '.join(c.ljust(w) for c, w in zip(row, widths)) + '  '
                     + description(spec))
    if topics:
        lines += ['', 'Topics and services:']
        width = max(len(t[1]) for t in topics)
        lines += [f'  {kind:<10} {name.ljust(width)}  {kind_type}'
                  for kind, name, kind_type in topics]
    if notes:
        lines += [''] + textwrap.wrap(textwrap.dedent(notes).strip(), 95)
    return '\n'.join(lines)


def _show(value: ParamValue) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f'{value:g}' if '.' in f'{value:g}' or 'e' in f'{value:g}' else f'{value:g}.0'
    if isinstance(value, str):
        return repr(value) if value == '' else value
    if isinstance(value, list):
        return '[' + ', '.join(value) + ']'
    return str(value)


def split_ros_args(argv: Sequence[str]) -> tuple[list[str], list[str]]:
    """
    (node's own flags, ROS arguments incl. '--ros-args') from a command line.

    ROS arguments run from each '--ros-args' to the next '--' or the end. `-p` rules are checked
    here so that a malformed one gives one clear line instead of an rcl parse error.
    """
    own: list[str] = []
    ros: list[str] = []
    inside = False
    expect_rule = False
    for arg in argv:
        if arg == '--ros-args':
            inside = True
            ros.append(arg)
        elif inside and arg == '--':
            inside = False
        elif inside:
            if expect_rule and ':=' not in arg:
                raise UsageError(f'parameter rule {arg!r} must read NAME:=VALUE')
            expect_rule = arg in ('-p', '--param')
            ros.append(arg)
        else:
            own.append(arg)
    if expect_rule:
        raise UsageError('-p at the end of --ros-args needs NAME:=VALUE')
    return own, ros


def start_exit_code(error: BaseException) -> int:
    """
    Exit code of a node that could not start or run (the table of `octoroach_model.errors`).

    A bad flag or ROS parameter at start is a usage error (2); an output that exists or cannot
    be written 3; an input that cannot be used 1.
    """
    from rclpy.exceptions import ParameterException

    if isinstance(error, (UsageError, ParameterError, ParameterException)):
        return EXIT_USAGE
    return exit_code(error)


def fail(message: str, code: int = 2) -> int:
    """Print the one-line reason a user gets, return the exit code."""
    sys.stderr.write('error: ' + ' '.join(str(message).split()) + '\n')
    return code


# -- spin and shutdown ----------------------------------------------------------------------

def run_node(node_factory: Callable[[], Node], ros_args: Sequence[str] | None = None,
             prog: str = 'octoroach_model', executor_threads: int = 1) -> int:
    """
    Init, build the node, spin until Ctrl-C / SIGTERM / done, shut down; an exit code.

    The Jazzy talker pattern. A node may have `done` (an rclpy Future: spin until its result,
    the exit code), `stop_jobs()` (called first on the way out, to stop worker threads) and
    `finish() -> int` (called after destroy_node, when rclpy may already be shut down by a
    signal, to close files; its code wins when non-zero). With executor_threads > 1 a
    MultiThreadedExecutor spins the node, so a callback that waits never blocks the others.
    Domain errors raised while building or spinning the node end as one `error:` line.

    A node asked to stop must stop: the way out runs under a watchdog that prints every
    thread's stack and ends the process if a step takes longer than SHUTDOWN_DEADLINE_S
    (cli.py watches the interpreter's exit after it, which joins the executor's threads).
    `finish()` (closing a bag, however large) runs outside the watchdog.
    """
    import rclpy
    from rclpy.exceptions import ParameterException
    from rclpy.executors import (
        ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor)
    from rclpy.signals import SignalHandlerOptions

    try:
        rclpy.init(args=[prog, *(ros_args or [])],
                   signal_handler_options=SignalHandlerOptions.NO)
    except Exception as error:  # noqa: BLE001 - RCLError for malformed --ros-args
        return fail(f'bad ROS arguments: {str(error).splitlines()[0]}')
    previous = {signum: signal.getsignal(signum) for signum in STOP_SIGNALS}
    stop_on_signals()
    node = None
    executor = None
    code = 0
    try:
        node = node_factory()
        executor = MultiThreadedExecutor(num_threads=executor_threads) \
            if executor_threads > 1 else SingleThreadedExecutor()
        executor.add_node(node)
        done = getattr(node, 'done', None)
        context = node.context
        if done is None:
            while context.ok():
                executor.spin_once(timeout_sec=SPIN_POLL_S)
        else:
            while context.ok() and not done.done():
                executor.spin_until_future_complete(done, timeout_sec=SPIN_POLL_S)
            code = int(done.result() or 0) if done.done() else 0
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (OctoroachError, ParameterException) as error:
        code = fail(str(error), start_exit_code(error))
    finally:
        stop_on_signals(interrupt=False)       # a second one must not cut the way out short
        stopping = shutdown_watchdog(prog, code)
        stop_jobs = getattr(node, 'stop_jobs', None)
        if stop_jobs is not None:
            stop_jobs()
        if executor is not None:
            executor.shutdown(timeout_sec=5.0)
        if node is not None:
            node.destroy_node()
        stopping.set()
        finish = getattr(node, 'finish', None)
        if finish is not None:
            code = int(finish() or 0) or code
        stopping = shutdown_watchdog(prog, code)
        rclpy.try_shutdown()
        stopping.set()
        for signum, handler in previous.items():    # as they were: a caller's children
            if handler is not None:                  # must not inherit SIG_IGN
                signal.signal(signum, handler)
    return code


SHUTDOWN_DEADLINE_S = 20.0
SPIN_POLL_S = 0.2      # longest wait of the executor: how soon a signal is acted on
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def stop_on_signals(interrupt: bool = True) -> None:
    """
    Make SIGINT and SIGTERM raise KeyboardInterrupt in the main thread (or do nothing).

    On the way out they do nothing: a second one must not cut a bag's closing short, and the
    watchdog bounds the way out. rclpy's own handlers are not installed: they shut the
    context down from a thread of their own, which can overlap the main thread's
    destroy_node (a segmentation fault in the type description service's destroy after a
    SIGINT, once in a suite run on a loaded machine), and they missed a SIGTERM now and then
    while a MultiThreadedExecutor waited, and the node ran on. Python's handlers run in the
    main thread, between the executor's short waits (SPIN_POLL_S): the way out is one
    thread's, in order.
    """
    def raise_interrupt(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt(signal.Signals(signum).name)

    for signum in STOP_SIGNALS:
        signal.signal(signum, raise_interrupt if interrupt else signal.SIG_IGN)


def shutdown_watchdog(prog: str, code: int,
                      deadline_s: float = SHUTDOWN_DEADLINE_S) -> threading.Event:
    """
    End the process if the way out is stuck; set the returned event when the step is done.

    A stuck middleware thread must not leave a node running after SIGTERM (a launch file or a
    shell's `wait` would hang on it). The stacks printed say where it was stuck.
    """
    finished = threading.Event()

    def watch() -> None:
        if finished.wait(deadline_s):
            return
        sys.stderr.write(f'error: {prog}: shutdown stuck for {deadline_s:.0f} s; the stack of '
                         f'every thread follows, then the process ends\n')
        faulthandler.dump_traceback(file=sys.stderr, all_threads=True)
        sys.stderr.flush()
        os._exit(code or 1)

    threading.Thread(target=watch, name=f'{prog}-shutdown-watchdog', daemon=True).start()
    return finished


def vicon_qos(depth: int = VICON_QOS_DEPTH) -> QoSProfile:
    """Reliable, volatile, keep_last `depth`: the QoS of every VICON-style publisher here."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
