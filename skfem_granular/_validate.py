"""Small input checks shared by the public entry points.

Every check raises :class:`ValueError` with one line that names the field and
the allowed range, so that bad input never surfaces as a traceback from deep
inside numpy or scipy.
"""

from __future__ import annotations

import math

import numpy as np

#: Local worker processes a command may ask for (studies, collapses).
MAX_WORKERS = 1024
#: Seeds of random grain columns on the command line (numpy's 32-bit seed range).
MAX_SEED = 2**32 - 1


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


def in_range(name: str, value, lo=None, hi=None, *, integer: bool = False,
             open_lo: bool = False, open_hi: bool = False):
    """Return ``value`` if it lies in the range, or raise a one-line ``ValueError``.

    Parameters
    ----------
    name : str
        The field or option the message names (``"--fps"``).
    value : int or float
        The value given.
    lo, hi : float, optional
        The bounds (``None``: none on that side).
    integer : bool
        An integer is required (not a boolean); else a finite number.
    open_lo, open_hi : bool
        Leave the bound out of the range.

    Returns
    -------
    int or float
        ``value`` (an ``int`` or a ``float``).

    Examples
    --------
    >>> in_range("--fps", 200.0, 0.1, 100)
    Traceback (most recent call last):
    ...
    ValueError: --fps = 200.0: must be a finite number in [0.1, 100]
    """
    kind = "an integer" if integer else "a finite number"

    def fmt(bound) -> str:
        return str(int(bound)) if integer else f"{bound:g}"

    if lo is not None and hi is not None:
        rule = f"in {'(' if open_lo else '['}{fmt(lo)}, {fmt(hi)}{')' if open_hi else ']'}"
    elif lo is not None:
        rule = f"{'>' if open_lo else '>='} {fmt(lo)}"
    else:
        rule = f"{'<' if open_hi else '<='} {fmt(hi)}"
    message = f"{name} = {value!r}: must be {kind} {rule}"
    if isinstance(value, bool | np.bool_):
        raise ValueError(message)
    x: float
    if integer:
        if not isinstance(value, int | np.integer):
            raise ValueError(message)
        x = int(value)
    else:
        try:
            x = float(value)
        except (TypeError, ValueError):
            raise ValueError(message) from None
        if not math.isfinite(x):
            raise ValueError(message)
    if lo is not None and (x < lo or (open_lo and x == lo)):
        raise ValueError(message)
    if hi is not None and (x > hi or (open_hi and x == hi)):
        raise ValueError(message)
    return x
