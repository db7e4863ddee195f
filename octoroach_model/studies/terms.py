"""
The terms a study can put into data and read back, by one name each.

The causes of the table and the extension families' terms (`run_order_drift:yaw_rate` for a
family's term).

One place for what the spec, the rows and the summary need of a term: its main parameter,
whether it has a sign, its value of no effect, its parameter ranges, and its table column.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from octoroach_model.diagnosis.causes import (
    BY_NAME, CANDIDATES, change_point_limit_s, MIXTURE_FRACTION, PERIODIC_LIMIT_PERIODS)
from octoroach_model.errors import ParameterError
from octoroach_model.model import EFFECT_PARAMETERS
from octoroach_model.model.extensions import (
    DRIFT, drift_term, DRIFTED, FAMILY_NAMES, TERM_BY_NAME)
from octoroach_model.settings import unknown_name

TERMS: tuple[str, ...] = tuple(cause.name for cause in CANDIDATES)


def column(term: str) -> str:
    """Return the term as it appears in table column names (no ':')."""
    return term.replace(':', '.')


def main_parameter(term: str) -> str:
    return BY_NAME[term].parameter


def signed(term: str) -> bool:
    return BY_NAME[term].signed


def null_value(term: str) -> float:
    """Return the main parameter's value of no effect (1 for change_point, else 0)."""
    return BY_NAME[term].null


def parameters(term: str) -> tuple[str, ...]:
    if term in EFFECT_PARAMETERS:
        return EFFECT_PARAMETERS[term]
    return TERM_BY_NAME[term].parameters


def term_of(item: Mapping[str, Any], where: str) -> str:
    """
    Return the term a spec entry names: `cause: NAME`, or `extension: FAMILY`.

    run_order_drift also takes `parameter:` (stride_frequency, yaw_rate, lateral_velocity or
    touchdown_angle_1 .. touchdown_angle_4).
    """
    if 'extension' in item:
        family = item['extension']
        if not isinstance(family, str) or family not in FAMILY_NAMES:
            raise ParameterError(f'{where}: unknown extension, '
                                 f'{unknown_name(family, FAMILY_NAMES)}; known: '
                                 f'{", ".join(FAMILY_NAMES)}')
        if family == DRIFT:
            drifted = item.get('parameter')
            if drifted not in DRIFTED:
                raise ParameterError(f'{where}: run_order_drift needs parameter: one of '
                                     f'{", ".join(DRIFTED)}')
            return drift_term(str(drifted))
        if 'parameter' in item:
            raise ParameterError(f'{where}: parameter: belongs to run_order_drift only')
        return str(family)
    return term_named(item.get('cause'), where)


def term_named(value: Any, where: str) -> str:
    """Return a cause or a term given by its name (e.g. in together:), or say what is known."""
    if not isinstance(value, str) or value not in BY_NAME:
        causes = [term for term in TERMS if not BY_NAME[term].is_extension]
        terms = [term for term in TERMS if BY_NAME[term].is_extension]
        raise ParameterError(f'{where}: unknown cause, {unknown_name(value, TERMS)}; known: '
                             f'{", ".join(causes)} (or an extension term: {", ".join(terms)})')
    return str(value)


def term_values(term: str, size: float, others: Mapping[str, float],
                duration_s: float) -> dict[str, float]:
    """
    Return every parameter of a term put into data with its main parameter at `size`.

    `size` is signed; for change_point it is the speed factor's distance from 1 (its sign
    says faster or slower); change_point's time defaults to half the run, periodic_heading's
    frequency to PERIODIC_LIMIT_PERIODS per run, run_mixture's fraction to MIXTURE_FRACTION
    (where their limits are stated).
    """
    values = dict(others)
    if term == 'change_point':
        values.setdefault('time_s', change_point_limit_s(duration_s))
    if term == 'periodic_heading':
        values.setdefault('frequency_hz', PERIODIC_LIMIT_PERIODS / duration_s)
    if term == 'run_mixture':
        values.setdefault('fraction', MIXTURE_FRACTION)
    values[main_parameter(term)] = null_value(term) + size
    return values
