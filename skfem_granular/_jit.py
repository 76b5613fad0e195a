"""numba kernels compiled at their first call, cached on disk where that is possible.

``@lazy_njit`` marks a kernel; nothing of numba is imported until a marked
function of the module is first called. Then every marked function of that
module is replaced, in the module's namespace, by ``numba.njit(cache=True)`` of
it, so kernels that call each other through module globals are compiled
together (numba reads those globals when it compiles). Importing numba costs
~0.15-0.2 s and its first compiled call (the compiler's set-up, even when the
machine code comes from the cache) ~0.2-0.3 s more: a process that never calls
a kernel (``import skfem_granular``, ``skfem-granular scenes``, a run whose
scene needs none) pays neither.

The disk cache (``cache=True``) goes where numba puts it: ``NUMBA_CACHE_DIR``
if set, else ``__pycache__`` next to the source when that is writable (a
checkout, a user's virtual environment), else the user's cache directory
(``~/.cache/numba``). Where none of these can be written (a read-only
installation with a read-only home), numba refuses ``cache=True``; the kernels
are then compiled without the disk cache, in every process, instead of failing.

A first call, which compiles or loads the kernels, is a :func:`~skfem_granular.signals.deferred`
zone: a SIGINT or SIGTERM that stops a run at once waits until it is done (raised
inside numba's compiler it crashed or broke it).
"""

from __future__ import annotations

import functools
import sys

from .signals import deferred

__all__ = ["compile_module", "lazy_njit", "njit_cached"]

#: module name -> names of its marked kernels not compiled yet
_PENDING: dict[str, list[str]] = {}


def njit_cached(func):
    """``numba.njit(cache=True)(func)``, or ``numba.njit(func)`` where no cache can be written."""
    import numba

    try:
        return numba.njit(cache=True)(func)
    except RuntimeError as exc:  # numba: "cannot cache function ...: no locator available"
        if "no locator available" not in str(exc):
            raise
        return numba.njit(func)


def lazy_njit(func):
    """Mark ``func`` as a kernel compiled (with its module's others) at its first call."""
    module = func.__module__
    _PENDING.setdefault(module, []).append(func.__name__)

    @functools.wraps(func)
    def first_call(*args):
        with deferred():  # numba compiles or loads at this call: no signal raised inside
            compile_module(module)
            return getattr(sys.modules[module], func.__name__)(*args)

    first_call.py_func = func
    return first_call


def compile_module(module: str) -> None:
    """Replace the marked kernels of ``module`` by their numba versions (once)."""
    names = _PENDING.get(module)
    if not names:
        return
    namespace = sys.modules[module].__dict__
    with deferred():  # importing numba, building its dispatchers
        compiled = {name: njit_cached(namespace[name].py_func) for name in names}
        namespace.update(compiled)
        del _PENDING[module]
