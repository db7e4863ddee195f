"""
What a named extension is, in the robot's terms: one sentence for the report and summary.md.

Each sentence gives the fitted size with its 95 % interval, says over what it acts (the run
order, the stances, a time in the run, a share of the runs) and where a lab would look.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
import math

from octoroach_model.diagnosis.modelfit import RunData, SizeEstimate
from octoroach_model.model.extensions import LEG_NAMES, WORN_TERMS

MAX_LISTED_RUNS = 12


def number(value: float, digits: int = 2) -> str:
    """Return `value` with `digits` significant digits, 0 for a value below rounding."""
    if not math.isfinite(value):
        return 'n/a'
    if abs(value) < 1e-12:
        return '0'
    return f'{value:.{digits}g}' if abs(value) < 10 ** digits else f'{value:.0f}'


def _range(interval: Sequence[float], scale: float = 1.0, digits: int = 2) -> str:
    low, high = sorted(scale * float(value) for value in interval)
    return f'{number(low, digits)} to {number(high, digits)}'


def _percent_range(interval: Sequence[float], sign: float) -> str:
    low, high = sorted(abs(100 * float(value)) if sign * float(value) > 0 else 0.0
                       for value in interval)
    return f'{number(low)}-{number(high)} %'


def _runs(indices: Sequence[int]) -> str:
    shown = ', '.join(str(index) for index in indices[:MAX_LISTED_RUNS])
    more = f' and {len(indices) - MAX_LISTED_RUNS} more' if len(indices) > MAX_LISTED_RUNS else ''
    return shown + more


def describe(term: str, values: Mapping[str, float], interval: Mapping[str, Sequence[float]],
             estimate: SizeEstimate | None, data: RunData) -> str:
    """Return the sentence for an extension term fitted as `values` (module docstring)."""
    change = float(values.get('change', 0.0))
    if term == 'run_order_drift:stride_frequency':
        way = 'fell' if change < 0 else 'rose'
        look = ('look at the battery (a battery that drains over the session slows the gait)'
                if change < 0 else 'look at the battery or the motor (a gait that quickens '
                'over the session: a fresh battery swapped in, a motor warming up)')
        return (f'the stride frequency {way} by {number(abs(100 * change))} % '
                f'({_percent_range(interval["change"], change)}) from the first run to the '
                f'last, in recording order: {look}')
    if term == 'run_order_drift:yaw_rate':
        return (f'the turning rate changed by {number(change)} deg/s '
                f'({_range(interval["change"])}) from the first run to the last, in '
                'recording order (left positive): a leg that wears, or a foot or a floor '
                'that changes over the session')
    if term == 'run_order_drift:lateral_velocity':
        return (f'the sideways drift changed by {number(change)} cm/s '
                f'({_range(interval["change"])}) from the first run to the last, in '
                'recording order (right positive): a leg that wears, or a floor that '
                'changes over the session')
    if term in WORN_TERMS:
        way = 'wider' if change > 0 else 'narrower'
        column = WORN_TERMS[term]
        return (f'a leg that wears: the touchdown angle of {LEG_NAMES[column]} (phi{column + 1}) '
                f'moved by {number(change)} deg ({_range(interval["change"])}) from the first '
                f'run to the last, in recording order, its stance {way}, the liftoff angle '
                "following by the paper's eqs. (7)-(8): look at the legs' wear, or a foot "
                'that loosens over the session')
    if term == 'heading_random_walk':
        return (f'the heading wanders stance by stance: each stance turns it by a random '
                f'{number(values["step_std_deg"])} deg ({_range(interval["step_std_deg"])}, '
                "standard deviation) that stays, beyond what the paper's random angles give: "
                'slipping feet, or an uneven or compliant floor')
    if term == 'periodic_heading':
        frequency = float(values['frequency_hz'])
        low, high = interval.get('frequency_hz', (frequency, frequency))
        return (f'the heading swings by +-{number(values["amplitude_deg"])} deg '
                f'({_range(interval["amplitude_deg"])}) at {number(frequency, 3)} Hz '
                f'({number(low, 3)} to {number(high, 3)} Hz, a period of '
                f'{number(1 / max(frequency, 1e-9))} s), not at the stride frequency '
                f'({number(data.stride_frequency, 3)} Hz): a tether or a cable, a tail, or a '
                'floor with a period')
    if term == 'change_point':
        factor = float(values['speed_factor'])
        way = 'slower' if factor < 1 else 'faster'
        return (f'from {number(values["time_s"], 3)} s ({_range(interval["time_s"], digits=3)}'
                f' s) into each run the gait runs at {number(factor, 3)} '
                f'({_range(interval["speed_factor"], digits=3)}) times its earlier speed, '
                f'{number(abs(100 * (1 - factor)))} % {way}: a change of floor, or a slope, at '
                'that point of the track')
    if term == 'run_mixture':
        turning = list((estimate.detail if estimate else {}).get('turning_runs', []))
        listed = f'; the turning runs, numbered in recording order: {_runs(turning)}' \
            if turning else ''
        return (f'{number(100 * values["fraction"])} % '
                f'({_range(interval["fraction"], 100)} %) of the runs turn at '
                f'{number(values["yaw_rate_deg_s"])} deg/s '
                f'({_range(interval["yaw_rate_deg_s"])}), the others do not: a leg that '
                f'fails in some runs, or runs started against an obstacle{listed}')
    if term == 'yaw_rate_ramp':
        rate = float(values['final_yaw_rate_deg_s'])
        return (f'every run turns more as it goes on: its yaw rate rises from 0 at the start '
                f'to {number(rate)} deg/s ({_range(interval["final_yaw_rate_deg_s"])}) at '
                f'{number(data.paths.t[-1], 3)} s (left positive): a motor that heats, a '
                'tether or cable that pulls harder as the robot goes, a floor that tilts along '
                'the track')
    raise KeyError(f'no description for {term}')
