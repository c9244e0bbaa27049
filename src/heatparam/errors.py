"""Errors that carry a one-line, user-facing message (the CLI prints them and exits with code 2)."""


class HeatparamError(ValueError):
    """Bad input or an impossible request: the message says what is wrong and what to do."""


class MeshError(HeatparamError):
    """The mesh cannot be parameterized as given (format, geometry or topology)."""


class TopologyError(MeshError):
    """The mesh is valid but not a single disk (closed, handles, nearly closed, several components, non-manifold or
    inconsistently oriented): ``heatparam.parameterize`` makes an atlas of it (``pipeline.atlas_stage``) instead.

    ``reason`` says what the mesh is (the atlas reports it), ``advice`` what a user of ``parameterize_disk`` can do;
    the message is both."""

    def __init__(self, reason: str, advice: str):
        super().__init__(f"{reason} — {advice}")
        self.reason, self.advice = reason, advice


class ResourceError(HeatparamError):
    """The request would not fit in the available memory."""
