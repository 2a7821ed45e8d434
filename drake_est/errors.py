"""Exceptions with one-line, actionable messages.

Every error a user can cause by handing us bad input derives from
:class:`DrakeEstError`; the CLI prints ``str(err)`` on one line and exits 2.
"""


class DrakeEstError(ValueError):
    """Base class for user-facing errors (bad input, unidentifiable problems)."""


class DataError(DrakeEstError):
    """A log or data file is missing, malformed or physically implausible."""


class IdentifiabilityError(DrakeEstError):
    """The data do not excite the parameters the requested model needs."""
