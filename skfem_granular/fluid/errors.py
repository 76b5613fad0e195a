"""Exceptions raised by the fluid solvers."""


class ConvergenceError(RuntimeError):
    """A nonlinear or iterative linear solve did not converge.

    The message names the solver, the iterations done, the residual reached
    and what to try instead.
    """
