"""Numba-compiled loops, compiled (or loaded from numba's on-disk cache) at their first call.

Importing numba costs 0.1-0.5 s, which only the runs that use a compiled loop should pay; a loop that calls other
compiled loops names them (``calls``) and they are compiled first and handed to it under their own names.
"""

from __future__ import annotations

import types

__all__ = ["COMPILED_MIN_FACES", "Compiled", "compiled", "pending", "warm_all", "warmup"]

#: From this many faces a mesh's per-face and per-corner loops run compiled (``refine.energy``,
#: ``mesh.topology``): at 235k faces numpy's batched (2,3) @ (3,2) products took 33 ms against the loop's 2.3 ms.
#: Below it, numba's import and cache load (0.1-0.5 s, once per process) would not pay off.
COMPILED_MIN_FACES = 20_000

#: each module's warm-up (its compiled loops run once on tiny inputs), registered at the module's import
_WARMUPS: list = []
#: every compiled loop of the modules imported so far
_LOOPS: list = []


class Compiled:
    """``fn`` compiled with ``numba.njit(cache=True, **options)`` at its first call; ``calls``: the compiled functions
    it calls."""

    def __init__(self, fn, calls: tuple[Compiled, ...] = (), options: dict | None = None):
        self.fn, self.calls, self.options, self._compiled = fn, calls, dict(options or {}), None
        _LOOPS.append(self)

    @property
    def ready(self) -> bool:
        """Whether the loop has been compiled (or loaded from the cache) for a call."""
        return self._compiled is not None and bool(self._compiled.signatures)

    def dispatcher(self):
        """The numba dispatcher (compiled, or loaded from the cache, now if not yet)."""
        if self._compiled is None:
            from numba import njit

            fn = self.fn
            if self.calls:  # numba reads the callees from the function's globals: the compiled ones there
                env = {**fn.__globals__, **{c.fn.__name__: c.dispatcher() for c in self.calls}}
                fn = types.FunctionType(fn.__code__, env, fn.__name__, fn.__defaults__, fn.__closure__)
            self._compiled = njit(cache=True, **self.options)(fn)
        return self._compiled

    def __call__(self, *args):
        return self.dispatcher()(*args)


def compiled(*calls: Compiled, **options):
    """Decorator: ``@compiled()`` or ``@compiled(callee, ..., option=value)`` makes a :class:`Compiled` (``options``:
    numba's, e.g. ``error_model="numpy"``)."""
    return lambda fn: Compiled(fn, calls, options)


def warmup(fn):
    """Decorator: ``fn()`` runs a module's compiled loops once on tiny inputs; :func:`warm_all` calls it."""
    _WARMUPS.append(fn)
    return fn


def warm_all() -> None:
    """Compile, or load from numba's cache, every compiled loop of the modules imported so far: a process that
    forks one child per mesh (the batch's job servers) does it once, so that each child does not (0.3-0.5 s each)."""
    for fn in _WARMUPS:
        fn()


def pending() -> list[str]:
    """The compiled loops of the modules imported so far that Python calls (not only other loops) and that are not
    yet compiled for a call, as ``module.name`` (a callee is compiled into its caller)."""
    callees = {id(c) for loop in _LOOPS for c in loop.calls}
    return [f"{c.fn.__module__}.{c.fn.__name__}" for c in _LOOPS if id(c) not in callees and not c.ready]
