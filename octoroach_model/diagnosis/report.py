"""Writing a diagnosis: report.json, summary.md in plain words, and the plots."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from octoroach_model.paths import Paths


def _plain(value):
    """JSON-ready copy: numpy scalars and arrays become Python numbers and lists."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items() if not str(k).startswith('_')}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(float(value)) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def summary_text(report: dict) -> str:
    """A short account in plain words: what is wrong, the cause, the evidence, the gain."""
    lines = ['# What the simulation gets wrong', '']
    top = [row for row in report['discrepancies'] if abs(row['z']) >= 3][:5]
    lines.append(f'{report["paths"]} measured runs of {report["duration_s"]:.2f} s were '
                 f'compared with the paper\'s model calibrated on '
                 f'{report["split"]["calibration"]} of them.')
    lines.append('')
    if top:
        lines.append('Largest disagreements (data against baseline model, z = difference in '
                     'standard errors):')
        for row in top:
            lines.append(f'- {row["statistic"]}: data {row["data"]:.4g} {row["unit"]}, model '
                         f'{row["model"]:.4g} {row["unit"]} (z = {row["z"]:+.1f})')
    else:
        lines.append('No statistic disagrees by more than 3 standard errors.')
    lines.append('')
    cause = report['cause']
    if cause == 'none':
        lines.append('**Cause: none.** No candidate extension describes the held-out runs '
                     'significantly better than the paper\'s model.')
    else:
        chosen = next(c for c in report['candidates'] if c['cause'] == cause)
        params = ', '.join(f'{k} = {v:.3g}' for k, v in report['parameters'].items())
        lines.append(f'**Cause: {cause}** ({params}).')
        lines.append(f'Evidence: with it, the held-out runs score {chosen["gain"]:.3g} nats per '
                     f'run better (one-sided paired t-test p = {chosen["p_value"]:.2g}, level '
                     f'{report["decision"]["per_candidate_level"]:.2g}); it was estimated from '
                     f'the statistic "{chosen["statistic"]}".')
    others = [c for c in report['candidates'] if c['cause'] != cause]
    lines.append('')
    lines.append('Other candidates: ' + '; '.join(
        f'{c["cause"]} gain {c["gain"]:.3g}, p = {c["p_value"]:.2g}' for c in others) + '.')
    gain = report['gain']
    lines.append('')
    lines.append(f'Gain: {gain["metric"]}: baseline {gain["baseline"]:.4g}, extended '
                 f'{gain["extended"]:.4g} (relative {gain["relative"]:+.1%}); energy score '
                 f'{gain["energy_score_cm"]["baseline"]:.4g} -> '
                 f'{gain["energy_score_cm"]["extended"]:.4g} cm.')
    base, ext = report.get('baseline', {}), report.get('extended', {})
    if 'violation' in base and 'violation' in ext:
        lines.append('')
        lines.append(f"Paper's validation (rho = {base['rho']}): baseline widest spread "
                     f"sigma1 = {base['sigma1']:.3f}, sigma2 = {base['sigma2']:.3f} rad at "
                     f"E_k = {base['violation']:.3f}; extended sigma1 = {ext['sigma1']:.3f}, "
                     f"sigma2 = {ext['sigma2']:.3f} rad at E_k = {ext['violation']:.3f}.")
    lines.append('')
    lines.append('Smallest effects this data could detect (5 % level, 80 % power): ' + '; '.join(
        f'{c["cause"]} {k} = {v:.3g}' if v is not None else f'{c["cause"]}: beyond the grid'
        for c in report['candidates'] for k, v in c['detectable'].items()) + '.')
    return '\n'.join(lines) + '\n'


def write_report(report: dict, out_dir: Path | str, measured: Paths | None = None,
                 plots: bool = True) -> dict[str, Path]:
    """Write report.json, summary.md and (with `measured`) the PNG plots into out_dir."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = {'report': out / 'report.json', 'summary': out / 'summary.md'}
    plain = _plain(report)
    written['report'].write_text(json.dumps(plain, indent=2) + '\n')
    written['summary'].write_text(summary_text(plain))
    if plots and measured is not None:
        from octoroach_model.diagnosis.plots import write_plots
        written.update(write_plots({**plain, '_models': report.get('_models')}, measured, out))
    return written
