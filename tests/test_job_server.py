"""The batch's warm job server: a fork per job, exit codes and signals reported, output into the job's log, the
server kept after a killed or crashed job, its children gone with it."""

from __future__ import annotations

import os
import signal
import sys
import time

import psutil
import pytest

from heatparam.job_server import JobServer, ServerPool

pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="the job server forks")

# a job by the folder's name: "ok" writes a file, "fail" raises, "crash" ends by SIGSEGV, "sleep" sleeps
JOB = """
import os, pathlib, signal, sys, time
from heatparam.job_server import serve

def job(folder):
    kind = pathlib.Path(folder).name
    print("started", kind, "in", os.getpid())
    if kind == "fail":
        raise ValueError("bad mesh")
    if kind == "crash":
        os.kill(os.getpid(), signal.SIGSEGV)
    if kind == "sleep":
        time.sleep(60)
    if kind == "modules":  # what the server had imported when it forked this job
        pathlib.Path(folder, "out.txt").write_text(str("tabnanny" in sys.modules))
        return
    pathlib.Path(folder, "out.txt").write_text(str(os.getppid()))

serve(job)
"""


@pytest.fixture
def server():
    s = JobServer([sys.executable, "-c", JOB])
    yield s
    s.close()


def _folder(tmp_path, kind):
    d = tmp_path / kind
    d.mkdir(exist_ok=True)
    return d


def test_jobs_report_their_exit(tmp_path, server):
    d = _folder(tmp_path, "ok")
    pid = server.start(str(d))
    assert server.ended(None) == 0
    assert (d / "out.txt").read_text() == str(server.proc.pid)  # forked by the server
    assert f"started ok in {pid}" in (d / "log.txt").read_text()
    d = _folder(tmp_path, "fail")
    server.start(str(d))
    assert server.ended(None) == 1
    assert "ValueError: bad mesh" in (d / "log.txt").read_text()
    server.start(str(_folder(tmp_path, "crash")))
    assert server.ended(None) == -signal.SIGSEGV
    server.start(str(_folder(tmp_path, "ok")))  # the server goes on after a failed and a crashed job
    assert server.ended(None) == 0 and server.alive()


def test_a_job_gets_the_modules_it_asks_for_imported_by_the_server(tmp_path, server):
    d = _folder(tmp_path, "modules")
    server.start(str(d))
    assert server.ended(None) == 0 and (d / "out.txt").read_text() == "False"
    server.start(str(d), ("tabnanny",))
    assert server.ended(None) == 0 and (d / "out.txt").read_text() == "True"
    server.start(str(d), ("tabnanny", "no_such_module_anywhere"))  # asked again: once per server; a bad one ignored
    assert server.ended(None) == 0 and server.alive()


def test_a_job_killed_from_outside(tmp_path, server):
    pid = server.start(str(_folder(tmp_path, "sleep")))
    assert server.ended(0.2) is None  # still running
    os.kill(pid, signal.SIGKILL)
    assert server.ended(None) == -signal.SIGKILL
    server.start(str(_folder(tmp_path, "ok")))
    assert server.ended(None) == 0


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_children_die_with_the_server(tmp_path, server):
    pid = server.start(str(_folder(tmp_path, "sleep")))
    server.proc.kill()
    deadline = time.time() + 10
    while psutil.pid_exists(pid) and psutil.Process(pid).status() != psutil.STATUS_ZOMBIE and time.time() < deadline:
        time.sleep(0.05)
    assert not psutil.pid_exists(pid) or psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    with pytest.raises(OSError, match="stopped"):
        server.ended(5)


def test_server_ends_with_its_input():
    s = JobServer([sys.executable, "-c", JOB])
    s.proc.stdin.close()
    assert s.proc.wait(timeout=10) == 0


def test_pool_keeps_servers_and_replaces_dead_ones(tmp_path):
    pool = ServerPool([sys.executable, "-c", JOB])
    pool.prestart()
    first = pool.take()
    first.start(str(_folder(tmp_path, "ok")))
    assert first.ended(None) == 0
    pool.give_back(first)
    assert pool.take() is first  # kept warm for the next job
    pool.give_back(first)
    first.proc.kill()
    first.proc.wait()
    second = pool.take()  # a dead server is not handed out
    assert second is not first
    second.start(str(_folder(tmp_path, "ok")))
    assert second.ended(None) == 0
    second.close()
