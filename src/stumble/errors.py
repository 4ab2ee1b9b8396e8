"""Errors that reach the user as one line (the CLI prints ``stumble: <message>``)."""


class StumbleError(Exception):
    """A problem the user can fix; its message is one complete line naming the problem."""


class InputError(StumbleError, ValueError):
    """Bad input: a missing or corrupt file, an unknown name, a value out of range."""


class TripNotSet(InputError):
    """A trip that cannot be set at that instant: the tripped toe is already over the
    obstacle's height, or the obstacle would stand under the stance foot. Alone it is bad
    input; in a study it is an outcome of its own (``not set``: the foot passes over)."""
