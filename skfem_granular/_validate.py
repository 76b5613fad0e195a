"""Small input checks shared by the public entry points.

Every check raises :class:`ValueError` with one line that names the field and
the allowed range, so that bad input never surfaces as a traceback from deep
inside numpy or scipy.
"""

from __future__ import annotations

import math

import numpy as np


def positive(name: str, value, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a float, or raise if it is not finite and positive."""
    bound = ">= 0" if allow_zero else "> 0"
    if isinstance(value, bool):  # float(True) == 1.0: a boolean is a mistake, not a number
        raise ValueError(f"{name} = {value!r}: must be a finite number {bound}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r}: must be a finite number {bound}") from None
    if not math.isfinite(x) or x < 0 or (x == 0 and not allow_zero):
        raise ValueError(f"{name} = {value!r}: must be a finite number {bound}")
    return x


def finite_vector(name: str, value, size: int = 2) -> np.ndarray:
    """Return ``value`` as a finite float array of shape ``(size,)``."""
    try:
        x = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r}: must be {size} finite numbers") from None
    if x.shape != (size,) or not np.all(np.isfinite(x)):
        raise ValueError(f"{name} = {value!r}: must be {size} finite numbers")
    return x


def points_array(name: str, value) -> np.ndarray:
    """Return ``value`` as a finite ``(2, N)`` float array."""
    try:
        x = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be a (2, N) array of finite coordinates") from None
    if x.ndim == 1 and x.shape[0] == 2:
        x = x[:, None]
    if x.ndim != 2 or x.shape[0] != 2:
        raise ValueError(f"{name}: shape {x.shape} given, must be (2, N)")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name}: contains NaN or inf, coordinates must be finite")
    return x
