"""
The plots of a study, drawn from its summary: every axis, line and colour labelled.

- false_positive.png: false-positive rate per run count, 95 % intervals, the 5 % target;
- power.png: power against size for each cause (one panel) and run count (one line);
- power_at_limit.png: power at multiples of the reported detection limit, with the band an
  honest limit must fall in (65-95 % at 1x, >= 90 % at 2x);
- estimation_error.png: median relative error of the main parameter where the cause was named.

A plot whose data the study does not hold is not drawn (and not listed).
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from octoroach_model.studies.summary import AT_LIMIT_RANGE, AT_TWICE_MIN, POWER_TARGET
from octoroach_model.studies.summary_records import (
    FALSE_POSITIVE_TARGET, Rate, RunsCell, StudySummary)
from octoroach_model.studies.terms import main_parameter


def write_plots(summary: StudySummary, out: Path) -> list[Path]:
    """Every plot the summary has data for, as PNG files in `out` (atomic); their paths."""
    import matplotlib

    from octoroach_model.fileio import atomic_file

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    written = []
    for name, draw in (('false_positive.png', _false_positive), ('power.png', _power),
                       ('power_at_limit.png', _power_at_limit),
                       ('estimation_error.png', _estimation_error)):
        figure = draw(plt, summary)
        if figure is None:
            continue
        figure.tight_layout()
        with atomic_file(out / name, replace=True, what='plot') as stream:
            figure.savefig(stream, format='png', dpi=110)
        plt.close(figure)
        written.append(out / name)
    return written


def _errorbars(rates: Sequence[Rate]) -> tuple[list, list]:
    """Rates and their asymmetric interval half-widths, for matplotlib's errorbar."""
    shares = [_share(rate) for rate in rates]
    below = [_share(rate) - _bounds(rate)[0] for rate in rates]
    above = [_bounds(rate)[1] - _share(rate) for rate in rates]
    return shares, [below, above]


def _share(rate: Rate) -> float:
    assert rate.rate is not None        # only rates of data sets are drawn
    return rate.rate


def _bounds(rate: Rate) -> tuple[float, float]:
    assert rate.interval is not None
    return rate.interval


def _runs_label(runs: RunsCell) -> str:
    return f'{runs} runs' if runs != 'drawn' else 'runs drawn per data set'


def _false_positive(plt, summary):
    cells = [cell for cell in summary.false_positive.by_runs if cell.rate.rate is not None]
    if not cells:
        return None
    figure, axis = plt.subplots(figsize=(6, 4))
    positions = list(range(len(cells)))
    rates, bars = _errorbars([cell.rate for cell in cells])
    axis.errorbar(positions, rates, yerr=bars, fmt='o', color='tab:red', capsize=4,
                  label='false-positive rate (95 % Wilson interval)')
    axis.axhline(FALSE_POSITIVE_TARGET, color='grey', linestyle='--',
                 label=f'target {FALSE_POSITIVE_TARGET:.0%}')
    axis.set_xticks(positions, [f'{_runs_label(c.runs)}\n({c.rate.trials} data sets)'
                                for c in cells])
    axis.set_xlabel('run count of the null data sets')
    axis.set_ylabel('share of null data sets with a cause named')
    axis.set_ylim(-0.01, max(0.2, max(_bounds(c.rate)[1] for c in cells) * 1.1))
    axis.set_title("False positives: a cause named on data from the paper's model")
    axis.legend(loc='upper right', fontsize=8)
    return figure


def _power(plt, summary):
    entries = [entry for entry in summary.power if entry.named.rate is not None]
    causes = list(dict.fromkeys(entry.cause for entry in entries))
    if not causes:
        return None
    figure, axes = plt.subplots(1, len(causes), figsize=(4.5 * len(causes), 4), squeeze=False)
    for axis, cause in zip(axes[0], causes):
        mine = [entry for entry in entries if entry.cause == cause]
        for runs in dict.fromkeys(entry.runs for entry in mine):
            line = sorted((e for e in mine if e.runs == runs), key=lambda e: e.size)
            rates, bars = _errorbars([e.named for e in line])
            axis.errorbar([e.size for e in line], rates, yerr=bars, marker='o', capsize=3,
                          label=_runs_label(runs))
        axis.axhline(POWER_TARGET, color='grey', linestyle='--',
                     label=f'{POWER_TARGET:.0%} power')
        axis.set_ylim(-0.02, 1.02)
        axis.set_xlabel(f'true {main_parameter(cause)} (size of the effect)')
        axis.set_ylabel('share of data sets with the cause named')
        axis.set_title(f'Power: {cause}')
        axis.legend(title='run count (95 % intervals)', fontsize=8)
    return figure


def _power_at_limit(plt, summary):
    entries = [entry for entry in summary.power_at_limit_multiples
               if entry.named.rate is not None]
    if not entries:
        return None
    figure, axis = plt.subplots(figsize=(6.5, 4.5))
    for cause, runs in dict.fromkeys((e.cause, e.runs) for e in entries):
        line = sorted((e for e in entries if (e.cause, e.runs) == (cause, runs)),
                      key=lambda e: e.limit_multiple)
        rates, bars = _errorbars([e.named for e in line])
        axis.errorbar([e.limit_multiple for e in line], rates, yerr=bars, marker='o',
                      capsize=3, label=f'{cause}, {_runs_label(runs)}')
    axis.fill_between([0.9, 1.1], *AT_LIMIT_RANGE, color='tab:green', alpha=0.2,
                      label=f'honest limit at 1x: {AT_LIMIT_RANGE[0]:.0%}-'
                            f'{AT_LIMIT_RANGE[1]:.0%}')
    axis.fill_between([1.9, 2.1], AT_TWICE_MIN, 1.0, color='tab:blue', alpha=0.2,
                      label=f'honest limit at 2x: >= {AT_TWICE_MIN:.0%}')
    axis.set_ylim(-0.02, 1.02)
    axis.set_xlabel('effect size as a multiple of the detection limit reported on the '
                    'null data')
    axis.set_ylabel('share of data sets with the cause named')
    axis.set_title('Do the reported detection limits hold? (95 % intervals)')
    axis.legend(fontsize=7)
    return figure


def _estimation_error(plt, summary):
    entries = [entry for entry in summary.estimation
               if entry.median_abs_relative_error is not None]
    if not entries:
        return None
    figure, axis = plt.subplots(figsize=(max(6, 0.6 * len(entries) + 2), 4.5))
    positions = list(range(len(entries)))
    axis.bar(positions, [100 * e.median_abs_relative_error for e in entries],
             color='tab:purple', label='median |relative error|')
    axis.plot(positions, [100 * e.median_relative_error for e in entries], 'k_',
              markersize=14, label='median relative error (bias)')
    axis.axhline(0, color='grey', linewidth=0.8)
    axis.set_xticks(positions, [
        f'{e.arm}\n' + (f'{e.cause}\n' if e.arm.count('=') > 1 else '')
        + f'{_runs_label(e.runs)}, {e.named} named' for e in entries],
        rotation=60, ha='right', fontsize=7)
    axis.set_ylabel('error of the main parameter, %')
    axis.set_xlabel('arm (cause = size), run count, data sets where the cause was named')
    axis.set_title('Estimation error where the true cause was named')
    axis.legend(fontsize=8)
    return figure
