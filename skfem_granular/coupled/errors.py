"""How a coupled run stops early."""


class SimulationError(RuntimeError):
    """A run stopped early; the history and the last good state were written."""
