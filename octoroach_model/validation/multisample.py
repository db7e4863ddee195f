"""Multisamples (docs/validation.md): n mutually disjoint groups of k measured runs."""
from __future__ import annotations

import math

import numpy as np

from octoroach_model.arrays import IntArray
from octoroach_model.errors import DataError, ParameterError


def chernoff_sample_size(epsilon: float, delta: float) -> int:
    """Smallest n with n >= ln(2/delta) / (2 epsilon^2) (eq. 16, Hoeffding/Chernoff)."""
    if not (0 < epsilon < 1 and 0 < delta < 1):
        raise ParameterError(f'epsilon and delta must lie in (0, 1), got {epsilon}, {delta}')
    return math.ceil(math.log(2.0 / delta) / (2.0 * epsilon ** 2) - 1e-12)


def disjoint_multisamples(n_runs: int, n: int, k: int, rng: np.random.Generator) -> IntArray:
    """
    (n, k) run indices: a random grouping of distinct runs, no run in two groups.

    Returns
    -------
    array of int, shape (n, k)
        Run indices in 0..n_runs-1.

    """
    if k < 2:
        raise ParameterError(f'k must be at least 2 for a spread estimate, got {k}')
    needed = n * k
    if n_runs < needed:
        raise DataError(f'{n_runs} runs are too few: n x k = {n} x {k} needs {needed} runs '
                        f'(lower k, or raise epsilon/delta to lower n)')
    return rng.permutation(n_runs)[:needed].reshape(n, k)
