"""``heatparam batch``: a folder of ~20 meshes on a local Dask cluster and on a real scheduler started here,
resumability, a worker killed mid-run, task limits, discovery and usage errors."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import heatparam
from heatparam import datasets
from heatparam.batching import discover, run_batch
from heatparam.cli import main
from heatparam.options import Options, to_cli_terms
from heatparam.unwrap import unwrap_file

from conftest import shared_mesh

distributed = pytest.importorskip("distributed")


def _write_obj(path: Path, V: np.ndarray, F: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in V.tolist())
                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F.tolist()))


def _write_off(path: Path, V: np.ndarray, F: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"OFF\n{len(V)} {len(F)} 0\n" + "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in V.tolist())
                    + "".join(f"3 {a} {b} {c}\n" for a, b, c in F.tolist()))


def make_library(root: Path) -> dict[str, str]:
    """~20 meshes: generated shapes (coarse), three shared ones (cow.off is closed: an atlas), a malformed OBJ, and
    ``part.obj`` in two subfolders. Returns {path relative to root: expected status}."""
    gen = {
        "disk": lambda h: datasets.flat_disk(h=h), "square": lambda h: datasets.flat_square(h=h),
        "cylinder": lambda h: datasets.cylinder_patch(h=h), "cylholes": lambda h: datasets.cylinder_with_holes(h=h),
        "cone": lambda h: datasets.cone_s_strip(h=h / 2), "cap": lambda h: datasets.curved_cap_with_holes(h=h),
    }
    expect = {}
    for k, (name, make) in enumerate(gen.items()):
        for h in (0.15, 0.2):
            s = make(h)
            rel = f"generated/{name}_{int(h * 100)}.{'obj' if k % 2 else 'off'}"
            (_write_obj if k % 2 else _write_off)(root / rel, s.V, s.F)
            expect[rel] = "ok"
    big = datasets.scale_shape(datasets.cylinder_patch(h=0.15), 25.0)  # millimetres
    _write_obj(root / "generated/deep/cylinder_mm.obj", big.V, big.F)
    expect["generated/deep/cylinder_mm.obj"] = "ok"
    a, b = datasets.flat_disk(h=0.18), datasets.cylinder_with_holes(h=0.14)
    _write_obj(root / "a/part.obj", a.V, a.F)
    _write_obj(root / "b/part.obj", b.V, b.F)
    expect["a/part.obj"] = expect["b/part.obj"] = "ok"
    for name, status in (("halftunnel.off", "ok"), ("woody.obj", "ok"), ("cow.off", "ok")):
        (root / "shared").mkdir(exist_ok=True)
        (root / "shared" / name).write_bytes(shared_mesh(name).read_bytes())
        expect[f"shared/{name}"] = status
    (root / "bad").mkdir()
    (root / "bad" / "broken.obj").write_text("v 0 0 0\nv 1 0\nf 1 2 three\nthis is not a mesh\n")
    expect["bad/broken.obj"] = "refused"
    (root / "notes.txt").write_text("not a mesh: ignored by the folder search\n")
    return expect


def _obj_of(rel: str) -> str:
    return str(Path(rel).with_suffix(".obj"))


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    """The folder, and the bytes of ``heatparam unwrap``'s OBJ for each good mesh (the reference)."""
    root = tmp_path_factory.mktemp("lib") / "meshes"
    root.mkdir()
    expect = make_library(root)
    ref_dir = tmp_path_factory.mktemp("ref")
    refs = {}
    for rel, status in expect.items():
        if status == "ok":
            out = ref_dir / rel.replace("/", "__")
            out = out.with_suffix(".obj")
            assert main(["unwrap", str(root / rel), "-o", str(out), "--quiet"]) == 0
            refs[rel] = out.read_bytes()
    return root, expect, refs


def _rows(out: Path) -> dict[str, dict]:
    summary = json.loads((out / "summary.json").read_text())
    return {str(Path(r["input"]).resolve()): r for r in summary["rows"]}


def _check_outputs(root: Path, out: Path, expect: dict, refs: dict, statuses=("ok",)) -> dict[str, dict]:
    rows = _rows(out)
    assert len(rows) == len(expect)  # one row per input, nothing else (notes.txt is not a mesh)
    for rel, status in expect.items():
        r = rows[str((root / rel).resolve())]
        if status == "ok":
            assert r["status"] in statuses, (rel, r)
            assert (out / _obj_of(rel)).read_bytes() == refs[rel], rel  # bit for bit the unwrap output
            rep = json.loads((out / rel).with_suffix(".json").read_text())
            assert rep["batch"]["input"]["size"] == (root / rel).stat().st_size
            assert r["vertices"] == rep["mesh"]["vertices"] and r["charts"] == rep["metrics"].get("charts", 1)
            assert (r["charts"] > 1) == rel.endswith("cow.off")  # the closed cow is an atlas, the rest one piece
            assert r["iso_mean"] == rep["metrics"]["iso_mean"] and r["flips"] == 0 and r["crossings"] == 0
            assert r["warnings"] == " | ".join(to_cli_terms(w) for w in rep["warnings"])
            assert ("an atlas of" in r["warnings"]) == rel.endswith("cow.off")
        else:
            assert r["status"] == status and r["reason"] and "\n" not in r["reason"], (rel, r)
            assert not (out / _obj_of(rel)).exists()
    leftovers = [p for p in out.rglob("*") if p.name.startswith(".") or p.suffix == ".tmp"]
    assert leftovers == []  # no temporary folder or half-written file
    return rows


def test_local_cluster_equals_unwrap_and_resumes(library, tmp_path, capsys):
    root, expect, refs = library
    out = tmp_path / "out"
    code = main(["batch", str(root), "-o", str(out), "--workers", "2", "--quiet"])
    err = capsys.readouterr().err
    assert code == 1  # the malformed mesh is refused (the closed one becomes an atlas)
    rows = _check_outputs(root, out, expect, refs)
    assert "broken.obj" in err and "cow.off" not in err
    broken = rows[str((root / "bad/broken.obj").resolve())]
    assert broken["reason"].startswith("cannot read")
    assert int(rows[str((root / "shared/cow.off").resolve())]["charts"]) > 1
    # part.obj in a/ and b/: two outputs, no clash
    assert (out / "a/part.obj").read_bytes() != (out / "b/part.obj").read_bytes()
    csv_lines = (out / "summary.csv").read_text().splitlines()
    assert csv_lines[0].split(",")[:4] == ["input", "output", "status", "reason"]
    assert len(csv_lines) == 1 + len(expect)
    assert "<table>" in (out / "index.html").read_text()

    # a rerun runs nothing: good meshes are up to date, the refused ones unchanged (still exit 1)
    mtimes = {p: p.stat().st_mtime_ns for p in out.rglob("*.obj")}
    t = time.perf_counter()
    assert main(["batch", str(root), "-o", str(out), "--workers", "2"]) == 1
    assert time.perf_counter() - t < 10
    assert "of the meshes flattened have warnings: see the warnings column of" in capsys.readouterr().err
    rows = _check_outputs(root, out, expect, refs, statuses=("skipped",))
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*.obj")} == mtimes
    assert all(r["status"] in ("skipped", "refused") for r in rows.values())

    # touching one input redoes only that one
    touched = root / "generated/cone_15.off"
    st = touched.stat()
    os.utime(touched, ns=(st.st_atime_ns, st.st_mtime_ns + 2_000_000_000))
    assert main(["batch", str(root), "-o", str(out), "--workers", "2", "--quiet"]) == 1
    rows = _check_outputs(root, out, expect, refs, statuses=("ok", "skipped"))
    redone = [k for k, r in rows.items() if r["status"] == "ok"]
    assert redone == [str(touched.resolve())]
    assert (out / "generated/cone_15.obj").stat().st_mtime_ns > mtimes[out / "generated/cone_15.obj"]


@pytest.fixture
def dask_processes(tmp_path):
    """A ``dask scheduler`` and two ``dask worker`` processes on 127.0.0.1 (single-threaded), torn down after."""
    sched_file = tmp_path / "scheduler.json"
    env = {**os.environ, "DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "1"}
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                               "--port", "0", "--scheduler-file", str(sched_file), "--no-dashboard",
                               "--dashboard-address", "127.0.0.1:0"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)]
    try:
        deadline = time.time() + 60
        while not sched_file.exists() and time.time() < deadline:
            time.sleep(0.2)
        assert sched_file.exists(), "the scheduler did not start"
        for _ in range(2):
            procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file",
                                           str(sched_file), "--nthreads", "1", "--host", "127.0.0.1",
                                           "--no-dashboard", "--dashboard-address", "127.0.0.1:0"],
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env))
        with distributed.Client(scheduler_file=str(sched_file), timeout="30s") as c:
            c.wait_for_workers(2, timeout=90)
            assert all(a.startswith("tcp://127.0.0.1:") for a in c.scheduler_info()["workers"])
        yield sched_file
    finally:
        for p in reversed(procs):
            p.send_signal(signal.SIGINT)
        for p in reversed(procs):
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=10)


def test_real_scheduler(library, tmp_path, dask_processes, capsys):
    root, expect, refs = library
    out = tmp_path / "out"
    address = json.loads(dask_processes.read_text())["address"]
    assert main(["batch", str(root), "-o", str(out), "--scheduler", address, "--quiet"]) == 1
    _check_outputs(root, out, expect, refs)
    assert "broken.obj" in capsys.readouterr().err
    # the scheduler file works too, and the rerun skips everything
    assert main(["batch", str(root), "-o", str(out), "--scheduler", str(dask_processes), "--quiet"]) == 1
    _check_outputs(root, out, expect, refs, statuses=("skipped",))


@pytest.fixture(scope="module")
def cluster_client():
    import dask

    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
        cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                           silence_logs=50)
    client = distributed.Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def test_killed_worker_mid_run(library, tmp_path, cluster_client):
    """The test kills a worker process while it runs a mesh: the mesh is rerun on another worker, the summary is
    complete and no partial file is left."""
    root, expect, refs = library
    out = tmp_path / "out"
    result = {}

    def run():
        try:
            result["summary"] = run_batch([root], out, client=cluster_client)
        except BaseException as exc:  # pragma: no cover - reported below
            result["error"] = exc

    th = threading.Thread(target=run)
    th.start()
    pids = cluster_client.run(os.getpid)
    killed = None
    deadline = time.time() + 60
    while killed is None and time.time() < deadline and th.is_alive():
        busy = [w for w, keys in cluster_client.processing().items() if keys]
        if busy and out.exists() and any(out.rglob(".heatparam-tmp-*")):
            time.sleep(0.3)  # the subprocess is running its mesh
            killed = pids[busy[0]]
            os.kill(killed, signal.SIGKILL)
        time.sleep(0.05)
    th.join(timeout=240)
    assert not th.is_alive()
    assert "error" not in result, result.get("error")
    assert killed is not None, "no task was caught running"
    rows = _check_outputs(root, out, expect, refs)
    assert sum(r["status"] == "ok" for r in rows.values()) == sum(s == "ok" for s in expect.values())


def test_task_time_and_memory_limits(tmp_path, cluster_client):
    src = shared_mesh("woody.obj")
    big = datasets.cylinder_patch(h=0.012)  # ~40k faces: seconds of work, far past the limit
    _write_obj(tmp_path / "big.obj", big.V, big.F)
    s = heatparam.batch(tmp_path / "big.obj", tmp_path / "t", client=cluster_client, task_timeout=0.2)
    assert s["rows"][0]["status"] == "failed" and "timed out after 0.2 s" in s["rows"][0]["reason"]
    s = heatparam.batch([src], tmp_path / "m", client=cluster_client, task_memory="20MB")
    assert s["rows"][0]["status"] == "failed" and "memory limit" in s["rows"][0]["reason"]
    assert sorted(p.name for p in (tmp_path / "m").iterdir()) == ["index.html", "summary.csv", "summary.json"]
    s = heatparam.batch([src], tmp_path / "m", client=cluster_client, task_memory="4GB", task_timeout=120)
    assert s["rows"][0]["status"] == "ok" and s["rows"][0]["peak_mem_mb"] > 20
    assert s["counts"] == {"ok": 1, "refused": 0, "failed": 0, "skipped": 0}
    # other options: redone (the manifest's options hash differs); the same again: skipped; --force: redone
    s = heatparam.batch([src], tmp_path / "m", client=cluster_client, seams="none")
    assert s["rows"][0]["status"] == "ok" and s["options"]["seams"] == "none"
    assert heatparam.batch([src], tmp_path / "m", seams="none")["rows"][0]["status"] == "skipped"
    s = heatparam.batch([src], tmp_path / "m", client=cluster_client, seams="none", force=True)
    assert s["rows"][0]["status"] == "ok"


def test_discovery(tmp_path):
    d = datasets.flat_disk(h=0.3)
    for rel in ("x/part.obj", "x/part.off", "x/y/z.obj", "x/.hidden/h.obj", "x/readme.md", "w/part.obj"):
        (_write_off if rel.endswith(".off") else _write_obj)(tmp_path / rel, d.V, d.F)
    items = discover([tmp_path / "x"], tmp_path / "out")
    assert [(str(i.rel), i.stem) for i in items] == [(".", "part-obj"), (".", "part-off"), ("y", "z")]
    items = discover([str(tmp_path / "*" / "part.obj")], tmp_path / "out")
    assert [(str(i.rel), i.stem) for i in items] == [("w", "part"), ("x", "part")]
    items = discover([str(tmp_path / "x" / "**" / "*.obj")], tmp_path / "x" / "y")  # outputs never inputs
    assert [(str(i.rel), i.stem) for i in items] == [(".", "part")]
    with pytest.raises(heatparam.HeatparamError, match="would all be written"):
        discover([tmp_path / "x/part.obj", tmp_path / "w/part.obj"], tmp_path / "out")
    with pytest.raises(heatparam.HeatparamError, match="inside the output folder"):
        discover([tmp_path / "w"], tmp_path)


@pytest.mark.parametrize("args, message", [
    (["{root}/nope"], "no such file or folder"),
    (["{root}/empty"], "holds no mesh"),
    (["{root}/*.ply"], "no file matches"),
    (["{root}/w", "--format", "obj,gif"], "unknown format"),
    (["{root}/w", "--landmarks", "2"], "landmarks"),
])
def test_usage_errors_exit_2(tmp_path, capsys, args, message):
    d = datasets.flat_disk(h=0.3)
    _write_obj(tmp_path / "w/part.obj", d.V, d.F)
    (tmp_path / "empty").mkdir()
    code = main(["batch", *[a.format(root=tmp_path) for a in args], "-o", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and message in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_unavailable_format_is_a_usage_error(tmp_path, capsys, monkeypatch):
    import dataclasses

    from heatparam.formats import exporters

    missing = dataclasses.replace(exporters.BY_NAME["step"], requires="no_such_module_for_heatparam_tests")
    monkeypatch.setitem(exporters.BY_NAME, "step", missing)  # as if OCP were missing
    code = main(["batch", str(shared_mesh("woody.obj")), "-o", str(tmp_path / "out"), "--format", "obj,step"])
    assert code == 2 and "format step is not available" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_suffixes_and_formats_agree_with_formats_package():
    from heatparam import batching
    from heatparam.formats import MESH_SUFFIXES
    from heatparam.formats.exporters import batch_formats, map_formats

    assert batching.MESH_SUFFIXES == MESH_SUFFIXES
    assert set(batch_formats()) == set(map_formats()) | {"json"}  # every map format, and the report


def test_unwrap_file_is_the_unwrap_command(tmp_path):
    src = shared_mesh("woody.obj")
    assert main(["unwrap", str(src), "-o", str(tmp_path / "a.obj"), "--quiet", "--seed", "3"]) == 0
    r = unwrap_file(src, tmp_path / "b.obj", report=tmp_path / "b.json", options=Options(seed=3))
    assert (tmp_path / "a.obj").read_bytes() == (tmp_path / "b.obj").read_bytes()
    # the flat patterns too: a batch with --format obj,dxf,svg writes the unwrap command's bytes
    out = tmp_path / "out"
    assert main(["batch", str(src), "-o", str(out), "--format", "obj,dxf,svg", "--workers", "1", "--quiet",
                 "--seed", "3"]) == 0
    assert main(["unwrap", str(src), "-o", str(tmp_path / "c.dxf"), "-o", str(tmp_path / "c.svg"), "--quiet",
                 "--seed", "3"]) == 0
    for ext in ("obj", "dxf", "svg"):
        got = next(out.rglob(f"woody.{ext}")).read_bytes()
        assert got == (tmp_path / ("a.obj" if ext == "obj" else f"c.{ext}")).read_bytes(), ext
    assert r.report["input"] == str(src) and json.loads((tmp_path / "b.json").read_text())["parameters"]["seed"] == 3


def test_ctrl_c_then_resume(tmp_path):
    """SIGINT to ``heatparam batch`` mid-run: exit 130, only complete outputs, summary.json says interrupted; the
    next run does only what is missing."""
    root = tmp_path / "in"
    for k, h in enumerate((0.15, 0.16, 0.17, 0.18, 0.19, 0.2)):
        s = datasets.cylinder_patch(h=h)
        _write_obj(root / f"c{k}.obj", s.V, s.F)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "heatparam.cli", "batch", str(root), "-o", str(out), "--workers", "1", "--quiet"]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.time() + 120
        while time.time() < deadline and p.poll() is None and not list(out.glob("*.json")):
            time.sleep(0.05)
        p.send_signal(signal.SIGINT)  # after the first mesh is done, while the next ones run or wait
        _, err = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 130 and "interrupted" in err and "Traceback" not in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] and len(summary["rows"]) == 6
    done = {r["input"] for r in summary["rows"] if r["status"] == "ok"}
    assert 1 <= len(done) < 6
    assert [p for p in out.rglob("*") if p.name.startswith(".")] == []
    for r in summary["rows"]:
        assert (out / r["output"]).exists() == (r["status"] == "ok")
        assert (out / r["output"]).with_suffix(".json").exists() == (r["status"] == "ok")
    assert main(["batch", str(root), "-o", str(out), "--workers", "1", "--quiet"]) == 0
    rows = json.loads((out / "summary.json").read_text())["rows"]
    assert {r["input"] for r in rows if r["status"] == "skipped"} == done
    assert all(r["status"] == "ok" for r in rows if r["input"] not in done)


def test_batch_units_as_unwraps(tmp_path):
    """--units names every mesh's unit as unwrap's does (no 'mm assumed'); a rerun with other units redoes it."""
    src = shared_mesh("halftunnel.off")
    out = tmp_path / "out"
    assert main(["batch", str(src), "-o", str(out), "--format", "obj,svg", "--workers", "1", "--quiet",
                 "--units", "cm"]) == 0
    assert main(["unwrap", str(src), "-o", str(tmp_path / "u.svg"), "--quiet", "--units", "cm"]) == 0
    assert next(out.rglob("halftunnel.svg")).read_bytes() == (tmp_path / "u.svg").read_bytes()
    rep = json.loads(next(out.rglob("halftunnel.json")).read_text())
    assert rep["units"] == "cm" and rep["units_assumed"] is False
    assert main(["batch", str(src), "-o", str(out), "--format", "obj,svg", "--workers", "1", "--quiet",
                 "--units", "in"]) == 0
    assert json.loads(next(out.rglob("halftunnel.json")).read_text())["units"] == "in"
