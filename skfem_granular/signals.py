"""SIGINT and SIGTERM at any instant of a run's life: stop cleanly, never half way.

During a run's loop (:class:`StopSignals`, a context) the first SIGINT or SIGTERM
only sets :attr:`StopSignals.stopped_by`: the run stops at the end of the current
step, with a checkpoint. A second one, of either kind, stops it at once with
:class:`StopNow`: the history of the accepted steps and the summary are still
written, the last checkpoint stays as it was. Before and after a loop
(:func:`startup_signals`: reading the scene, meshing, between the runs of a
study) the first signal stops at once.

"At once" means the next instant at which stopping is safe. A handler never
raises inside a *deferred zone* (:func:`deferred`): numba compiling or loading
kernels (an exception raised inside its compiler crashed it or left it broken),
the output folder's lock being taken, a file being written. The signal is then
raised as :class:`StopNow` when the outermost zone closes, from ordinary code; inside
numba's compiler (its global compiler lock held: a kernel called the first time
with new argument types) and inside an import (raised there, numpy's C extension
turned it into an ImportError) the signal is sent again after :data:`RETRY_SECONDS`.
Every signal is also recorded, so that one whose exception was swallowed on its
way (a ``__del__``, a callback) is not lost: :class:`StopSignals` takes over a
signal that came before its loop and stops after the first step.

The command line installs :func:`startup_signals` before it imports the library's
heavy modules, so a signal during the imports is handled too; only the Python
interpreter's own start (before any of this code runs) leaves the signal its
default action (SIGTERM: the process ends with status 143 before it wrote anything).
The handlers that were installed before are restored when a context closes.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading

__all__ = ["STOP_SIGNALS", "StopNow", "StopSignals", "deferred", "startup_signals",
           "take_received"]

#: The signals that stop a run.
STOP_SIGNALS = ("SIGINT", "SIGTERM")

class _Zones:
    """How deep the deferred zones are nested now, how many of them discard a stop, and
    the signal they hold back."""

    depth = 0
    discard = 0
    pending: str | None = None


_zones = _Zones()
#: The last stop signal any handler saw and nobody has taken over yet.
_received: list[str] = []


class StopNow(BaseException):
    """A signal that stops a run at once (a second one during a run, any during start-up).

    A :class:`BaseException`, like :class:`KeyboardInterrupt`: ``except Exception``
    does not swallow it.

    Parameters
    ----------
    name : str
        ``"SIGINT"`` or ``"SIGTERM"``.
    """

    def __init__(self, name: str):
        super().__init__(name)
        self.name = name

    @property
    def exit_status(self) -> int:
        """``128 +`` the signal's number (130 for SIGINT, 143 for SIGTERM)."""
        return 128 + int(getattr(signal, self.name))


@contextlib.contextmanager
def deferred(raise_pending: bool = True):
    """A zone in which no signal handler raises; a stop that comes waits for its end.

    Parameters
    ----------
    raise_pending : bool, optional
        ``False``: a stop that came inside is not raised at the end either (the last
        writes of a run, after which it ends anyway).
    """
    _zones.depth += 1
    _zones.discard += not raise_pending
    try:
        yield
    finally:
        _zones.depth -= 1
        _zones.discard -= not raise_pending
    if not _zones.depth and _zones.pending is not None:
        name, _zones.pending = _zones.pending, None
        raise StopNow(name)


#: While numba compiles or loads a kernel a stop is tried again after this long (s).
RETRY_SECONDS = 0.02


def _numba_compiling() -> bool:
    """Whether this thread is inside numba's compiler (it holds the global compiler lock
    while it compiles a kernel or loads one from its cache)."""
    module = sys.modules.get("numba.core.compiler_lock")
    return module is not None and module.global_compiler_lock.is_locked()


#: The import system's own frames (a module being imported is executed below them).
_IMPORT_FILES = ("<frozen importlib._bootstrap>", "<frozen importlib._bootstrap_external>")


def _importing(frame) -> bool:
    """Whether ``frame`` (a handler's) runs inside an import: an exception raised there can
    surface as another error (numpy's C extension reports an ImportError of ``datetime``)."""
    while frame is not None:
        if frame.f_code.co_filename in _IMPORT_FILES:
            return True
        frame = frame.f_back
    return False


def _stop_now(name: str, frame=None) -> None:
    """Raise :class:`StopNow` from a handler, or hold it back: inside a deferred zone until
    the zone closes; inside numba's compiler or an import (``frame``, the interrupted
    one) by sending the signal again a moment later."""
    if _zones.depth:
        if not _zones.discard:
            _zones.pending = name
        return
    if _numba_compiling() or _importing(frame):
        again = threading.Timer(RETRY_SECONDS, os.kill, (os.getpid(), getattr(signal, name)))
        again.daemon = True
        again.start()
        return
    raise StopNow(name)


def take_received() -> str | None:
    """The stop signal a handler saw and no one has acted on (then forgotten), or None."""
    return _received.pop() if _received else None


def _say(text: str) -> None:
    try:
        os.write(2, text.encode())
    except OSError:
        pass


def _install(handler) -> dict:
    """Install ``handler`` for the stop signals (main thread, signals Python handles)."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    caught = {}
    for name in STOP_SIGNALS:
        sig = getattr(signal, name)
        prev = signal.getsignal(sig)
        if prev is None or prev == signal.SIG_IGN:  # not Python's, or ignored: left alone
            continue
        caught[sig] = prev
        signal.signal(sig, handler)
    return caught


def _restore(caught: dict, handler) -> None:
    for sig, prev in caught.items():
        if signal.getsignal(sig) == handler:  # a bound method: equal, not the same object
            signal.signal(sig, prev)


class StopSignals:
    """The stop signals while a run's loop is open (a context; see the module notes).

    Attributes
    ----------
    stopped_by : str or None
        The first signal's name, once one came (or the one that came before the loop).
    at_once : bool
        Whether a second signal stopped the run inside a step.
    """

    def __init__(self):
        self.stopped_by = None
        self.at_once = False
        self._caught = {}

    def _handle(self, signum, frame):
        name = signal.Signals(signum).name
        if self.stopped_by is None:
            self.stopped_by = name
            _say(f"\nskfem-granular: {name}: stopping at the end of this step "
                 "(again: stop at once)\n")
            return
        self.at_once = True
        _stop_now(name, frame)

    def critical(self, raise_pending: bool = True):
        """A file being written: a second signal waits until it is complete
        (a :func:`deferred` zone)."""
        return deferred(raise_pending)

    def __enter__(self):
        self._caught = _install(self._handle)
        came = take_received()
        if came is not None and self.stopped_by is None:
            self.stopped_by = came  # a signal before the loop: stop after the first step
        return self

    def __exit__(self, *exc):
        _restore(self._caught, self._handle)
        self._caught = {}
        return False


def _startup_handler(signum, frame):
    name = signal.Signals(signum).name
    _received[:] = [name]
    _stop_now(name, frame)


@contextlib.contextmanager
def startup_signals(ignore_after: bool = False):
    """SIGINT or SIGTERM stop at once while this context is open (:class:`StopNow`,
    held back inside :func:`deferred` zones).

    Parameters
    ----------
    ignore_after : bool, optional
        Ignore both signals once the context closes instead of restoring the
        previous handlers: for a process that then only exits, with an exit
        status already decided that a late signal must not change.
    """
    caught = _install(_startup_handler)
    try:
        yield
    finally:
        _received.clear()  # acted on, or the command has ended: not for a later run
        if ignore_after:
            for sig in caught:
                signal.signal(sig, signal.SIG_IGN)
        else:
            _restore(caught, _startup_handler)
