"""Stage timing and progress display (tqdm on stderr), silenced by ``quiet``."""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager

from tqdm import tqdm


class Progress:
    """Records per-stage wall time into ``timings`` and shows progress bars when ``enabled``."""

    def __init__(self, enabled: bool = False):
        self.enabled = enabled
        self.timings: dict[str, float] = {}

    @contextmanager
    def stage(self, name: str):
        """Time a stage (accumulates if the same stage runs twice)."""
        if self.enabled:
            print(f"heatparam: {name} ...", file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.timings[name] = round(self.timings.get(name, 0.0) + time.perf_counter() - t0, 4)

    def bar(self, total: int | None, desc: str, unit: str = "it") -> tqdm:
        """A progress bar over ``total`` units (None: open-ended counter); shown only after a second and when
        enabled."""
        return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, disable=not self.enabled,
                    mininterval=0.5, delay=1.0, leave=False)

    def warn(self, message: str) -> None:
        if self.enabled:
            print(f"heatparam: warning: {message}", file=sys.stderr, flush=True)
