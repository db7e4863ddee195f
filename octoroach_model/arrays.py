"""
Array aliases for annotations: the dtype an array holds, said once.

A docstring states an array's shape and unit (numpydoc, as pysindy: ``x : FloatArray, shape
(n_runs, n_samples)``); the alias states its dtype, which mypy checks.
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.intp]
# a number or an array of them, broadcast against the other arguments
Floats = FloatArray | float
