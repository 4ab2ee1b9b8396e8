"""Errors that reach the user as one line (the CLI prints ``stumble: <message>``)."""


class StumbleError(Exception):
    """A problem the user can fix; its message is one complete line naming the problem."""


class InputError(StumbleError, ValueError):
    """Bad input: a missing or corrupt file, an unknown name, a value out of range."""


class SimulationDiverged(StumbleError):
    """The physics blew up (NaN/Inf state or a MuJoCo instability warning)."""
