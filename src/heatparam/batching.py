"""``heatparam batch``: the unwrap pipeline over many meshes, one Dask task per mesh.

A local Dask cluster (``distributed.LocalCluster``, one single-threaded worker process per core) by default, or
any running scheduler (``--scheduler tcp://host:8786`` or a scheduler JSON file). The Python API is
``heatparam.batch(paths, out_dir, client=None, **options)`` (= :func:`run_batch`).

Design (and why):

- **The job is ``heatparam unwrap``** (``unwrap.unwrap_file``), so a batch output is the ``unwrap`` output, byte for
  byte (the report JSON differs only by its timings and the ``batch`` manifest below).
- **One process per mesh**, so that a task can be held to a wall-time limit (``--task-timeout``) and a memory
  limit (``--task-memory``, on the process's resident memory; default: the Dask worker's ``memory_limit``): the
  task polls the process and kills it past either limit. A thread cannot be stopped from outside, a process can;
  it also gives each mesh its own peak-memory figure, and a crash (segfault, OOM kill) of one mesh takes down only
  its process. The process is forked by a warm job server (``job_server``: kept by each worker, with heatparam and
  its libraries already imported, started while the batch is set up), so a small mesh costs milliseconds beyond
  its own work, not the half second of a fresh interpreter; without ``fork`` it is a fresh subprocess. Both die
  with their worker (``PR_SET_PDEATHSIG`` on Linux): killing a worker kills the meshes it was running, and Dask
  reruns them elsewhere. A worker that dies is retried once (our ``LocalCluster`` sets
  ``distributed.scheduler.allowed-failures`` to 1; an external scheduler uses its own setting, default 3), then
  the mesh is recorded as failed.
- **Never a partial file**: the subprocess writes into a hidden folder ``.heatparam-tmp-*`` beside the outputs;
  only when it succeeded are the files renamed into place, the report JSON last. Leftover temporary folders (a
  killed worker, Ctrl-C) are removed at the start and at the end of every batch.
- **Resumability manifest = the report JSON**: ``report["batch"]`` records the options hash (every pipeline
  option, the formats, the preview flag and the heatparam version) and the input's size, ``mtime_ns`` and
  SHA-256. A rerun skips an input when its report exists with the same options hash, the input's size and
  ``mtime_ns`` are those recorded (so touching or editing the input redoes it; comparing recorded values rather
  than clocks works across machines of a cluster) and every requested output exists. ``--force`` redoes all.
  Refused and failed inputs have no outputs and are tried again on every run.

Outputs: ``OUTDIR/<path relative to the input folder>/<stem>.obj`` and ``<stem>.json`` (the report; inputs
given as files or globs go to the top of OUTDIR, or below the glob's fixed folder), plus ``OUTDIR/summary.csv``,
``summary.json`` and ``index.html`` (a sortable table with the previews of ``--preview``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import glob
import hashlib
import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path, PurePosixPath

from heatparam.errors import HeatparamError, ResourceError
from heatparam.job_server import JobServer, ServerPool, die_with_parent
from heatparam.options import Options, make_options, to_cli_terms
from heatparam.version import __version__

#: Mesh suffixes searched in folders (heatparam.formats.MESH_SUFFIXES; a test checks they agree).
MESH_SUFFIXES = (".obj", ".off", ".ply", ".stl", ".glb", ".gltf")
TMP_PREFIX = ".heatparam-tmp-"
STATUSES = ("ok", "refused", "failed", "skipped")
#: How often a task checks its subprocess's memory and time, in seconds.
POLL_S = 0.05


# ---------------------------------------------------------------------------------------------------- discovery

@dataclasses.dataclass(frozen=True)
class Item:
    """One input mesh and where its outputs go: ``out_dir / rel / (stem + ext)``."""

    input: Path
    rel: PurePosixPath
    stem: str

    def output(self, out_dir: Path, ext: str) -> Path:
        return out_dir / self.rel / f"{self.stem}.{ext}"


def _is_glob(s: str) -> bool:
    return any(c in s for c in "*?[")


def _glob_root(pattern: str) -> Path:
    """The fixed folder in front of a glob pattern's first wildcard."""
    parts = Path(pattern).parts
    fixed = []
    for part in parts[:-1]:
        if _is_glob(part):
            break
        fixed.append(part)
    return Path(*fixed) if fixed else Path(".")


def _inside(p: Path, folder: Path) -> bool:
    try:
        p.relative_to(folder)
        return True
    except ValueError:
        return False


def discover(inputs: list[str | os.PathLike], out_dir: str | os.PathLike) -> list[Item]:
    """The meshes named by ``inputs`` (files, folders searched recursively by mesh suffix, globs), in order.

    Files given by name are taken whatever their suffix (an unsupported one is then refused by the job). Hidden
    folders and ``out_dir`` are not searched. Two inputs that would write the same output: if their suffixes
    differ (``part.obj`` and ``part.off`` in one folder) the stems become ``part-obj`` and ``part-off``;
    otherwise it is a usage error.

    Returns
    -------
    list of :class:`Item`, sorted by output path. Raises ``HeatparamError`` for an input that does not exist,
    a glob or folder that holds no mesh, an empty list, or colliding outputs.
    """
    if not inputs:
        raise HeatparamError("no input: give mesh files, folders or globs")
    found = _found_meshes(inputs, Path(out_dir).resolve())
    if not found:
        raise HeatparamError(f"no mesh to flatten (every input lies inside the output folder {out_dir})")
    return _named_items(found, Path(out_dir))


def _found_meshes(inputs: list[str | os.PathLike], out: Path) -> dict[Path, tuple[Path, PurePosixPath]]:
    """Each mesh named by ``inputs`` once, outside ``out``: resolved path → (path as given, its output folder
    relative to the folder or glob root it was found under)."""
    found: dict[Path, tuple[Path, PurePosixPath]] = {}

    def add(p: Path, root: Path | None) -> None:
        r = p.resolve()
        if _inside(r, out) or r in found:
            return
        rel = PurePosixPath(p.parent.resolve().relative_to(root.resolve()).as_posix()) if root else PurePosixPath()
        found[r] = (p, rel)

    for s in map(str, inputs):
        p = Path(s)
        if p.is_file():
            add(p, None)
        elif p.is_dir():
            meshes = [q for q in sorted(p.rglob("*")) if q.suffix.lower() in MESH_SUFFIXES and q.is_file()
                      and not any(x.startswith(".") for x in q.relative_to(p).parts)]
            if not meshes:
                raise HeatparamError(f"folder {p} holds no mesh ({', '.join(MESH_SUFFIXES)})")
            for q in meshes:
                add(q, p)
        elif _is_glob(s):
            root = _glob_root(s)
            hits = [Path(h) for h in sorted(glob.glob(s, recursive=True)) if Path(h).is_file()]
            if not hits:
                raise HeatparamError(f"no file matches {s}")
            for h in hits:
                add(h, root)
        else:
            raise HeatparamError(f"cannot read {p}: no such file or folder")
    return found


def _named_items(found: dict[Path, tuple[Path, PurePosixPath]], out_dir: Path) -> list[Item]:
    """The items of the found meshes, sorted by output path; two meshes of one stem in one folder are told apart
    by their suffixes (``part-obj``, ``part-off``), or refused when they have the same suffix too."""
    groups: dict[tuple[PurePosixPath, str], list[tuple[Path, PurePosixPath]]] = {}
    for p, rel in found.values():
        groups.setdefault((rel, p.stem), []).append((p, rel))
    items = []
    for (rel, stem), members in groups.items():
        if len(members) == 1:
            items.append(Item(members[0][0], rel, stem))
            continue
        suffixes = [p.suffix.lower() for p, _ in members]
        if len(set(suffixes)) < len(suffixes):
            names = ", ".join(str(p) for p, _ in members)
            raise HeatparamError(f"{names} would all be written to {out_dir / rel / stem}.obj — give "
                                 "their common folder instead of the files, or flatten them in separate batches")
        items += [Item(p, rel, f"{stem}-{p.suffix[1:].lower()}") for p, _ in members]
    return sorted(items, key=lambda it: (str(it.rel), it.stem))


# ----------------------------------------------------------------------------------------------------- manifest

def options_hash(options: Options, formats: tuple[str, ...], preview: bool) -> str:
    """SHA-256 (16 hex digits) of everything that decides an output's bytes: pipeline options (not ``progress``),
    formats, preview flag, heatparam version."""
    fields = {k: v for k, v in dataclasses.asdict(options).items() if k != "progress"}
    key = json.dumps({"options": fields, "formats": sorted(formats), "preview": preview, "version": __version__},
                     sort_keys=True, default=str)
    return hashlib.sha256(key.encode()).hexdigest()[:16]


def _file_sha256(p: Path) -> str:
    h = hashlib.sha256()
    with open(p, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _expected_outputs(item: Item, out_dir: Path, formats: tuple[str, ...], preview: bool) -> list[Path]:
    exts = [f for f in formats if f != "json"] + (["png"] if preview else []) + ["json"]
    return [item.output(out_dir, e) for e in exts]


def up_to_date(item: Item, out_dir: Path, opt_hash: str, *, formats: tuple[str, ...], preview: bool) -> dict | None:
    """The report of ``item``'s earlier outputs when they can be kept (see module docstring), else None."""
    rep_path = item.output(out_dir, "json")
    try:
        report = json.loads(rep_path.read_text())
        st = item.input.stat()
        man = report["batch"]
        if (man["options_hash"] != opt_hash or man["input"]["size"] != st.st_size
                or man["input"]["mtime_ns"] != st.st_mtime_ns):
            return None
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not all(p.is_file() for p in _expected_outputs(item, out_dir, formats, preview)):
        return None
    return report


def _charts(report: dict) -> int:
    return int(report.get("metrics", {}).get("charts", 1))  # an atlas reports its charts; one piece otherwise


def _previous_refusals(out_dir: Path) -> dict:
    """The inputs the last batch into ``out_dir`` refused for good (``summary.json``'s ``refusals``)."""
    try:
        return dict(json.loads((out_dir / "summary.json").read_text()).get("refusals", {}))
    except (OSError, ValueError, AttributeError):
        return {}


def _refused_again(item: Item, refusals: dict, opt_hash: str, out_dir: Path) -> dict | None:
    """A refused row, not rerun, when the last batch refused this unchanged input with the same options (the
    refusal is deterministic: a malformed or closed mesh); it stays refused (exit code 1), with its reason."""
    prev = refusals.get(str(item.input))
    try:
        st = item.input.stat()
        if prev is None or prev["options_hash"] != opt_hash or (prev["size"], prev["mtime_ns"]) != (
                st.st_size, st.st_mtime_ns):
            return None
    except (OSError, KeyError, TypeError):
        return None
    row = _bad_row(item, out_dir, "refused", prev["reason"])
    row["_refusal"] = {k: prev[k] for k in ("options_hash", "size", "mtime_ns")}
    return row


def _row_from_report(item: Item, out_dir: Path, status: str, report: dict, *, seconds: float | None = None,
                     peak_mb: float | None = None) -> dict:
    m = report.get("metrics", {})
    man = report.get("batch", {})
    return {
        "input": str(item.input), "output": str(item.output(out_dir, "obj").relative_to(out_dir)),
        "status": status, "reason": "up to date" if status == "skipped" else "",
        "vertices": report.get("mesh", {}).get("vertices"), "charts": _charts(report),
        "iso_mean": m.get("iso_mean"), "flips": m.get("flips"), "crossings": m.get("boundary_crossings"),
        "seconds": round(seconds if seconds is not None else man.get("seconds", 0.0), 3),
        "peak_mem_mb": peak_mb if peak_mb is not None else man.get("peak_mem_mb"),
        "warnings": " | ".join(to_cli_terms(w) for w in report.get("warnings", [])),
    }


def _bad_row(item: Item, out_dir: Path, status: str, reason: str, *, seconds: float = 0.0,
             peak_mb: float | None = None) -> dict:
    return {"input": str(item.input), "output": str(item.output(out_dir, "obj").relative_to(out_dir)),
            "status": status, "reason": reason, "vertices": None, "charts": None, "iso_mean": None, "flips": None,
            "crossings": None, "seconds": round(seconds, 3), "peak_mem_mb": peak_mb, "warnings": ""}


# ------------------------------------------------------------------------------------------ the per-mesh job

def _one_line(exc: BaseException) -> str:
    msg = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {msg[0]}" if msg else type(exc).__name__


def _job_main(tmp: str) -> None:
    """Subprocess entry point: run ``unwrap_file`` on the spec in ``tmp/spec.json``, outputs into ``tmp``, and
    write ``tmp/result.json`` ({status, reason, report?})."""
    from heatparam.formats import save_json
    from heatparam.memory import peak_rss_bytes
    from heatparam.unwrap import unwrap_file

    tmp_p = Path(tmp)
    spec = json.loads((tmp_p / "spec.json").read_text())
    stem = spec["stem"]
    t0 = time.perf_counter()
    try:
        opts = make_options(**spec["options"])
        src = Path(spec["input"])
        st = src.stat()
        outs = [tmp_p / f"{stem}.{f}" for f in spec["formats"] if f != "json"]
        result = unwrap_file(src, outs, preview=tmp_p / f"{stem}.png" if spec["preview"] else None, options=opts,
                             quiet=True)
        report = result.report
        report["batch"] = {
            "options_hash": spec["options_hash"], "formats": spec["formats"], "preview": spec["preview"],
            "input": {"path": str(src), "size": st.st_size, "mtime_ns": st.st_mtime_ns, "sha256": _file_sha256(src)},
            "seconds": round(time.perf_counter() - t0, 3),
            "peak_mem_mb": round(peak_rss_bytes() / 2**20, 1),
        }
        save_json(tmp_p / f"{stem}.json", report)
        out = {"status": "ok", "reason": ""}
    except HeatparamError as exc:
        out = {"status": "refused", "reason": str(exc).strip().splitlines()[0] if str(exc).strip() else "refused",
               # the same input and options are refused again, except for lack of memory (it depends on the moment)
               "final": not isinstance(exc, ResourceError)}
    except MemoryError:
        out = {"status": "failed", "reason": "out of memory"}
    except Exception as exc:  # any other error: one line, no traceback, the batch goes on
        out = {"status": "failed", "reason": _one_line(exc)}
    out["peak_mem_mb"] = round(peak_rss_bytes() / 2**20, 1)
    (tmp_p / "result.json").write_text(json.dumps(out))


def _task_memory_default() -> int | None:
    try:
        from distributed import get_worker

        limit = get_worker().memory_manager.memory_limit
        return int(limit) if limit else None
    except Exception:  # not on a Dask worker, or an older distributed
        return None


class _Child:
    """A job started as a plain subprocess (where there is no ``fork``, or its job server would not start)."""

    def __init__(self, tmp: Path):
        with open(tmp / "log.txt", "wb") as log:
            self.proc = subprocess.Popen(
                [sys.executable, "-c", "import sys; from heatparam.batching import _job_main; _job_main(sys.argv[1])",
                 str(tmp)], stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT, preexec_fn=die_with_parent)
        self.pid = self.proc.pid

    def ended(self, timeout: float | None) -> int | None:
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            return None


class _Forked:
    """A job forked by one of this worker's warm job servers (``job_server``)."""

    def __init__(self, server: JobServer, tmp: Path, modules: tuple[str, ...]):
        self.server = server
        self.pid = server.start(str(tmp), modules)

    def ended(self, timeout: float | None) -> int | None:
        return self.server.ended(timeout)


#: This worker process's warm job servers (``job_server``), started by a worker's setup or by the first job.
_SERVERS = ServerPool([sys.executable, "-c", "from heatparam.batching import _job_main; "
                       "from heatparam.job_server import serve; serve(_job_main)"])


def dask_setup(worker) -> None:
    """Dask's preload hook (our LocalCluster preloads this module): a job server starts importing while the batch
    is set up, so the first mesh does not wait for it."""
    if hasattr(os, "fork"):
        with contextlib.suppress(OSError):
            _SERVERS.prestart()


def _modules(spec: dict) -> tuple[str, ...]:
    """What the job of ``spec`` imports beyond the job server's preload: its formats' writers and the libraries
    they need (``formats.exporters``), the preview's pyplot, a glTF input's reader, the texture nesting."""
    from heatparam.formats.exporters import BY_NAME

    mods = [m for f in spec["formats"] for m in (BY_NAME[f].module, BY_NAME[f].requires) if m]
    if spec["preview"]:
        mods.append("matplotlib.pyplot")
    if Path(spec["input"]).suffix.lower() in (".glb", ".gltf"):
        mods.append("trimesh")
    if spec["options"].get("pack") == "texture":
        mods.append("heatparam.mesh.nest")
    return tuple(dict.fromkeys(mods))


def _start_job(tmp: Path, spec: dict) -> _Child | _Forked:
    """The job of ``spec`` on ``tmp``, forked by a warm job server where there is one, else a fresh subprocess."""
    if not hasattr(os, "fork"):
        return _Child(tmp)
    server = None
    try:
        server = _SERVERS.take()
        return _Forked(server, tmp, _modules(spec))
    except OSError:
        if server is not None:
            server.close()
        return _Child(tmp)


def _run_process(tmp: Path, spec: dict, timeout: float | None, mem_limit: int | None,
                 t0: float) -> tuple[int, int, str | None]:
    """Run :func:`_job_main` on ``tmp`` (its ``spec``) in a process of its own (output into ``tmp/log.txt``),
    killed past ``mem_limit`` bytes of resident memory or ``timeout`` seconds since ``t0``; it never outlives this
    call.
    Returns (its exit code, the peak resident bytes seen, why it was killed or None)."""
    import psutil

    job = _start_job(tmp, spec)
    rc, peak, reason = None, 0, None
    try:
        ps = psutil.Process(job.pid)
        while rc is None:  # the limits checked before each wait: a job forked warm can end within one
            with contextlib.suppress(psutil.Error):
                rss = ps.memory_info().rss
                peak = max(peak, rss)
                if mem_limit and rss > mem_limit:
                    reason = f"exceeded the task memory limit ({mem_limit / 2**20:.0f} MiB)"
            if timeout and time.perf_counter() - t0 > timeout:
                reason = f"timed out after {timeout:g} s (--task-timeout)"
            if reason:
                os.kill(job.pid, signal.SIGKILL)
                rc = job.ended(None)
                break
            rc = job.ended(POLL_S)
    finally:
        if rc is None:  # an exception here (the task cancelled): never leave the mesh running
            with contextlib.suppress(OSError):
                os.kill(job.pid, signal.SIGKILL)
            if isinstance(job, _Forked):  # its exit line was never read: this server is out of step
                job.server.close()
            else:
                job.proc.wait()
        elif isinstance(job, _Forked):
            _SERVERS.give_back(job.server)
    return rc, peak, reason


def _death_reason(tmp: Path, rc: int) -> str:
    """Why a job that wrote no ``result.json`` died: its exit code or signal, and the last line of its log."""
    why = f"exit code {rc}"
    if rc < 0:
        why = f"signal {-rc}"
        with contextlib.suppress(ValueError):
            why += f" ({signal.Signals(-rc).name})"
    last = (tmp / "log.txt").read_text(errors="replace").strip().splitlines()
    return f"the job died: {why}" + (f": {last[-1]}" if last else "")


def _job_row(item: Item, out_dir: Path, spec: dict, tmp: Path, *, rc: int, seconds: float,
             peak_mb: float | None) -> dict:
    """The summary row of a job that ran to its end in ``tmp``; on success its outputs are moved into place, the
    report last."""
    try:
        res = json.loads((tmp / "result.json").read_text())
    except (OSError, ValueError):
        return _bad_row(item, out_dir, "failed", _death_reason(tmp, rc), seconds=seconds, peak_mb=peak_mb)
    peak_mb = max(peak_mb or 0.0, res.get("peak_mem_mb") or 0.0) or None
    if res["status"] != "ok":
        row = _bad_row(item, out_dir, res["status"], res["reason"], seconds=seconds, peak_mb=peak_mb)
        if res.get("final"):
            st = item.input.stat()
            row["_refusal"] = {"options_hash": spec["options_hash"], "size": st.st_size,
                               "mtime_ns": st.st_mtime_ns}
        return row
    report = json.loads((tmp / f"{item.stem}.json").read_text())
    for p in _expected_outputs(item, out_dir, tuple(spec["formats"]), spec["preview"]):  # report last
        os.replace(tmp / p.name, p)
    return _row_from_report(item, out_dir, "ok", report, seconds=seconds, peak_mb=peak_mb)


def run_job(spec: dict) -> dict:
    """One mesh, as a Dask task: the job in a subprocess under the time and memory limits; outputs renamed into
    place on success. Returns the summary row (a dict of ``formats.summary.COLUMNS``)."""
    item = Item(Path(spec["input"]), PurePosixPath(spec["rel"]), spec["stem"])
    out_dir = Path(spec["out_dir"])
    dest = out_dir / item.rel
    dest.mkdir(parents=True, exist_ok=True)
    tmp = dest / f"{TMP_PREFIX}{item.stem}-{uuid.uuid4().hex[:8]}"
    tmp.mkdir()
    t0 = time.perf_counter()
    timeout, mem_limit = spec["task_timeout"], spec["task_memory"] or _task_memory_default()
    try:
        (tmp / "spec.json").write_text(json.dumps(spec))
        rc, peak, reason = _run_process(tmp, spec, timeout, mem_limit, t0)
        seconds = time.perf_counter() - t0
        peak_mb = round(peak / 2**20, 1) if peak else None
        if reason:
            return _bad_row(item, out_dir, "failed", reason, seconds=seconds, peak_mb=peak_mb)
        return _job_row(item, out_dir, spec, tmp, rc=rc, seconds=seconds, peak_mb=peak_mb)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


# -------------------------------------------------------------------------------------------------- the batch

def _clean_tmp(out_dir: Path) -> None:
    if out_dir.is_dir():
        for d in sorted(out_dir.rglob(f"{TMP_PREFIX}*"), reverse=True):
            shutil.rmtree(d, ignore_errors=True)


def parse_formats(formats: str | list[str] | tuple[str, ...]) -> tuple[str, ...]:
    """Validate ``--format`` names (comma-separated or a list; ``formats.exporters``); the report ``json`` is always
    included."""
    from heatparam.formats.exporters import BY_NAME, batch_formats

    names = [f.strip().lower() for f in (formats.split(",") if isinstance(formats, str) else formats) if f.strip()]
    for f in names:
        if f not in batch_formats():
            raise HeatparamError(f"unknown format {f!r}: use one of {', '.join(batch_formats())}")
        missing = BY_NAME[f].missing_requirement()
        if missing:
            raise HeatparamError(f"format {f} is not available in this installation (no {missing})")
    if "obj" not in names:
        names.insert(0, "obj")  # the OBJ with UVs is the map itself: always written
    return tuple(dict.fromkeys(names + ["json"]))


def _parse_bytes(value) -> int | None:
    if value in (None, "", 0, "0", "none"):
        return None
    if isinstance(value, int | float):
        return int(value)
    from dask.utils import parse_bytes

    try:
        return int(parse_bytes(value))
    except (ValueError, TypeError):
        raise HeatparamError(f"task memory must be a size like 2GB or 500MiB, got {value!r}") from None


@contextlib.contextmanager
def _client(client, scheduler: str | None, workers: int | None):
    """The Dask client to use: ``client`` as given, one connected to ``scheduler`` (an address or a scheduler
    JSON file), or a new LocalCluster of ``workers`` single-threaded processes (closed at the end)."""
    import dask
    from distributed import Client, LocalCluster

    if client is not None:
        yield client
        return
    if scheduler:
        try:
            c = (Client(scheduler_file=scheduler, timeout="20s") if scheduler.endswith(".json")
                 else Client(scheduler, timeout="20s"))
        except OSError as exc:
            raise HeatparamError(f"cannot reach the Dask scheduler at {scheduler}: {_one_line(exc)}") from None
        try:
            yield c
        finally:
            c.close()
        return
    n = workers or os.cpu_count() or 1
    dashboard = ":0"  # a free port (the scheduler always serves HTTP; the dashboard needs bokeh)
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=dashboard,
                               silence_logs=50, preload=["heatparam.batching"])  # dask_setup: warm job servers
    try:
        c = Client(cluster)
        try:
            yield c
        finally:
            c.close()
    finally:
        cluster.close()


def _dashboard(client) -> str | None:
    if importlib.util.find_spec("bokeh") is None:  # the scheduler names a dashboard it cannot serve
        return None
    try:
        if "dashboard" in client.scheduler_info().get("services", {}):
            return client.dashboard_link
    except Exception:
        pass
    return None


def run_batch(paths, out_dir, client=None, *, formats="obj", force: bool = False, workers: int | None = None,
              scheduler: str | None = None, task_timeout: float | None = None, task_memory=None,
              preview: bool = False, progress: bool = False, options: Options | None = None,
              **option_fields) -> dict:
    """Flatten every mesh in ``paths`` (files, folders, globs) into ``out_dir``, one Dask task per mesh.

    Parameters
    ----------
    paths : a path or a list of paths, folders (searched recursively) and glob patterns.
    out_dir : output folder (created).
    client : a ``distributed.Client`` to run on; default: connect to ``scheduler``, else a LocalCluster of
        ``workers`` processes (default: one per core), closed at the end. No cluster is started when every
        input is up to date.
    formats : output formats ("obj,dxf" or a list); obj and the json report are always written.
    force : redo inputs whose outputs are up to date.
    task_timeout : seconds one mesh may take (None = no limit).
    task_memory : bytes (or "2GB") one mesh's process may hold; default: the worker's memory limit.
    preview : also write ``<stem>.png`` previews (shown in index.html).
    progress : a progress bar over meshes on stderr, and the dashboard address.
    options, **option_fields : pipeline :class:`~heatparam.pipeline.Options` (fields override ``options``).

    Returns
    -------
    The summary (also written to ``out_dir/summary.json``): ``{"rows": [one dict per input: COLUMNS], "counts":
    {status: n}, "options": ..., "wall_s": ...}``. Raises ``HeatparamError`` for usage errors (nothing run).
    """
    t_start = time.perf_counter()
    paths = [paths] if isinstance(paths, str | os.PathLike) else list(paths)
    opts = make_options(options, **option_fields, progress=False)
    opts.validate()
    fmts = parse_formats(formats)
    mem = _check_limits(task_timeout=task_timeout, task_memory=task_memory, workers=workers, scheduler=scheduler,
                       client=client)
    out, items = _prepare_out(paths, out_dir)
    h = options_hash(opts, fmts, preview)
    _clean_tmp(out)

    rows, todo = _triage(items, out, h, fmts=fmts, preview=preview, force=force)
    opt_fields = {k: v for k, v in dataclasses.asdict(opts).items()}
    specs = {i: {"input": str(items[i].input), "rel": str(items[i].rel), "stem": items[i].stem, "out_dir": str(out),
                 "formats": list(fmts), "preview": preview, "options": opt_fields, "options_hash": h,
                 "task_timeout": task_timeout, "task_memory": mem} for i in todo}
    interrupted = False
    if todo:
        with _client(client, scheduler, workers) as c:
            interrupted = _submit(c, items, specs, rows, out=out, progress=progress)
    _clean_tmp(out)
    ordered = _final_rows(items, rows, out, h, fmts=fmts, preview=preview)
    refusals = {r["input"]: {**r.pop("_refusal"), "reason": r["reason"]} for r in ordered if "_refusal" in r}
    counts = {s: sum(r["status"] == s for r in ordered) for s in STATUSES}
    summary = {"heatparam_version": __version__, "out_dir": str(out), "options": opt_fields, "options_hash": h,
               "formats": list(fmts), "wall_s": round(time.perf_counter() - t_start, 3), "counts": counts,
               "interrupted": interrupted, "rows": ordered, "refusals": refusals}
    from heatparam.formats.summary import write_summary

    write_summary(out, summary)
    if interrupted:
        raise KeyboardInterrupt
    return summary


def _check_limits(*, task_timeout: float | None, task_memory, workers: int | None, scheduler: str | None,
                  client) -> int | None:
    """Validate :func:`run_batch`'s task limits and cluster choice; returns ``task_memory`` in bytes (or None)."""
    if task_timeout is not None and not task_timeout > 0:
        raise HeatparamError(f"task timeout must be positive, got {task_timeout}")
    mem = _parse_bytes(task_memory)
    if workers is not None and workers < 1:
        raise HeatparamError(f"workers must be at least 1, got {workers}")
    if workers is not None and (scheduler or client is not None):
        raise HeatparamError("--workers sizes the local cluster; a scheduler's workers are its own")
    return mem


def _prepare_out(paths: list, out_dir) -> tuple[Path, list[Item]]:
    """Discover the inputs and create ``out_dir``; returns both resolved."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise HeatparamError(f"{out} exists and is not a folder")
    items = discover(paths, out)
    out.mkdir(parents=True, exist_ok=True)
    return out.resolve(), [Item(it.input.resolve(), it.rel, it.stem) for it in items]


def _triage(items: list[Item], out: Path, h: str, *, fmts: tuple[str, ...], preview: bool,
            force: bool) -> tuple[dict[int, dict], list[int]]:
    """Rows for the inputs that need no run (up to date, or refused before), and the indices of the others."""
    rows: dict[int, dict] = {}
    todo = []
    refused_before = {} if force else _previous_refusals(out)
    for i, it in enumerate(items):
        rep = None if force else up_to_date(it, out, h, formats=fmts, preview=preview)
        if rep is not None:
            rows[i] = _row_from_report(it, out, "skipped", rep)
        elif (prev := _refused_again(it, refused_before, h, out)) is not None:
            rows[i] = prev
        else:
            todo.append(i)
    return rows, todo


def _final_rows(items: list[Item], rows: dict[int, dict], out: Path, h: str, *, fmts: tuple[str, ...],
                preview: bool) -> list[dict]:
    """All rows in input order; an input with no row (interrupted) is ok when its outputs got into place, else
    failed."""
    for i, it in enumerate(items):
        if i not in rows:
            rep = up_to_date(it, out, h, formats=fmts, preview=preview)
            rows[i] = (_row_from_report(it, out, "ok", rep) if rep is not None
                       else _bad_row(it, out, "failed", "interrupted"))
    return [rows[i] for i in range(len(items))]


def _submit(client, items: list[Item], specs: dict[int, dict], rows: dict[int, dict], *, out: Path,
            progress: bool) -> bool:
    """Run the jobs on ``client``, filling ``rows``; True when interrupted (Ctrl-C)."""
    from distributed import as_completed
    from tqdm import tqdm

    if progress:
        link = _dashboard(client)
        if link:
            print(f"heatparam: Dask dashboard at {link}", file=sys.stderr)
    futures = {client.submit(run_job, spec, key=f"heatparam-{i}-{uuid.uuid4().hex[:8]}", pure=False): i
               for i, spec in specs.items()}
    bar = tqdm(total=len(futures), unit="mesh", disable=not progress, file=sys.stderr, desc="heatparam batch")
    try:
        for fut in as_completed(list(futures)):
            i = futures[fut]
            try:
                rows[i] = fut.result()
            except Exception as exc:  # a worker died twice (KilledWorker), a lost connection, a cancellation
                why = ("its worker died twice while running it (killed, or out of memory)"
                       if type(exc).__name__ == "KilledWorker" else _one_line(exc))
                rows[i] = _bad_row(items[i], out, "failed", why)
            bar.update(1)
    except KeyboardInterrupt:
        client.cancel(list(futures), force=True)
        from heatparam import interrupt

        interrupt.finish()  # acknowledged: the summary of what is done is still written (a later Ctrl-C is noted)
        return True
    finally:
        bar.close()
    return False
