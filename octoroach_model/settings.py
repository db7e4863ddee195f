"""
One source for each setting: the dataclass field, carrying its help, unit and range.

A setting is declared once, as a field of the record that uses it (`ValidationSettings.rho`,
`RunSettings.sigma1`, ...), made with `setting(...)`: its `Setting` rides in the field's
metadata. Everything else is made from it: the record's own checks (`check_fields`), the
options of the offline programs (`commands.common.add_setting`), the ROS parameters of the
nodes with their descriptors (`nodes.common.field_specs`), the nodes' flags
(`nodes.common.add_flag`) and, through the parameters, the params files config/NODE.yaml
(`settings_yaml`). test_settings.py compares them all, so the help,
unit and range a user reads are the ones in force, wherever they read them.

A setting used by several records (the axes of the poses, the gap that splits runs, the wait
for subscribers) is one `Setting` constant given to each field.

A value is checked for its kind as well as its range (`check_fields`, `check_setting`): the
field's annotation says it (int: a whole number, float: a number, str, bool, each with None
where the annotation allows it), so that `DiagnosisSettings(bootstrap=2.5)` or `seed='1'`
through the Python API is refused in one line, as the programs' options and the nodes'
parameter types refuse them.

The entry points' other arguments are checked here too, each fact in one place: a number's
kind (`is_number`, `number`), a flag's (`flag`: true or false, numpy's too, never a text that
would read as true) and a callback's (`check_callable`: a `progress` given as 5 is refused
before any work, not when it is first called).
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, Field, field, fields, MISSING
import difflib
import functools
import math
import numbers
import re
import types
import typing
from typing import Any, TypeVar

import numpy as np

from octoroach_model.errors import ParameterError

__all__ = ['Progress', 'Setting', 'check_callable', 'check_fields', 'check_kinds',
           'check_record', 'check_setting', 'check_value', 'flag', 'is_number', 'number',
           'setting', 'settings_of', 'shown']

METADATA_KEY = 'setting'


@dataclass(frozen=True)
class Setting:
    """
    What a user is told about one setting, and the values it allows.

    `low`/`high` bound a number (inclusive, or exclusive where `open_low`/`open_high`; None:
    unbounded on that side), `choices` list the allowed strings. `option` names the
    command-line option where it is not --NAME-WITH-DASHES; `read_only` marks a ROS parameter
    that can only be set when the node starts.
    """

    description: str
    unit: str = ''
    low: float | None = None
    high: float | None = None
    open_low: bool = False
    open_high: bool = False
    choices: tuple[str, ...] = ()
    read_only: bool = False
    option: str = ''

    def range_text(self) -> str:
        """Return the allowed values for humans: '[lo, hi]', '(0, 1)', '>= 0', 'a | b' or ''."""
        if self.choices:
            return ' | '.join(self.choices)
        low = None if self.low is None else number_text(self.low)
        high = None if self.high is None else number_text(self.high)
        if low is not None and high is not None:
            return f'{"(" if self.open_low else "["}{low}, {high}{")" if self.open_high else "]"}'
        if low is not None:
            return f'{">" if self.open_low else ">="} {low}'
        if high is not None:
            return f'{"<" if self.open_high else "<="} {high}'
        return ''

    def allows(self, value: Any) -> bool:
        """Tell whether `value` lies in the range (finite numbers) or among the choices."""
        if self.choices:
            return value in self.choices
        if not isinstance(value, numbers.Real) or isinstance(value, bool):
            return True                         # numpy's numbers too; kinds: check_setting
        real = float(value)
        if not math.isfinite(real):             # NaN lies in no range; no setting is infinite
            return False
        if self.low is not None and (real <= self.low if self.open_low else real < self.low):
            return False
        return self.high is None or not (real >= self.high if self.open_high
                                         else real > self.high)

    def help_text(self) -> str:
        """Return an option's help: 'description [unit]; range' (choices: argparse lists them)."""
        unit = f' [{self.unit}]' if self.unit else ''
        bounds = '' if self.choices else self.range_text()
        return self.description + unit + (f'; {bounds}' if bounds else '')

    def demand(self) -> str:
        """Say what a value must be, after 'NAME must ': 'lie in (0, 1)', 'be non-negative'."""
        if self.choices:
            return 'be one of ' + ', '.join(repr(choice) for choice in self.choices)
        if self.low == 0 and self.high is None:
            return 'be positive' if self.open_low else 'be non-negative'
        unit = f' {self.unit}' if self.unit else ''
        if self.high is None and self.low is not None:
            return f'be {"above" if self.open_low else "at least"} {number_text(self.low)}{unit}'
        if self.low is None and self.high is not None:
            return f'be {"below" if self.open_high else "at most"} {number_text(self.high)}{unit}'
        return f'lie in {self.range_text()}{unit}'


def number_text(value: float) -> str:
    """Write a bound as people read it: 0.01, 1000, 2147483647."""
    return f'{value:g}' if isinstance(value, float) else str(value)


def setting(default: Any = MISSING, about: str | Setting = '', *,
            default_factory: Any = MISSING, **details: Any) -> Any:
    """
    Make a dataclass field that carries its Setting (the one source of that setting).

    `about` is the help text, or a shared `Setting` (then `details` must be empty); `details`
    are the Setting's unit, low, high, open_low, open_high, choices, read_only and option.
    """
    described = about if isinstance(about, Setting) else Setting(about, **details)
    if isinstance(about, Setting) and details:
        raise TypeError('a shared Setting takes no further details')
    return field(default=default, default_factory=default_factory,
                 metadata={METADATA_KEY: described})


def setting_of(item: Field[Any]) -> Setting | None:
    """Return the Setting a field carries, or None."""
    described = item.metadata.get(METADATA_KEY)
    return described if isinstance(described, Setting) else None


def settings_of(record: Any) -> dict[str, tuple[Any, Setting]]:
    """Return {field name: (default, Setting)} of the fields of `record` that carry one."""
    found: dict[str, tuple[Any, Setting]] = {}
    for item in fields(record):
        described = setting_of(item)
        if described is None:
            continue
        default = item.default if item.default_factory is MISSING else item.default_factory()
        found[item.name] = (default, described)
    return found


def check_fields(record: Any) -> None:
    """Raise ParameterError with a one-line reason for the first field of a wrong kind or range."""
    for name in settings_of(record):
        check_setting(type(record), name, getattr(record, name))


def check_kinds(record: Any) -> None:
    """Raise ParameterError for the first field of a plain kind (int, str, ...) holding another."""
    record_type: type = type(record)
    for name, kind in field_kinds(record_type).items():
        value = getattr(record, name)
        if not kind.holds(value):
            raise ParameterError(f'{name} must be {kind.words}, got {shown(value)}')


def check_setting(record_type: type, name: str, value: Any) -> None:
    """Raise ParameterError when `value` is not of the kind or range of `record_type.name`."""
    kind = field_kinds(record_type).get(name)
    if kind is not None and not kind.holds(value):
        raise ParameterError(f'{name} must be {kind.words}, got {shown(value)}')
    check_value(name, value, settings_of(record_type)[name][1])


@dataclass(frozen=True)
class Kind:
    """The values a field's annotation allows: its types, in words for an error message."""

    types: tuple[type, ...]
    words: str
    optional: bool = False

    def holds(self, value: Any) -> bool:
        """Tell whether `value` is of the kind (a bool is not a number, though Python says so)."""
        if value is None:
            return self.optional
        if isinstance(value, bool) and bool not in self.types:
            return False
        return isinstance(value, self.types)


KINDS = {int: Kind((numbers.Integral,), 'a whole number'),
         float: Kind((numbers.Real,), 'a number'),
         str: Kind((str,), 'text'),
         bool: Kind((bool, np.bool_), 'true or false')}    # numpy's bool, as flag takes it


@functools.lru_cache(maxsize=None)
def field_kinds(record_type: type) -> dict[str, Kind]:
    """Return {field name: Kind} of the fields whose annotation is a plain kind (or it | None)."""
    try:
        hints = typing.get_type_hints(record_type)
    except (NameError, TypeError):       # a name only for type checkers: its kinds unchecked
        return {}
    found = {}
    for name, hint in hints.items():
        parts = typing.get_args(hint) if isinstance(hint, types.UnionType) else (hint,)
        plain = [part for part in parts if part is not type(None)]
        if len(plain) == 1 and plain[0] in KINDS:
            kind = KINDS[plain[0]]
            found[name] = Kind(kind.types, kind.words + (' or none' if len(parts) > 1 else ''),
                               len(parts) > 1)
    return found


def is_number(value: Any) -> bool:
    """
    Tell whether `value` is a real number, Python's or numpy's: a bool, a text, a list is not.

    Quick for a float (numpy's float64 is one) before the slower test against numbers.Real:
    `ModelParameters` asks it inside the fits' residuals.
    """
    return isinstance(value, float) or (isinstance(value, numbers.Real)
                                        and not isinstance(value, bool))


def number(name: str, value: Any) -> float:
    """Return `value` as a float, or raise ParameterError: a text, a bool or a list is not one."""
    if not is_number(value):
        raise ParameterError(f'{name} must be a number, got {shown(value)}')
    return float(value)


def flag(name: str, value: Any) -> bool:
    """Return `value` as a bool, or raise ParameterError: only True or False (numpy's too)."""
    if not KINDS[bool].holds(value):
        raise ParameterError(f'{name} must be {KINDS[bool].words}, got {shown(value)}')
    return bool(value)


# how the package calls a progress callback (a fraction done in [0, 1], a line of text),
# unless an entry point says otherwise
Progress = Callable[[float, str], None]
PROGRESS_CALL = 'fraction, message'


def check_callable(name: str, value: Any, arguments: str = PROGRESS_CALL) -> None:
    """Raise ParameterError unless `value` is None or callable (as NAME(`arguments`))."""
    if value is not None and not callable(value):
        raise ParameterError(f'{name} must be a function, called as {name}({arguments}), or '
                             f'None, got {shown(value)}')


def check_record(name: str, value: Any, record_type: type) -> None:
    """Raise ParameterError unless `value` is None or a `record_type` (a settings record)."""
    if value is not None and not isinstance(value, record_type):
        raise ParameterError(f'{name} must be a {record_type.__name__} (or None for the '
                             f'defaults), got {shown(value)}')


def shown(value: Any) -> str:
    """
    Show a refused value: a number, bool or None as written, anything else by its kind.

    A text may come from a file (a params file, a study spec): an error never quotes it.
    """
    if value is None or isinstance(value, (bool, np.bool_)):
        return repr(None if value is None else bool(value))
    if isinstance(value, numbers.Integral):     # numpy's as Python's: -1, not np.int64(-1)
        return repr(int(value))
    if isinstance(value, numbers.Real):
        return repr(float(value))
    if isinstance(value, str):
        return f'text ({len(value)} character{"" if len(value) == 1 else "s"}, not shown)'
    name = type(value).__name__
    return f'{"an" if name[0] in "aeiouAEIOU" else "a"} {name}'


# a name read from a file that an error may list: what a user types back (--subject, --topic)
LISTED_NAME = re.compile(r'[A-Za-z0-9_.:/@+\-]([A-Za-z0-9_.:/@+\- ]{0,98}[A-Za-z0-9_.:/@+\-])?')


def looks_like_name(value: Any) -> bool:
    """Tell whether `value` is a name an error may list: letters, digits, _ . : / @ + - ."""
    return isinstance(value, str) and LISTED_NAME.fullmatch(value) is not None


Listed = TypeVar('Listed')


def listed_items(items: Iterable[Listed], describe: Callable[[Listed], str],
                 names: Callable[[Listed], Iterable[Any]], limit: int = 12,
                 noun: str = 'name') -> str:
    """
    List things read from a file among which a user chooses, as an error may: up to `limit`.

    A subject's, a marker's or a topic's name is what the user types back, so an item is
    described where all its `names` look like names; any other (a control character, a long
    text, a line of something else in a name) is counted as a `noun` not shown, never shown.
    """
    items = list(items)
    named = [item for item in items if all(looks_like_name(name) for name in names(item))]
    parts = [', '.join(describe(item) for item in named[:limit])]
    if len(named) > limit:
        parts.append(f'{len(named) - limit} more')
    hidden = len(items) - len(named)
    if hidden:
        parts.append(f'{hidden} {noun}{"s" if hidden > 1 else ""} not shown')
    return ' and '.join(part for part in parts if part)


def listed_names(names: Iterable[Any], limit: int = 12) -> str:
    """List names read from a file, those that look like names (`listed_items`)."""
    return listed_items(names, str, lambda name: (name,), limit)


# names longer than this are not compared with the known ones (`unknown_name`)
NAME_COMPARED_CHARACTERS = 100


def unknown_name(value: Any, known: Sequence[str]) -> str:
    """
    Describe a name that is not among `known` without quoting it: it may come from a file.

    `shown` of it, and the known name it is close to, where one is (a typo's fix, in the
    package's own words).
    """
    close = difflib.get_close_matches(value, list(known), n=1) \
        if isinstance(value, str) and len(value) <= NAME_COMPARED_CHARACTERS else []
    return shown(value) + (f' (did you mean {close[0]}?)' if close else '')


def check_value(name: str, value: Any, described: Setting) -> None:
    """Raise ParameterError when `value` of setting `name` is not allowed: 'NAME must ...'."""
    if not described.allows(value):
        if isinstance(value, float) and not math.isfinite(value):
            raise ParameterError(f'{name} must be a finite number, got {shown(value)}')
        raise ParameterError(f'{name} must {described.demand()}, got {shown(value)}')
