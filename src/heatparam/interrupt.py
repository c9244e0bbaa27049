"""Clean Ctrl-C at any moment: a SIGINT handler that raises ``KeyboardInterrupt`` *and* remembers it.

Some libraries swallow ``KeyboardInterrupt`` while they import (trimesh wraps optional imports in
``except BaseException``), so an interrupt in the first second could be lost and the run finish. The flag set here
survives that: :func:`check` re-raises it after such imports and before every output is renamed into place
(``io.atomic_write``), so an interrupted run writes nothing. While the outputs are being written (:func:`deferred`)
an interrupt waits until they are all complete; after that the run has nothing left to stop and an interrupt is
only noted. Without :func:`handling` or :func:`install` (library use) the flag is never set and :func:`check` does
nothing.
"""

from __future__ import annotations

import contextlib
import importlib
import signal
import threading

_interrupted = False
_quiet = False  # set while the outputs are written and after: the handler then only notes the interrupt


def _handler(signum, frame):  # noqa: ARG001 - the signal module's signature
    global _interrupted
    _interrupted = True
    if not _quiet and not _in_import_machinery(frame):
        raise KeyboardInterrupt


def _in_import_machinery(frame) -> bool:
    """Whether the signal arrived in importlib's own code (not a module being imported): there an exception from
    a weakref callback of its module locks is only printed, "Exception ignored in: <function
    _get_module_lock.<locals>.cb ...>" with a traceback, and the run goes on (1 in ~10 runs of
    ``test_ctrl_c_at_any_moment_is_clean`` with a Ctrl-C ~60 ms in). The interrupt is only noted there: the next
    :func:`check` raises it (after the imports, at the latest before any output is written)."""
    return frame is not None and frame.f_code.co_filename.startswith("<frozen importlib")


def interrupted() -> bool:
    """Whether SIGINT arrived since the handler was installed."""
    return _interrupted


def check() -> None:
    """Raise ``KeyboardInterrupt`` if SIGINT arrived, even if a library swallowed the exception it raised (not
    once the outputs are being written)."""
    if _interrupted and not _quiet:
        raise KeyboardInterrupt


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def install() -> None:
    """Install the handler for the rest of the process (the ``heatparam`` entry point; never restored)."""
    global _interrupted, _quiet
    if _main_thread():
        _interrupted = _quiet = False
        signal.signal(signal.SIGINT, _handler)


def finish() -> None:
    """The run is over (its outputs written or refused): from now on an interrupt is only noted."""
    global _quiet
    _quiet = True


@contextlib.contextmanager
def handling():
    """Install the handler for the duration (main thread only; inside :func:`install` or another ``handling`` the
    outer state is kept)."""
    global _interrupted, _quiet
    if not _main_thread():
        yield
        return
    previous = signal.getsignal(signal.SIGINT)
    outermost = previous is not _handler
    if outermost:
        _interrupted = _quiet = False
    signal.signal(signal.SIGINT, _handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if outermost:  # the run is over: an interrupt it noted must not stop later library use in this process
            _interrupted = _quiet = False


@contextlib.contextmanager
def deferred():
    """The writing of a run's outputs: an interrupt before it raises here (nothing written); one during it or after
    it is only noted (:func:`interrupted`), so a run leaves all its outputs or none. If the writing fails, the
    handler raises again."""
    global _quiet
    check()
    _quiet = True
    try:
        yield
    except BaseException:
        _quiet = False
        raise


@contextlib.contextmanager
def noted():
    """Imports of native extensions (libigl's nanobind module, OpenCascade): an interrupt while they run is only
    noted — raised inside their C++ code it aborts the process ("terminate called after throwing an instance of
    nanobind::python_error", with a traceback) — and raised once they are done."""
    global _quiet
    previous = _quiet
    _quiet = True
    try:
        yield
    finally:
        _quiet = previous
    check()


def guarded_import(name: str):
    """``importlib.import_module(name)``, re-raising an interrupt the imported package swallowed."""
    try:
        module = importlib.import_module(name)
    except BaseException:
        check()
        raise
    check()
    return module
