"""Numba-compiled loops, compiled (or loaded from numba's on-disk cache) at their first call.

Importing numba costs 0.1-0.5 s, which only the runs that use a compiled loop should pay; a loop that calls other
compiled loops names them (``calls``) and they are compiled first and handed to it under their own names.
"""

from __future__ import annotations

import types

__all__ = ["Compiled", "compiled"]


class Compiled:
    """``fn`` compiled with ``numba.njit(cache=True)`` at its first call; ``calls``: the compiled functions it calls."""

    def __init__(self, fn, calls: tuple[Compiled, ...] = ()):
        self.fn, self.calls, self._compiled = fn, calls, None

    def dispatcher(self):
        """The numba dispatcher (compiled, or loaded from the cache, now if not yet)."""
        if self._compiled is None:
            from numba import njit

            fn = self.fn
            if self.calls:  # numba reads the callees from the function's globals: the compiled ones there
                env = {**fn.__globals__, **{c.fn.__name__: c.dispatcher() for c in self.calls}}
                fn = types.FunctionType(fn.__code__, env, fn.__name__, fn.__defaults__, fn.__closure__)
            self._compiled = njit(cache=True)(fn)
        return self._compiled

    def __call__(self, *args):
        return self.dispatcher()(*args)


def compiled(*calls: Compiled):
    """Decorator: ``@compiled()`` or ``@compiled(callee, ...)`` makes a :class:`Compiled`."""
    return lambda fn: Compiled(fn, calls)
