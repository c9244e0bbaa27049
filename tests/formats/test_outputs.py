"""The writing contract: every output path checked before the computation, all outputs committed together, a
failure leaves every pre-existing file byte-identical (exit 2, one line, no traceback), modes follow the umask."""

import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from heatparam import formats
from heatparam.cli import main
from heatparam.errors import HeatparamError
from heatparam.formats import outputs
from heatparam.formats.outputs import commit_outputs, plan_outputs

from formats_cases import cylinder_map, write_off


@pytest.fixture()
def src(tmp_path):
    m = cylinder_map()
    return write_off(tmp_path / "part.off", m.V, m.F)


@pytest.fixture()
def existing(tmp_path):
    """Pre-existing outputs with known bytes in a folder of their own."""
    d = tmp_path / "out"
    d.mkdir()
    files = {d / name: f"old {name}\n".encode() for name in ("p.obj", "p.dxf", "p.svg", "p.json")}
    for p, b in files.items():
        p.write_bytes(b)
    return d, files


def unchanged(files, folder):
    assert all(p.read_bytes() == b for p, b in files.items())
    assert sorted(folder.iterdir()) == sorted(files)  # no temporary or new file left


def one_line_error(capsys, *words):
    err = capsys.readouterr().err
    assert err.startswith("heatparam: error:") and err.count("\n") == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err
    return err


def no_compute(monkeypatch):
    """Make the pipeline fail loudly: checks that must happen before it never reach it."""
    import heatparam.pipeline

    def boom(*a, **k):
        raise AssertionError("the computation ran")

    monkeypatch.setattr(heatparam.pipeline, "parameterize", boom)


def args(src, folder, *extra):
    return ["unwrap", str(src), "-o", str(folder / "p.obj"), "-o", str(folder / "p.dxf"), "-o",
            str(folder / "p.svg"), "--report", str(folder / "p.json"), "--quiet", *extra]


def unwritable_folder(tmp_path) -> Path:
    """A folder in which no file can be created (chmod 0555; as root, whom that does not stop, /sys)."""
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o555)
    if outputs.can_create(d):
        d.chmod(0o755)
        d = Path("/sys")
        if not d.is_dir() or outputs.can_create(d):
            pytest.skip("no unwritable folder available here")
    return d


def test_unwritable_output_is_refused_before_the_computation(tmp_path, src, existing, capsys, monkeypatch):
    d, files = existing
    bad = unwritable_folder(tmp_path)
    no_compute(monkeypatch)
    assert main([*args(src, d), "-o", str(bad / "x.ply")]) == 2
    one_line_error(capsys, "not writable", "x.ply")
    unchanged(files, d)
    # the unwritable report path of the issue: same, the OBJ is neither written nor replaced
    assert main(["unwrap", str(src), "-o", str(d / "p.obj"), "--report", str(bad / "r.json"), "--quiet"]) == 2
    one_line_error(capsys, "r.json")
    unchanged(files, d)


def test_directory_as_output_is_refused(tmp_path, src, existing, capsys, monkeypatch):
    d, files = existing
    no_compute(monkeypatch)
    for extra in (["-o", str(tmp_path)], ["--report", str(tmp_path / "out")], ["-o", str(tmp_path / "nope" / "x.svg")],
                  ["-o", str(d / "p.obj")], ["-o", str(d / "p.txt")], ["-o", str(src)]):
        assert main([*args(src, d), *extra]) == 2
        one_line_error(capsys)
    unchanged(files, d)
    # and as a console script: exit 2, one line, no traceback
    r = subprocess.run([sys.executable, "-m", "heatparam.cli", "unwrap", str(src), "-o", str(tmp_path), "--quiet"],
                       capture_output=True, text=True, env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "is a folder" in r.stderr and not r.stdout


def test_failure_after_the_computation_leaves_everything(tmp_path, src, existing, capsys, monkeypatch):
    """(a) a sheet smaller than the part (known only once the map exists); (b) the SVG writer failing (disk
    full) after the OBJ and DXF temporaries were written: exit 2, one line, every old file byte-identical, no
    new file (p.ply did not exist) and no temporary left."""
    d, files = existing
    assert main([*args(src, d), "-o", str(d / "p.ply"), "--sheet", "1x1"]) == 2
    one_line_error(capsys, "does not fit")
    unchanged(files, d)
    import heatparam.formats.svg

    calls = []

    def disk_full(path, *a, **k):
        calls.append(path)
        Path(path).write_bytes(b"partial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(heatparam.formats.svg, "write_svg", disk_full)
    assert main([*args(src, d), "-o", str(d / "p.ply")]) == 2
    one_line_error(capsys, "p.svg", "No space left")
    assert calls  # the failure did happen after the computation, while writing
    unchanged(files, d)


def test_success_replaces_all_and_modes_follow_umask(tmp_path, src, existing):
    d, files = existing
    old = os.umask(0o027)
    try:
        assert main([*args(src, d), "-o", str(d / "p.ply"), "--preview", str(d / "p.png")]) == 0
    finally:
        os.umask(old)
    for p in [*files, d / "p.ply", d / "p.png"]:
        assert p.read_bytes() != files.get(p)
        assert stat.S_IMODE(p.stat().st_mode) == 0o640, p
    assert not list(d.glob(".*"))
    old = os.umask(0o002)
    try:
        formats.save_json(d / "q.json", {"a": 1})
        assert stat.S_IMODE((d / "q.json").stat().st_mode) == 0o664  # atomic_write too
    finally:
        os.umask(old)


def test_step_unavailable_is_one_line(tmp_path, src, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "heatparam.formats.step", None)  # as if OpenCascade were not installed
    no_compute(monkeypatch)
    assert main(["unwrap", str(src), "-o", str(tmp_path / "p.step"), "--quiet"]) == 2
    one_line_error(capsys, "STEP", "unavailable")
    assert not (tmp_path / "p.step").exists()


def test_plan_outputs_checks():
    plans = plan_outputs(["a.obj", "b.STP", ("r.json", {"json"})])
    assert [p.format for p in plans] == ["obj", "step", "json"]
    for bad, msg in ((["a.obj", "./a.obj"], "twice"), (["a.json"], "unknown extension"), ([("a.obj", {"json"})],
                                                                                             "unknown extension")):
        with pytest.raises(HeatparamError, match=msg):
            plan_outputs(bad)


def test_commit_rolls_back_a_failed_rename(tmp_path, monkeypatch):
    """If the second rename fails, the first output is put back as it was; temporaries and backups are gone."""
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text("old a")
    real = os.replace
    n = []

    def flaky(s, d):
        if Path(d) == b:
            n.append(d)
            raise OSError(5, "Input/output error")
        return real(s, d)

    monkeypatch.setattr(outputs.os, "replace", flaky)
    with pytest.raises(HeatparamError, match="b.json"):
        commit_outputs([(a, lambda t: Path(t).write_text("new a")), (b, lambda t: Path(t).write_text("new b"))])
    assert n and a.read_text() == "old a" and not b.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json"]


def test_bad_sheet_is_refused_before_the_computation(tmp_path, src, existing, capsys, monkeypatch):
    d, files = existing
    no_compute(monkeypatch)
    for bad in ("10", "10x", "0x5", "ax3", "-1x2"):
        assert main([*args(src, d), f"--sheet={bad}"]) == 2
        one_line_error(capsys, "--sheet")
    unchanged(files, d)
