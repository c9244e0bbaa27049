"""Memory guard: check that a large allocation fits before making it (never be OOM-killed silently)."""

from __future__ import annotations

import psutil

from heatparam.errors import ResourceError

#: Fraction of the currently available memory that one stage may claim.
SAFETY_FRACTION = 0.6


def available_bytes() -> int:
    """Memory the process can still allocate without swapping, in bytes."""
    return int(psutil.virtual_memory().available)


def require(nbytes: float, what: str, hint: str) -> None:
    """Raise :class:`ResourceError` if ``nbytes`` would not fit in memory.

    Parameters
    ----------
    nbytes : bytes the caller is about to allocate (all buffers of the stage together).
    what : what the allocation is, for the message (e.g. "all-pairs distance matrix 90000 x 90000").
    hint : what the user can do instead (in API terms, e.g. "use geodesics='landmarks'"; the CLI shows flags).
    """
    avail = available_bytes()
    if nbytes > SAFETY_FRACTION * avail:
        raise ResourceError(
            f"{what} needs {nbytes / 2**30:.1f} GiB but only {avail / 2**30:.1f} GiB is available — {hint}"
        )


def peak_rss_bytes() -> int:
    """Peak resident set size of this process so far (Linux/macOS), in bytes."""
    import resource
    import sys

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(peak if sys.platform == "darwin" else peak * 1024)
