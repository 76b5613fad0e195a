"""SIGINT and SIGTERM during a run: stop at the end of the step, or at once on the second.

:class:`StopSignals` is a context: while it is open (in the main thread), the
first SIGINT or SIGTERM sets :attr:`StopSignals.stopped_by` and the run stops
at the end of the current step (with a checkpoint); a second one, of either
kind, raises :class:`StopNow` at once, so the run ends without finishing its
step: the history of the accepted steps and the summary are still written,
and the last checkpoint stays as it was. A second signal that comes while a
file is being written (:meth:`StopSignals.critical`: a checkpoint, a
history flush, a frame) waits until that file is complete. The handlers
that were installed before are restored when the context closes.

:func:`startup_signals` covers the time before a run's loop (reading the
scene, meshing): either signal raises :class:`StopNow`, which the command
line reports in one line with the exit status 128 + the signal's number.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading

#: The signals that stop a run.
STOP_SIGNALS = ("SIGINT", "SIGTERM")


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
        The first signal's name, once one came.
    at_once : bool
        Whether a second signal stopped the run inside a step.
    """

    def __init__(self):
        self.stopped_by = None
        self.at_once = False
        self._critical = 0
        self._pending = None
        self._caught = {}

    def _handle(self, signum, frame):
        name = signal.Signals(signum).name
        if self.stopped_by is None:
            self.stopped_by = name
            _say(f"\nskfem-granular: {name}: stopping at the end of this step "
                 "(again: stop at once)\n")
            return
        if self._critical:
            self._pending = name
            return
        self.at_once = True
        raise StopNow(name)

    @contextlib.contextmanager
    def critical(self, raise_pending: bool = True):
        """A file being written: a second signal waits until it is complete.

        ``raise_pending=False``: the signal is not raised afterwards either (the
        run's last writes, after which it ends anyway).
        """
        self._critical += 1
        try:
            yield
        finally:
            self._critical -= 1
        if raise_pending and not self._critical and self._pending is not None:
            name, self._pending = self._pending, None
            self.at_once = True
            raise StopNow(name)

    def __enter__(self):
        self._caught = _install(self._handle)
        return self

    def __exit__(self, *exc):
        _restore(self._caught, self._handle)
        self._caught = {}
        return False


@contextlib.contextmanager
def startup_signals(ignore_after: bool = False):
    """SIGINT or SIGTERM raise :class:`StopNow` while this context is open.

    Parameters
    ----------
    ignore_after : bool, optional
        Ignore both signals once the context closes instead of restoring the
        previous handlers: for a process that then only exits, with an exit
        status already decided that a late signal must not change.
    """
    def handler(signum, frame):
        raise StopNow(signal.Signals(signum).name)

    caught = _install(handler)
    try:
        yield
    finally:
        if ignore_after:
            for sig in caught:
                signal.signal(sig, signal.SIG_IGN)
        else:
            _restore(caught, handler)
