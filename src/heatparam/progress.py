"""Stage timing and progress display on stderr, silenced by ``quiet``.

On a terminal every stage announces itself when it starts and long loops show tqdm bars. When stderr is not a
terminal (a log file, a pipe, CI) each stage prints one line when it ends, with its elapsed time, and there are
no bars: a log gets no carriage returns.

A stage that runs more than once says which time it is: its ``detail`` and the pass it runs in
(:meth:`Progress.in_pass`: the map without seams, then the one with seams) follow its name in brackets,
``refine (map with seams): 7.52 s``.
``timings`` stay keyed by the bare stage name (summed over passes), so the lines add up to their total.
"""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager

from tqdm import tqdm

from heatparam.options import to_cli_terms


def stderr_is_tty() -> bool:
    """Whether the current ``sys.stderr`` is a terminal (False for anything without a working ``isatty``)."""
    try:
        return bool(sys.stderr.isatty())
    except (AttributeError, ValueError, OSError):
        return False


class Progress:
    """Records per-stage wall time into ``timings`` and shows progress on stderr when ``enabled``.

    Parameters
    ----------
    enabled : show progress at all (``--quiet`` turns it off); timings are recorded either way.
    tty : force terminal (True) or log (False) output; None decides from ``sys.stderr`` at each stage.
    """

    def __init__(self, enabled: bool = False, tty: bool | None = None):
        self.enabled = enabled
        self.tty = tty
        self.timings: dict[str, float] = {}
        self.pass_name = ""

    def _tty(self) -> bool:
        return stderr_is_tty() if self.tty is None else self.tty

    @contextmanager
    def in_pass(self, name: str):
        """The stages run inside show ``name`` as their pass (``""``: none) in their lines."""
        outer, self.pass_name = self.pass_name, name
        try:
            yield
        finally:
            self.pass_name = outer

    @contextmanager
    def stage(self, name: str, detail: str = ""):
        """Time a stage (accumulates if the same stage runs twice). Terminal: a line when it starts; log: a line
        with its elapsed time when it ends (also when it fails). ``detail`` (and the pass) tell its runs apart."""
        tty = self._tty()
        label = ", ".join(x for x in (detail, self.pass_name) if x)
        shown = f"{name} ({label})" if label else name
        if self.enabled and tty:
            print(f"heatparam: {shown} ...", file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        try:
            yield
        finally:
            dt = time.perf_counter() - t0
            self.timings[name] = round(self.timings.get(name, 0.0) + dt, 4)
            if self.enabled and not tty:
                print(f"heatparam: {shown}: {dt:.2f} s", file=sys.stderr, flush=True)

    def bar(self, total: int | None, desc: str, unit: str = "it") -> tqdm:
        """A progress bar over ``total`` units (None: open-ended counter); shown only after a second, when
        enabled and on a terminal (elsewhere a disabled bar that accepts the same calls)."""
        return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, disable=not (self.enabled and self._tty()),
                    mininterval=0.5, delay=1.0, leave=False)

    def warn(self, message: str) -> None:
        if self.enabled:
            print_warning(message)


def print_warning(message: str) -> None:
    """A warning on the terminal, in command-line terms (``--seams none``; the report keeps the API's)."""
    print(f"heatparam: warning: {to_cli_terms(message)}", file=sys.stderr, flush=True)
