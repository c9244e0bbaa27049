"""Warm job servers for the batch: long-lived processes kept by each Dask worker (one per job it runs at once), with
heatparam and its libraries imported, each forking one child process per mesh.

Why: each mesh runs in a process of its own, so that it can be held to a time and a memory limit and a crash loses
that mesh alone; but a fresh Python process pays about half a second of start and imports, more than the whole work
of a small mesh. A fork of a process that has already imported everything costs milliseconds. The server only
imports, and loads numba's compiled loops (``heatparam.compiled.warm_all``: they start no thread pool): it never
computes with the numerical libraries, because a library's thread pool (OpenMP, MKL) is not safe to fork once
started.

Protocol (text lines over the server's stdin / stdout): ``import <modules>`` asks the server to import what a job
needs beyond :data:`PRELOAD` (answer ``imported``); ``job <folder>`` forks a child that runs the job on that folder
with its output in ``folder/log.txt``, answered by ``pid <pid>`` and, when the child has ended, ``exit <code>`` (a
negative code: the signal that ended it). The server exits at the end of its
stdin, or with the worker (``PR_SET_PDEATHSIG``), and its children with it.
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib
import os
import select
import signal
import subprocess
import sys
import threading
import traceback
from collections.abc import Callable

from heatparam import compiled

#: Imported by every server before it says ready: what every job needs (the pipeline, its solvers, the readers).
#: What only some jobs need (a format's library, the preview's pyplot) a job asks for (:meth:`JobServer.start`),
#: once per server, so that a batch of plain meshes does not wait for them.
PRELOAD = ("heatparam.unwrap", "heatparam.pipeline", "heatparam.pipeline.atlas_stage", "heatparam.formats.exporters",
           "heatparam.formats.dxf", "heatparam.formats.svg", "heatparam.formats.preview", "heatparam.formats.readers",
           "heatparam.formats.outputs", "heatparam.refine", "heatparam.fill", "heatparam.heat", "scipy.sparse.linalg",
           "scipy.spatial", "igl", "gpytoolbox", "cholespy", "pypardiso", "matplotlib.path", "meshio")


def die_with_parent() -> None:  # pragma: no cover - runs in a child process
    """Linux: this process gets SIGKILL when the thread that started it dies (elsewhere: nothing)."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(Exception):
            ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG = 1


def serve(job: Callable[[str], None]) -> None:  # pragma: no cover - the server process's main loop
    """The server's loop (module docstring): preload, say ``ready``, then fork ``job(folder)`` for each line."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the children and the batch, not the server
    os.environ.setdefault("MPLBACKEND", "Agg")
    _import(PRELOAD)
    with contextlib.suppress(Exception):  # (a loop that will not compile fails in the job, with its message)
        compiled.warm_all()  # numba's loops, compiled, no thread pool started: children inherit them
    _say("ready")
    while line := sys.stdin.readline():
        if line.startswith("import "):  # modules a job asks for, imported here once rather than in each child
            _import(line.split()[1:])
            _say("imported")
            continue
        pid = os.fork()
        if pid == 0:
            _child(job, line.rstrip("\n").removeprefix("job "))
        _say(f"pid {pid}")
        _, status = os.waitpid(pid, 0)
        _say(f"exit {os.waitstatus_to_exitcode(status)}")


def _import(names) -> None:  # pragma: no cover - server side
    for name in names:
        with contextlib.suppress(Exception):  # a module that will not import fails in the job, with its message
            importlib.import_module(name)


def _say(line: str) -> None:  # pragma: no cover - server side
    sys.stdout.write(line + "\n")
    sys.stdout.flush()


def _child(job: Callable[[str], None], folder: str) -> None:  # pragma: no cover - runs in the forked child
    """Run ``job(folder)`` with stdin from /dev/null and stdout / stderr into ``folder/log.txt``; never returns."""
    code = 1
    try:
        die_with_parent()
        signal.signal(signal.SIGINT, signal.default_int_handler)
        log = os.open(os.path.join(folder, "log.txt"), os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
        os.dup2(log, 1)
        os.dup2(log, 2)
        job(folder)
        code = 0
    except BaseException:
        traceback.print_exc()
    finally:
        with contextlib.suppress(Exception):
            sys.stdout.flush()
            sys.stderr.flush()
        os._exit(code)


class ServerPool:
    """The warm job servers of one worker process: one per job running at the same time (per worker thread),
    each handed back after its job and kept for the next.

    Parameters
    ----------
    command : the servers' command line (:class:`JobServer`).
    """

    def __init__(self, command: list[str]):
        self.command = command
        self._idle: list[JobServer] = []
        self._lock = threading.Lock()

    def prestart(self) -> None:
        """Start a server now (it imports while the batch is set up), for the first job to take."""
        with self._lock:
            self._idle.append(JobServer(self.command))

    def take(self) -> JobServer:
        """An idle server that is still alive, or a new one."""
        with self._lock:
            while self._idle:
                server = self._idle.pop()
                if server.alive():
                    return server
        return JobServer(self.command)

    def give_back(self, server: JobServer) -> None:
        with self._lock:
            self._idle.append(server)


class JobServer:
    """The worker's side of one server: start it, hand it a job, learn when the job has ended.

    Parameters
    ----------
    command : the server's command line (a Python process whose main loop is :func:`serve`). The server starts
        importing at once; the first job waits until it is ready.
    """

    def __init__(self, command: list[str]):
        self.proc = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, preexec_fn=die_with_parent)
        self._buffer = b""
        self._ready = False
        self._imported: set[str] = set()

    def alive(self) -> bool:
        return self.proc.poll() is None

    def start(self, folder: str, modules: tuple[str, ...] = ()) -> int:
        """Fork a job on ``folder``, the ``modules`` it needs imported in the server first; returns its process id."""
        if not self._ready:
            if self._line(timeout=120) != "ready":
                self.close()
                raise OSError("the job server did not start")
            self._ready = True
        wanted = [m for m in modules if m not in self._imported]
        if wanted:
            self._send("import " + " ".join(wanted))
            if self._line(timeout=120) != "imported":
                raise OSError("the job server stopped")
            self._imported.update(wanted)
        self._send("job " + folder)
        answer = self._line(timeout=60)
        if not answer or not answer.startswith("pid "):
            raise OSError("the job server stopped")
        return int(answer.split()[1])

    def _send(self, line: str) -> None:
        self.proc.stdin.write(line.encode() + b"\n")
        self.proc.stdin.flush()

    def ended(self, timeout: float | None) -> int | None:
        """The running job's exit code once it has ended (waiting up to ``timeout`` seconds, None: until then);
        None while it runs."""
        answer = self._line(timeout)
        if answer is None:
            return None
        if not answer.startswith("exit "):
            raise OSError("the job server stopped")
        return int(answer.split()[1])

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.proc.stdin.close()
        with contextlib.suppress(Exception):
            self.proc.kill()
            self.proc.wait(timeout=10)

    def _line(self, timeout: float | None) -> str | None:
        """The next line from the server: None when none came within ``timeout``, "" when the server is gone.
        Read from the raw pipe (a buffered reader could hold a line that ``select`` then never reports)."""
        fd = self.proc.stdout.fileno()
        while b"\n" not in self._buffer:
            if not select.select([fd], [], [], timeout)[0]:
                return None
            chunk = os.read(fd, 4096)
            if not chunk:
                return ""
            self._buffer += chunk
        line, self._buffer = self._buffer.split(b"\n", 1)
        return line.decode()
