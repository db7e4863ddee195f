"""The diagnosis in pictures: paths against the confidence region (as the paper's Figs. 5b
and 6), E^_k over the (sigma1, sigma2) grid, the deciding statistic, the discrepancies."""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from octoroach_model.diagnosis.candidates import BY_CAUSE  # noqa: E402
from octoroach_model.diagnosis.features import INDEX, run_features  # noqa: E402
from octoroach_model.paths import Paths  # noqa: E402
from octoroach_model.validation.region import t_multiplier  # noqa: E402

N_SHOWN = 45


def write_plots(report: dict, measured: Paths, out: Path) -> dict[str, Path]:
    models = report.get('_models') or {}
    written = {}
    written['paths_plot'] = _paths_plot(report, measured, models, out / 'paths.png')
    if 'grid' in report.get('baseline', {}):
        written['violation_plot'] = _violation_plot(report, out / 'violation_grid.png')
    written['statistic_plot'] = _statistic_plot(report, measured, models,
                                                out / 'deciding_statistic.png')
    written['discrepancy_plot'] = _discrepancy_plot(report, out / 'discrepancies.png')
    return written


def _simulate(models: dict, name: str, measured: Paths, n: int) -> Paths | None:
    entry = models.get(name)
    if not entry:
        return None
    model, sigmas = entry
    return Paths(measured.t, model(sigmas, np.random.SeedSequence(7), n, measured.t))


def _paths_plot(report, measured, models, path: Path) -> Path:
    k = report.get('baseline', {}).get('k', 11) or 11
    centre = measured.positions.mean(axis=0) * 100
    half = t_multiplier(k, 0.95) * measured.positions.std(axis=0, ddof=1) * 100
    shown = np.random.default_rng(0).permutation(measured.n_paths)[:30]
    fig, axes = plt.subplots(1, 3, figsize=(15, 5.5))
    ax = axes[0]
    for i in shown:
        ax.plot(measured.poses[i, :, 0] * 100, measured.poses[i, :, 1] * 100, color='0.6', lw=0.7)
    ax.plot(centre[:, 0], centre[:, 1], 'r--', lw=2, label='data average')
    ax.set_title(f'30 of {measured.n_paths} measured runs (Fig. 5a)')
    for ax, name in zip(axes[1:], ('baseline', 'extended')):
        sim = _simulate(models, name, measured, N_SHOWN)
        ax.fill_betweenx(centre[:, 1], centre[:, 0] - half[:, 0], centre[:, 0] + half[:, 0],
                         color='tab:orange', alpha=0.25, label='95 % region of x (data)')
        if sim is not None:
            for run in sim.poses:
                ax.plot(run[:, 0] * 100, run[:, 1] * 100, color='tab:blue', lw=0.6, alpha=0.7)
        ax.plot(centre[:, 0], centre[:, 1], 'k', lw=2.5, label='data average')
        label = 'paper model' if name == 'baseline' else f'extended: {report["cause"]}'
        ax.set_title(f'{N_SHOWN} runs of the {label} (Fig. 6)')
    for ax in axes:
        ax.set_xlabel('x [cm]')
        ax.set_ylabel('y [cm]')
        ax.set_aspect('equal', adjustable='datalim')
        ax.legend(loc='lower right', fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _violation_plot(report, path: Path) -> Path:
    panels = [(n, report[n]) for n in ('baseline', 'extended') if 'grid' in report.get(n, {})]
    fig, axes = plt.subplots(1, len(panels), figsize=(6 * len(panels), 5), squeeze=False)
    for ax, (name, section) in zip(axes[0], panels):
        grid = section['grid']
        image = ax.pcolormesh(grid['sigma2'], grid['sigma1'], np.array(grid['violation']),
                              vmin=0, vmax=1, cmap='viridis', shading='nearest')
        ax.contour(grid['sigma2'], grid['sigma1'], np.array(grid['violation']),
                   levels=[section['rho']], colors='w', linewidths=1)
        ax.plot(section['sigma2'], section['sigma1'], 'r*', ms=16,
                label=f'chosen ({section["sigma1"]:.3f}, {section["sigma2"]:.3f}), '
                      f'E = {section["violation"]:.2f}')
        ax.set_xlabel('sigma2 [rad] (liftoff)')
        ax.set_ylabel('sigma1 [rad] (touchdown)')
        ax.set_title(f'E^_k, {name} model (rho = {section["rho"]})')
        ax.legend(loc='upper right', fontsize=8)
        fig.colorbar(image, ax=ax)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


FEATURE_OF = {'initial_pose_error': 'start_heading', 'measurement_noise': 'log_jitter',
              'gait_frequency_variation': 'stride_frequency', 'speed_decay': 'progress_ratio',
              'lateral_slip': 'slip_angle', 'persistent_turning': 'heading_rate'}


def _statistic_plot(report, measured, models, path: Path) -> Path:
    best = max(report['candidates'], key=lambda c: c['gain'])
    cause = report['cause'] if report['cause'] != 'none' else best['cause']
    feature = FEATURE_OF[cause]
    frequency = report['nominal']['stride_frequency_hz']
    heading = math.radians(report['nominal']['start_pose']['heading_deg'])
    fig, ax = plt.subplots(figsize=(7, 4.5))
    data = run_features(measured, frequency, heading)[:, INDEX[feature]]
    bins = np.histogram_bin_edges(data, bins=30)
    ax.hist(data, bins=bins, density=True, alpha=0.5, color='k', label='measured')
    for name, colour in (('baseline', 'tab:blue'), ('extended', 'tab:orange')):
        sim = _simulate(models, name, measured, 1000)
        if sim is not None:
            values = run_features(sim, frequency, heading)[:, INDEX[feature]]
            ax.hist(values, bins=np.histogram_bin_edges(np.concatenate([values, data]), 40),
                    density=True, histtype='step', lw=2, color=colour, label=f'{name} model')
    ax.set_xlabel(f'{feature} ({BY_CAUSE[cause].statistic_name})')
    ax.set_ylabel('density')
    ax.set_title(f'Deciding statistic for {cause}')
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _discrepancy_plot(report, path: Path) -> Path:
    rows = report['discrepancies']
    fig, ax = plt.subplots(figsize=(8, 0.4 * len(rows) + 1.5))
    z = np.clip([row['z'] for row in rows], -50, 50)
    ax.barh([row['statistic'] for row in rows], z,
            color=['tab:red' if abs(v) >= 3 else 'tab:gray' for v in z])
    ax.axvline(-3, color='k', ls=':')
    ax.axvline(3, color='k', ls=':')
    ax.invert_yaxis()
    ax.set_xlabel('z = (data - baseline model) / standard error (clipped at 50)')
    ax.set_title('Where the paper model disagrees with the data')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
