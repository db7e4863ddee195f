"""
The diagnosis in pictures.

Paths against the confidence region (as the paper's Figs. 5b and 6),
E^_k over the (sigma1, sigma2) grid, the statistic that decided each cause, and the discrepancies
before and after the extension. Every axis has its unit, every line and threshold a legend entry,
every colour bar a label.

Each plot is drawn on its own: one that cannot be drawn (degenerate data) is reported with its
reason and costs nothing else.
"""
from __future__ import annotations

from collections.abc import Callable
import math
from pathlib import Path
from typing import Any, NamedTuple, TYPE_CHECKING

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from octoroach_model.arrays import FloatArray, IntArray  # noqa: E402
from octoroach_model.diagnosis.causes import BY_NAME  # noqa: E402
from octoroach_model.diagnosis.discrepancies import Discrepancy  # noqa: E402
from octoroach_model.diagnosis.features import (  # noqa: E402
    heading_amplitudes, INDEX, run_features)
from octoroach_model.diagnosis.summary import MISFIT_PLOT  # noqa: E402
from octoroach_model.model.effects import shared_clock  # noqa: E402
from octoroach_model.model.extensions import WORN_TERMS  # noqa: E402
from octoroach_model.paths import Paths  # noqa: E402
from octoroach_model.validation.region import t_multiplier  # noqa: E402

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from octoroach_model.diagnosis.modelfit import FittedModel
    from octoroach_model.diagnosis.records import DiagnosisReport, NamedExtension

N_SHOWN = 45
DEG = 180.0 / math.pi
# cause -> (feature, scale to the axis unit, axis label)
DECIDING = {
    'initial_pose_error': ('start_heading', DEG, 'start heading [deg]'),
    'measurement_noise': ('log_noise', 1.0,
                          'log median squared 4th difference of x, y, resolution included '
                          '[log m^2]'),
    'gait_frequency_variation': ('stride_frequency', 1.0, 'stride frequency [Hz]'),
    'speed_decay': ('progress_ratio', 1.0,
                    'log(distance in 2nd half / distance in 1st half) [-]'),
    'lateral_slip': ('slip_angle', DEG, 'direction of travel - heading [deg]'),
    'persistent_turning': ('heading_rate', DEG, 'heading rate over the run [deg/s]'),
}


def write_plots(report: DiagnosisReport, measured: Paths, out: Path
                ) -> tuple[dict[str, Path], dict[str, str]]:
    """Draw every plot; returns the files written and, per plot not drawn, the reason."""
    jobs = {'paths_plot': (_paths_plot, out / 'paths.png'),
            'violation_plot': (_violation_plot, out / 'violation_grid.png'),
            'statistic_plot': (_statistic_plot, out / 'deciding_statistic.png'),
            'discrepancy_plot': (_discrepancy_plot, out / 'discrepancies.png'),
            'extension_plot': (_extension_plot, out / 'extensions.png'),
            'misfit_plot': (_misfit_plot, out / MISFIT_PLOT)}
    written, errors = {}, {}
    for name, (draw, path) in jobs.items():
        try:
            if draw(report, measured, path):
                written[name] = path
        except Exception as error:  # noqa: BLE001 - a plot never costs the report
            errors[path.name] = f'{type(error).__name__}: {" ".join(str(error).split())}'
        finally:
            plt.close('all')
    return written, errors


def _simulate(model: FittedModel, measured: Paths, n: int,
              positions: FloatArray | None = None) -> Paths:
    poses = model.poses(n, measured.t, np.random.SeedSequence(7), positions=positions)
    return Paths(measured.t, poses)


def _at_places(model: FittedModel, measured: Paths, n: int) -> tuple[Paths, FloatArray]:
    """`n` runs of `model` at places drawn from the measured runs' (run-order terms)."""
    places = measured.recording_positions()[0]
    picks = np.random.default_rng(7).integers(0, len(places), n)
    return _simulate(model, measured, n, places[picks]), places[picks]


def _paths_plot(report: DiagnosisReport, measured: Paths, path: Path) -> bool:
    checked = report.baseline.validation
    k = checked.k if checked is not None else 11
    with np.errstate(invalid='ignore'):
        centre = np.nanmean(measured.positions, axis=0) * 100
        half = t_multiplier(k, 0.95) * np.nanstd(measured.positions, axis=0, ddof=1) * 100
    shown = np.random.default_rng(0).permutation(measured.n_paths)[:30]
    fig, axes = plt.subplots(1, 3, figsize=(15, 5.5))
    ax = axes[0]
    for number, i in enumerate(shown):
        ax.plot(measured.poses[i, :, 0] * 100, measured.poses[i, :, 1] * 100, color='0.6',
                lw=0.7, label='measured run' if number == 0 else None)
    ax.plot(centre[:, 0], centre[:, 1], 'r--', lw=2, label='data average')
    ax.set_title(f'{len(shown)} of {measured.n_paths} measured runs (Fig. 5a)')
    names = ', '.join(c.cause for c in report.causes) or 'no cause'
    for ax, (label, model) in zip(axes[1:], (('paper model (baseline)', report.baseline_model),
                                             (f'extended model\n({names})',
                                              report.extended_model))):
        ax.fill_betweenx(centre[:, 1], centre[:, 0] - half[:, 0], centre[:, 0] + half[:, 0],
                         color='tab:orange', alpha=0.25, label='95 % region of x (data)')
        simulated = _simulate(model, measured, N_SHOWN)
        for number, run in enumerate(simulated.poses):
            ax.plot(run[:, 0] * 100, run[:, 1] * 100, color='tab:blue', lw=0.6, alpha=0.7,
                    label='model run' if number == 0 else None)
        ax.plot(centre[:, 0], centre[:, 1], 'k', lw=2.5, label='data average')
        ax.set_title(f'{N_SHOWN} runs of the {label} (Fig. 6)')
    for ax in axes:
        ax.set_xlabel('x [cm]')
        ax.set_ylabel('y [cm]')
        ax.set_aspect('equal', adjustable='datalim')
        ax.legend(loc='lower right', fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return True


def _violation_plot(report: DiagnosisReport, measured: Paths, path: Path) -> bool:
    panels = [(name, section.validation) for name, section in
              (('baseline', report.baseline), ('extended', report.extended))
              if section.validation is not None and section.validation.grid is not None]
    if not panels:
        return False
    fig, axes = plt.subplots(1, len(panels), figsize=(6 * len(panels), 5), squeeze=False)
    for ax, (name, section) in zip(axes[0], panels):
        grid = section.grid
        assert grid is not None, 'only panels with a grid were kept'
        values = np.array(grid.violation)
        image = ax.pcolormesh(grid.sigma2, grid.sigma1, values, vmin=0, vmax=1,
                              cmap='viridis', shading='nearest')
        if values.min() < section.rho < values.max():
            ax.contour(grid.sigma2, grid.sigma1, values, levels=[section.rho],
                       colors='w', linewidths=1)
            ax.plot([], [], color='w', lw=1, label=f'E^_k = rho = {section.rho}')
        ax.plot(section.sigma2, section.sigma1, 'r*', ms=16,
                label=f'chosen ({section.sigma1:.3f}, {section.sigma2:.3f}) rad, '
                      f'E^_k = {section.violation:.2f}')
        ax.set_xlabel('sigma2, liftoff angle spread [rad]')
        ax.set_ylabel('sigma1, touchdown angle spread [rad]')
        ax.set_title(f'Estimated probability of violation, {name} model')
        ax.legend(loc='upper right', fontsize=8, facecolor='0.85')
        fig.colorbar(image, ax=ax, label='E^_k, estimated probability of violation [-]')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return True


def _bins(*samples: FloatArray, count: int = 40) -> list[float]:
    """Shared histogram edges that also work when every value is (almost) the same."""
    values = np.concatenate([s[np.isfinite(s)] for s in samples])
    low, high = (float(values.min()), float(values.max())) if values.size else (0.0, 1.0)
    width = high - low
    if not width > 1e-12 * max(1.0, abs(high)):
        pad = max(abs(high) * 1e-3, 1e-9)
        low, high = low - pad, high + pad
    edges: list[float] = np.linspace(low, high, count + 1).tolist()   # as matplotlib types bins
    return edges


def _statistic_plot(report: DiagnosisReport, measured: Paths, path: Path) -> bool:
    causes = [c.cause for c in report.causes]
    if not causes and report.extensions:
        return False            # the extensions' own plot shows their evidence
    if not causes:
        causes = [max(report.candidates, key=lambda c: c.gain).cause]
    frequency = report.nominal['stride_frequency_hz']
    heading = math.radians(report.nominal['start_pose']['heading_deg'])
    data_features = run_features(measured, frequency, heading)
    base = run_features(_simulate(report.baseline_model, measured, 1000), frequency, heading)
    extended = run_features(_simulate(report.extended_model, measured, 1000), frequency,
                            heading)
    fig, axes = plt.subplots(1, len(causes), figsize=(6.5 * len(causes), 4.5), squeeze=False)
    for ax, cause in zip(axes[0], causes):
        feature, scale, label = DECIDING[cause]
        column = INDEX[feature]
        data, b, e = (f[:, column] * scale for f in (data_features, base, extended))
        bins = _bins(data, b, e)
        ax.hist(data, bins=bins, density=True, alpha=0.45, color='k', label='measured runs')
        ax.hist(b, bins=bins, density=True, histtype='step', lw=2, color='tab:blue',
                label='baseline (paper model)')
        ax.hist(e, bins=bins, density=True, histtype='step', lw=2, color='tab:orange',
                ls='--', label='extended model')
        ax.set_xlabel(label)
        ax.set_ylabel('density [1 / axis unit]')
        named = 'named' if cause in {c.cause for c in report.causes} else 'not named'
        ax.set_title(f'{cause} ({named})')
        ax.legend(fontsize=8)
    fig.suptitle('The statistic behind each cause: data, baseline and extended model')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return True


def _discrepancy_plot(report: DiagnosisReport, measured: Paths, path: Path) -> bool:
    rows: list[Discrepancy] = list(report.discrepancies)
    names = [row.statistic for row in rows]
    after = {row.statistic: row for row in report.extended_discrepancies}
    bound = report.adequacy_bound_z
    fig, ax = plt.subplots(figsize=(9, 0.42 * len(rows) + 1.8))
    positions = np.arange(len(rows))
    before_z = np.clip([row.z for row in rows], -50, 50)
    ax.barh(positions - 0.2, before_z, height=0.4, color='tab:blue',
            label='data - baseline (paper model)')
    if after:
        after_z = np.clip([after[name].z if name in after else 0.0 for name in names], -50, 50)
        ax.barh(positions + 0.2, after_z, height=0.4, color='tab:orange',
                label='data - extended model')
    for sign in (-1, 1):
        ax.axvline(sign * bound, color='k', ls=':',
                   label=f'adequacy bound |z| = {bound:.1f}' if sign > 0 else None)
    ax.set_yticks(positions, names)
    ax.invert_yaxis()
    ax.set_xlabel('z = (data - model) / standard error [-] (clipped at +-50; 0 where the '
                  "difference is below the statistic's resolution)")
    ax.set_title('Where the model disagrees with the data,\nbefore and after the extension')
    ax.legend(fontsize=8, loc='lower right')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return True


# run-order drift term -> (feature, scale to the axis unit, axis label)
DRIFT_AXES = {
    'run_order_drift:stride_frequency': ('stride_frequency', 1.0, 'stride frequency [Hz]'),
    'run_order_drift:yaw_rate': ('heading_rate', DEG, 'heading rate over the run [deg/s]'),
    'run_order_drift:lateral_velocity': ('slip_angle', DEG,
                                         'direction of travel - heading [deg]'),
    # a worn leg where it shows most on open_world's robots: phi4 in the turn, the others in
    # the distance (its size is read off both, modelfit._joint_secant)
    **{term: ('heading_rate', DEG, 'heading rate over the run [deg/s]') if column == 3 else
       ('end_progress', 100.0, "progress along the start heading at the run's end [cm]")
       for term, column in WORN_TERMS.items()},
}
# places along the recording a curved drift's model mean is drawn at (means of runs about each)
CURVE_BINS = 10
MODEL_RUNS = 600


def _extension_plot(report: DiagnosisReport, measured: Paths, path: Path) -> bool:
    """One panel per named extension: its evidence where a person would look for it."""
    named = list(report.extensions)
    if not named:
        return False
    fig, axes = plt.subplots(1, len(named), figsize=(6.5 * len(named), 4.8), squeeze=False)
    panels = {'run_order_drift': _drift_panel, 'heading_random_walk': _walk_panel,
              'periodic_heading': _spectrum_panel, 'change_point': _speed_panel,
              'run_mixture': _groups_panel, 'yaw_rate_ramp': _turn_panel}
    for ax, extension in zip(axes[0], named):
        panels[extension.family](ax, report, measured, extension)
        ax.set_title(f'{extension.family}: ' + ', '.join(
            f'{key} = {value:.3g}' if isinstance(value, float) else f'{key} = {value}'
            for key, value in extension.parameters.items()), fontsize=10)
        ax.legend(fontsize=8)
    fig.suptitle('The evidence for each extension: data, baseline and extended model')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return True


def _features_of(report: DiagnosisReport, paths: Paths, places: FloatArray | None) -> FloatArray:
    frequency = report.nominal['stride_frequency_hz']
    heading = math.radians(report.nominal['start_pose']['heading_deg'])
    return run_features(paths, frequency, heading, places)


def _drift_panel(ax: Axes, report: DiagnosisReport, measured: Paths,
                 extension: NamedExtension) -> None:
    feature, scale, label = DRIFT_AXES[extension.term]
    column = INDEX[feature]
    places = measured.recording_positions()[0]
    order = places * max(measured.n_paths - 1, 1)
    data = _features_of(report, measured, places)[:, column] * scale
    ax.plot(order, data, '.', color='0.4', ms=3, label='measured run')
    grid = np.linspace(0.0, 1.0, 50)
    for model, colour, style, name in ((report.baseline_model, 'tab:blue', '-', 'baseline'),
                                       (report.extended_model, 'tab:orange', '--',
                                        'extended model')):
        runs, where = _at_places(model, measured, MODEL_RUNS)
        values = _features_of(report, runs, where)[:, column] * scale
        if BY_NAME[extension.term].secant_steps:     # a curve: the mean of runs about each place
            bins = np.minimum((where * CURVE_BINS).astype(int), CURVE_BINS - 1)
            counts = np.bincount(bins, minlength=CURVE_BINS)
            means = np.bincount(bins, values, minlength=CURVE_BINS) / np.maximum(counts, 1)
            centres = (np.arange(CURVE_BINS) + 0.5) / CURVE_BINS
            ax.plot(centres[counts > 0] * max(measured.n_paths - 1, 1), means[counts > 0],
                    color=colour, ls=style, lw=2, marker='o', ms=3,
                    label=f'{name}: mean of runs about each place')
            continue
        slope, intercept = np.polyfit(where, values, 1)
        ax.plot(grid * max(measured.n_paths - 1, 1), intercept + slope * grid, color=colour,
                ls=style, lw=2, label=f'{name}: mean at each place')
    ax.set_xlabel('run, in recording order [-]')
    ax.set_ylabel(label)


def _walk_panel(ax: Axes, report: DiagnosisReport, measured: Paths,
                extension: NamedExtension) -> None:
    frequency = report.nominal['stride_frequency_hz']
    stance_s = 0.5 / frequency
    dt = float(measured.t[1] - measured.t[0])
    picks = np.arange(0, len(measured.t), max(1, int(round(stance_s / dt))))
    stances = picks * dt / stance_s

    def spread(paths: Paths) -> FloatArray:
        change = paths.poses[:, picks, 2] - paths.poses[:, :1, 2]
        with np.errstate(invalid='ignore'):
            spread_deg: FloatArray = np.nanstd(change, axis=0, ddof=1) * DEG
        return spread_deg

    ax.plot(stances, spread(measured), 'k.-', label='measured runs')
    ax.plot(stances, spread(_simulate(report.baseline_model, measured, MODEL_RUNS)),
            color='tab:blue', lw=2, label='baseline (paper model)')
    ax.plot(stances, spread(_simulate(report.extended_model, measured, MODEL_RUNS)),
            color='tab:orange', ls='--', lw=2, label='extended model')
    ax.set_xlabel('stances since the start [-]')
    ax.set_ylabel('spread of the heading change across runs [deg]')


def _spectrum_panel(ax: Axes, report: DiagnosisReport, measured: Paths,
                    extension: NamedExtension) -> None:
    frequency = float(extension.parameters['frequency_hz'])
    stride = report.nominal['stride_frequency_hz']
    grid = np.linspace(0.05 * stride, 1.9 * stride, 120)

    def amplitude(paths: Paths) -> FloatArray:
        rms_deg: FloatArray = np.sqrt((heading_amplitudes(paths.poses[..., 2], paths.t, grid)
                                       ** 2).mean(axis=0)) * DEG
        return rms_deg

    ax.plot(grid, amplitude(measured), 'k', lw=1.5, label='measured runs')
    ax.plot(grid, amplitude(_simulate(report.baseline_model, measured, MODEL_RUNS)),
            color='tab:blue', lw=2, label='baseline (paper model)')
    ax.plot(grid, amplitude(_simulate(report.extended_model, measured, MODEL_RUNS)),
            color='tab:orange', ls='--', lw=2, label='extended model')
    ax.axvline(frequency, color='tab:red', ls=':', label=f'fitted {frequency:.3g} Hz')
    ax.axvline(stride, color='0.5', ls=':', label=f'stride frequency {stride:.3g} Hz')
    ax.set_xlabel('frequency [Hz]')
    ax.set_ylabel('rms amplitude of the heading (trend removed) [deg]')


def stride_windows(model: FittedModel, t: FloatArray) -> tuple[IntArray, FloatArray]:
    """
    Return where each window one stride of `model`'s gait clock long starts and ends.

    A stride is two stances of the model's clock (speed_decay and the clock terms, as fitted),
    so a window spans one stride before and after a change point, where a fixed number of
    samples would span more or less than one and let the sway within a stride into the curve.
    Starts are samples; ends are fractional sample positions (the clock interpolated), so the
    windows do not jitter by a sample; windows that would end past the grid are left out.
    """
    phase = 2.0 * model.parameters.stride_frequency * shared_clock(model.effects, t)
    after = np.searchsorted(phase, phase + 2.0)
    starts = np.flatnonzero(after < len(t))
    right = after[starts]
    left = right - 1
    fraction = (phase[starts] + 2.0 - phase[left]) / (phase[right] - phase[left])
    return starts, left + fraction


def _at(values: FloatArray, positions: FloatArray, angle: bool = False) -> FloatArray:
    """Return (runs, ...) `values` at fractional sample `positions`, linearly interpolated."""
    left = np.floor(positions).astype(int)
    right = np.minimum(left + 1, values.shape[1] - 1)
    step = values[:, right] - values[:, left]
    if angle:
        step = (step + math.pi) % (2 * math.pi) - math.pi
    fraction = (positions - left).reshape((1, -1) + (1,) * (values.ndim - 2))
    interpolated: FloatArray = values[:, left] + fraction * step
    return interpolated


class StrideCurve(NamedTuple):
    """Runs to draw stride by stride: their windows, the windows' middle times, the style."""

    paths: Paths
    starts: IntArray
    ends: FloatArray
    middle_s: FloatArray
    style: dict[str, Any]


def stride_curves(report: DiagnosisReport, measured: Paths, extended: str
                  ) -> tuple[StrideCurve, ...]:
    """
    Return the data and both models' runs, each with the stride windows it is read over.

    Each model's runs are read over its own strides (`stride_windows`), the data over the
    extended model's (the strides it reads in the data); a figure of several panels draws
    them all from one simulation of each model.
    """
    curves = []
    for paths, model, style in (
            (measured, report.extended_model,
             {'color': 'k', 'lw': 1.5, 'label': 'measured runs'}),
            (_simulate(report.baseline_model, measured, MODEL_RUNS), report.baseline_model,
             {'color': 'tab:blue', 'lw': 2, 'label': 'baseline (paper model)'}),
            (_simulate(report.extended_model, measured, MODEL_RUNS), report.extended_model,
             {'color': 'tab:orange', 'ls': '--', 'lw': 2, 'label': extended})):
        starts, ends = stride_windows(model, measured.t)
        middle = measured.t[starts] + 0.5 * _span_s(measured, starts, ends)
        curves.append(StrideCurve(paths, starts, ends, middle, style))
    return tuple(curves)


def _over_the_run(ax: Axes, curves: tuple[StrideCurve, ...],
                  per_stride: Callable[[Paths, IntArray, FloatArray], FloatArray]) -> None:
    """Plot `per_stride` (runs, window starts, window ends) of each curve against time."""
    for curve in curves:
        ax.plot(curve.middle_s, per_stride(curve.paths, curve.starts, curve.ends), **curve.style)
    ax.set_xlabel('time in the run [s] (the middle of a stride)')


def _span_s(paths: Paths, starts: IntArray, ends: FloatArray) -> FloatArray:
    """Return each window's duration, s (its end a fractional sample on the runs' times)."""
    span: FloatArray = np.interp(ends, np.arange(len(paths.t)), paths.t) - paths.t[starts]
    return span


def _mean_speed(paths: Paths, starts: IntArray, ends: FloatArray) -> FloatArray:
    """Return the mean over runs of the speed over each stride window, cm/s."""
    covered = np.linalg.norm(_at(paths.positions, ends) - paths.positions[:, starts], axis=-1)
    with np.errstate(invalid='ignore'):
        speed_cm_s: FloatArray = np.nanmean(covered, axis=0) / _span_s(paths, starts,
                                                                       ends) * 100
    return speed_cm_s


def _mean_rate(paths: Paths, starts: IntArray, ends: FloatArray) -> FloatArray:
    """Return the mean over runs of the heading rate over each stride window, deg/s."""
    heading = paths.poses[:, :, 2]
    turned = (_at(heading, ends, angle=True) - heading[:, starts] + math.pi) % (
        2 * math.pi) - math.pi
    with np.errstate(invalid='ignore'):
        rate_deg_s: FloatArray = np.nanmean(turned, axis=0) / _span_s(paths, starts,
                                                                      ends) * DEG
    return rate_deg_s


def _turned(paths: Paths, starts: IntArray, ends: FloatArray) -> FloatArray:
    """
    Return each run's mean heading over each window less that over the first, deg.

    An average over a whole stride leaves out the sway within it, which a heading read at
    one instant would carry (the start's too: where in its sway a run starts): (runs,
    windows), NaN past a run's end.
    """
    heading = np.unwrap(paths.poses[:, :, 2], axis=1)
    heading -= heading[:, :1]                                # numbers of order one to sum
    total = np.zeros((heading.shape[0], heading.shape[1] + 1))
    np.cumsum(heading, axis=1, out=total[:, 1:])            # total[:, k]: samples before k
    with np.errstate(invalid='ignore'):
        mean = (_at(total, ends) - total[:, starts]) / (ends - starts)
    turned_deg: FloatArray = (mean - mean[:, :1]) * DEG
    return turned_deg


def _mean_turn(paths: Paths, starts: IntArray, ends: FloatArray) -> FloatArray:
    """Return the mean over runs of the heading change since the first stride, deg."""
    with np.errstate(invalid='ignore'):
        mean_deg: FloatArray = np.nanmean(_turned(paths, starts, ends), axis=0)
    return mean_deg


def _turn_spread(paths: Paths, starts: IntArray, ends: FloatArray) -> FloatArray:
    """Return the spread across runs of the heading change since the first stride, deg."""
    with np.errstate(invalid='ignore'):
        spread_deg: FloatArray = np.nanstd(_turned(paths, starts, ends), axis=0, ddof=1)
    return spread_deg


SPEED_LABEL = 'mean speed over a stride [cm/s]'
RATE_LABEL = 'mean heading rate over a stride [deg/s] (left positive)'


def _speed_panel(ax: Axes, report: DiagnosisReport, measured: Paths,
                 extension: NamedExtension) -> None:
    _over_the_run(ax, stride_curves(report, measured, 'extended model'), _mean_speed)
    ax.axvline(float(extension.parameters['time_s']), color='tab:red', ls=':',
               label='fitted change')
    ax.set_ylabel(SPEED_LABEL)


def _turn_panel(ax: Axes, report: DiagnosisReport, measured: Paths,
                extension: NamedExtension) -> None:
    _over_the_run(ax, stride_curves(report, measured, 'extended model (yaw rate ramp)'),
                  _mean_rate)
    ax.set_ylabel(RATE_LABEL)


def _misfit_plot(report: DiagnosisReport, measured: Paths, path: Path) -> bool:
    """
    Where an extended model that is not adequate misses, over the run: data beside both models.

    An effect that no cause or family describes shows here before it has a name: a speed
    that swings within the runs, a turn that grows or reverses, runs that wander apart faster
    than the model's spread lets them (what summary.md's "Where to look" reads in numbers).
    """
    if report.adequate or report.misfit is None:
        return False
    panels = (('the speed', _mean_speed, SPEED_LABEL),
              ('the turn', _mean_turn, 'mean heading change since the first stride [deg]\n'
               "(each a stride's mean; left positive)"),
              ('how far runs turn apart', _turn_spread,
               'spread across runs of the heading change\nsince the first stride [deg] '
               "(each a stride's mean)"))
    curves = stride_curves(report, measured, 'extended model')      # one simulation each
    fig, axes = plt.subplots(1, len(panels), figsize=(6.5 * len(panels), 4.8))
    for ax, (title, per_stride, label) in zip(axes, panels):
        _over_the_run(ax, curves, per_stride)
        ax.set_title(title, fontsize=10)
        ax.set_ylabel(label)
        ax.legend(fontsize=8)
    fig.suptitle('Where the extended model still misses, over the run (it is not adequate): '
                 'a pattern in the data that neither model draws')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return True


def _groups_panel(ax: Axes, report: DiagnosisReport, measured: Paths,
                  extension: NamedExtension) -> None:
    column = INDEX['heading_rate']
    data = _features_of(report, measured, None)[:, column] * DEG
    base = _features_of(report, _simulate(report.baseline_model, measured, MODEL_RUNS),
                        None)[:, column] * DEG
    extended = _features_of(report, _simulate(report.extended_model, measured, MODEL_RUNS),
                            None)[:, column] * DEG
    bins = _bins(data, base, extended)
    ax.hist(data, bins=bins, density=True, alpha=0.45, color='k', label='measured runs')
    ax.hist(base, bins=bins, density=True, histtype='step', lw=2, color='tab:blue',
            label='baseline (paper model)')
    ax.hist(extended, bins=bins, density=True, histtype='step', lw=2, color='tab:orange',
            ls='--', label='extended model (two groups)')
    ax.set_xlabel('heading rate over the run [deg/s]')
    ax.set_ylabel('density [1 / (deg/s)]')
