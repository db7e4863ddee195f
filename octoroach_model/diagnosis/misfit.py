"""
Where the extended model still misses: which runs, and which part of a run.

Where neither the table of causes nor the library of extensions explains the data, the report
says which statistics are off (discrepancies.py) and, here, where to look:

- **which runs**: every run's features scored under the extended model (the held-out log score
  of scoring.py, runs simulated at each run's length and place); the runs it predicts worst,
  numbered in recording order, and whether badly predicted runs gather at one end of the
  recording (Spearman's rank correlation of the score with the run's place, and its p-value);
- **which part of a run**: at each tenth of the run's duration, the position across and along
  the start heading and the heading change since the start: their mean over runs (with its
  standard error) and their spread across runs (with its bootstrap error), in the data and the
  model; for each statistic, the tenth and quantity where the two differ most, in standard
  errors. The mean points at what every run does and the model does not (a speed that swings
  over the run shows in the progress, a turn that grows in the heading change); the spread at
  what varies from run to run (a stand-in term that spreads the runs too much shows there).
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy import stats

from octoroach_model.arrays import FloatArray
from octoroach_model.diagnosis.scoring import feature_log_score
from octoroach_model.paths import Paths

WORST_RUNS = 5
PARTS = 10
PART_BOOTSTRAP = 60
DEG = 180.0 / math.pi
QUANTITIES = ('lateral position', 'progress', 'heading change')
UNITS = {'lateral position': 'cm', 'progress': 'cm', 'heading change': 'deg'}


@dataclass(frozen=True)
class RunMisfit:
    """A run the extended model predicts badly: its number in recording order, its score."""

    run: int
    log_score: float


@dataclass(frozen=True)
class PartMisfit:
    """Where data and model differ most: a quantity's mean or spread at a tenth of a run."""

    from_fraction: float
    to_fraction: float
    quantity: str
    statistic: str        # 'mean' over the runs or 'spread' across them
    unit: str
    data: float
    model: float
    z: float


@dataclass(frozen=True)
class Misfit:
    """Where the extended model misses (module docstring)."""

    worst_runs: tuple[RunMisfit, ...]
    median_log_score: float
    order_correlation: float          # Spearman's rho of the per-run score with run order
    order_p_value: float
    parts: tuple[PartMisfit, ...]      # per statistic where it differs most; largest |z| first

    def words(self) -> list[str]:
        """Return summary.md's lines on it."""
        runs = ', '.join(f'{entry.run} ({entry.log_score:.1f} nats)' for entry in self.worst_runs)
        lines = [f'- The runs it predicts worst (numbered in recording order; the median run '
                 f'scores {self.median_log_score:.1f} nats): {runs}.']
        if self.order_p_value < 0.01:
            where = 'late' if self.order_correlation < 0 else 'early'
            lines.append(f'- Badly predicted runs gather {where} in the recording (Spearman '
                         f'rho = {self.order_correlation:+.2f}, p = {self.order_p_value:.2g}): '
                         'look at what changed over the session.')
        else:
            lines.append(f'- Badly predicted runs do not gather at one end of the recording '
                         f'(Spearman rho = {self.order_correlation:+.2f}, p = '
                         f'{self.order_p_value:.2g}).')
        for part in self.parts:
            what = 'mean over the runs' if part.statistic == 'mean' else 'spread across runs'
            lines.append(f'- Within the runs, the {what} differs most in the {part.quantity}, '
                         f'from {100 * part.from_fraction:.0f} to '
                         f'{100 * part.to_fraction:.0f} % of the run: {part.data:.3g} '
                         f'{part.unit} in the data, {part.model:.3g} {part.unit} in the model '
                         f'(z = {part.z:+.1f}).')
        return lines


def locate(data: Paths, data_features: FloatArray, places: FloatArray, model: Paths,
           model_features: FloatArray, scales: FloatArray, by_position: bool,
           rng: np.random.Generator) -> Misfit:
    """
    Return where the model (its simulated runs and their features) misses the data.

    `places`: the data runs' places in the recording (0..1); `scales`: the features' spreads
    the scores are in (scoring.feature_scales).
    """
    scores = feature_log_score(model_features / scales, data_features / scales, by_position)
    order = np.rint(places * max(len(places) - 1, 1)).astype(int)
    worst = np.argsort(scores)[:WORST_RUNS]
    rho, p_value = stats.spearmanr(scores, places) if len(scores) > 2 else (0.0, 1.0)
    rho = float(rho) if np.isfinite(rho) else 0.0
    p_value = float(p_value) if np.isfinite(p_value) else 1.0
    return Misfit(tuple(RunMisfit(int(order[i]), float(scores[i])) for i in worst),
                  float(np.median(scores)), rho, p_value, where_in_a_run(data, model, rng))


def where_in_a_run(data: Paths, model: Paths, rng: np.random.Generator
                   ) -> tuple[PartMisfit, ...]:
    """Return per statistic the tenth and quantity where data and model differ most."""
    data_values, model_values = _at_parts(data), _at_parts(model)
    best: dict[str, PartMisfit] = {}
    for quantity in range(len(QUANTITIES)):
        for part in range(PARTS):
            ours, theirs = data_values[:, part, quantity], model_values[:, part, quantity]
            ours, theirs = ours[np.isfinite(ours)], theirs[np.isfinite(theirs)]
            if len(ours) < 3 or len(theirs) < 3:
                continue
            name = QUANTITIES[quantity]
            compared = {
                'mean': (float(np.mean(ours)), float(np.mean(theirs)), math.sqrt(
                    np.var(ours, ddof=1) / len(ours) + np.var(theirs, ddof=1) / len(theirs))),
                'spread': (float(np.std(ours, ddof=1)), float(np.std(theirs, ddof=1)),
                           math.hypot(_spread_se(ours, rng), _spread_se(theirs, rng)))}
            for statistic, (in_data, in_model, error) in compared.items():
                if error <= 0:
                    continue
                z = (in_data - in_model) / error
                if statistic not in best or abs(z) > abs(best[statistic].z):
                    best[statistic] = PartMisfit(part / PARTS, (part + 1) / PARTS, name,
                                                 statistic, UNITS[name], in_data, in_model,
                                                 float(z))
    return tuple(sorted(best.values(), key=lambda found: -abs(found.z)))


def _at_parts(paths: Paths) -> FloatArray:
    """
    Return (n, PARTS, 3): lateral position, progress [cm], heading change [deg] per tenth.

    At the end of each tenth of each run's own duration, relative to its start and its start
    heading.
    """
    lengths = paths.lengths
    rows = np.arange(paths.n_paths)
    start = paths.poses[:, 0]
    forward = np.stack([np.cos(start[:, 2]), np.sin(start[:, 2])], axis=-1)
    right = np.stack([forward[:, 1], -forward[:, 0]], axis=-1)
    out = np.full((paths.n_paths, PARTS, 3), np.nan)
    for part in range(PARTS):
        index = np.rint((part + 1) / PARTS * np.maximum(lengths - 1, 0)).astype(int)
        pose = paths.poses[rows, index]
        offset = pose[:, :2] - start[:, :2]
        out[:, part, 0] = np.einsum('ij,ij->i', offset, right) * 100
        out[:, part, 1] = np.einsum('ij,ij->i', offset, forward) * 100
        out[:, part, 2] = (pose[:, 2] - start[:, 2]) * DEG
    return out


def _spread_se(values: FloatArray, rng: np.random.Generator) -> float:
    picks = rng.integers(0, len(values), (PART_BOOTSTRAP, len(values)))
    return float(np.std(np.std(values[picks], axis=1, ddof=1), ddof=1))
