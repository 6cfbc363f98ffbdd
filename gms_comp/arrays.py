"""The array types of gms-comp, named once: float64 samples and boolean masks."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
"""A float64 array (samples, parameters, states; SI units)."""

BoolArray = NDArray[np.bool_]
"""A boolean mask over samples."""

IntArray = NDArray[np.intp]
"""Indices of samples."""
