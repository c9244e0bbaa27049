"""Errors that carry a one-line, user-facing message (the CLI prints them and exits with code 2)."""


class HeatparamError(ValueError):
    """Bad input or an impossible request: the message says what is wrong and what to do."""


class MeshError(HeatparamError):
    """The mesh cannot be parameterized as given (format, geometry or topology)."""


class ResourceError(HeatparamError):
    """The request would not fit in the available memory."""
