"""Hostile inputs (issue 16), every one through the CLI: exit 0 with a valid output, or exit 2 with one line that
names the problem, nothing written, no traceback, no Python exception text or module name.

Classes: valid files in unusual encodings and OBJ/OFF/STL/PLY features (accepted); malformed and junk files
(refused); geodesics' source indices and time steps; numerical failures inside (thin limbs, slivers, needles: a
fallback, never NaN); Ctrl-C at any moment (subprocess). Option ranges and coordinate scale, which the options
table and the normalization handle, are in test_scale_guards.py.
"""

from __future__ import annotations

import os
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from heatparam import formats, interrupt
from heatparam.cli import main

sys.path.insert(0, str(Path(__file__).parent))
from hostile import degrade, leaked, ply_bytes, split_edge, thin_limbs_disk  # noqa: E402

SRC = str(Path(__file__).resolve().parents[1] / "src")
#: texts a reader error must never show: Python exception texts and module names
LEAKS = ("Traceback", "codec", "No module named", "Error:", "kwarg", "charset", "object has no attribute",
         "invalid literal", "could not convert")


def grid(k: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """A k×k grid on a gently curved sheet: V (k²,3), F (2(k-1)²,3) counter-clockwise."""
    x, y = np.meshgrid(np.arange(k, dtype=float), np.arange(k, dtype=float))
    V = np.column_stack([x.ravel(), y.ravel(), 0.1 * (x.ravel() - 1.5) ** 2])
    F = []
    for i in range(k - 1):
        for j in range(k - 1):
            a = i * k + j
            F += [[a, a + 1, a + k + 1], [a, a + k + 1, a + k]]
    return V, np.array(F, dtype=np.int64)


V4, F4 = grid()
QUADS = np.array([[i * 4 + j, i * 4 + j + 1, i * 4 + j + 5, i * 4 + j + 4] for i in range(3) for j in range(3)])


def obj_text(V=V4, F=F4, corner="{v}", neg=False) -> str:
    out = "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in V.tolist())
    for f in F.tolist():
        idx = [(i - len(V)) if neg else i + 1 for i in f]
        out += "f " + " ".join(corner.format(v=i) for i in idx) + "\n"
    return out


def off_text(V=V4, F=F4, header="OFF\n{nv} {nf} 0\n", vextra="", fextra="") -> str:
    out = header.format(nv=len(V), nf=len(F))
    out += "".join(f"{x!r} {y!r} {z!r}{vextra}\n" for x, y, z in V.tolist())
    out += "".join(f"{len(f)} " + " ".join(map(str, f)) + f"{fextra}\n" for f in F.tolist())
    return out


def stl_ascii(V=V4, F=F4, name="part") -> bytes:
    s = f"solid {name}\n".encode("latin-1")
    for f in F:
        s += b"facet normal 0 0 1\nouter loop\n"
        s += b"".join(b"vertex %r %r %r\n" % tuple(V[i].tolist()) for i in f)
        s += b"endloop\nendfacet\n"
    return s + b"endsolid\n"


def stl_binary(V=V4, F=F4, header=b"solid but binary") -> bytes:
    s = header.ljust(80, b" ") + struct.pack("<I", len(F))
    for f in F:
        s += struct.pack("<3f", 0, 0, 1) + struct.pack("<9f", *V[f].ravel().tolist()) + b"\0\0"
    return s


def ply_text(V=V4, F=F4, comment="made by caf\xe9") -> bytes:
    head = (f"ply\nformat ascii 1.0\ncomment {comment}\nelement vertex {len(V)}\nproperty double x\n"
            f"property double y\nproperty double z\nelement face {len(F)}\nproperty list uchar int vertex_indices\n"
            "end_header\n")
    body = "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in V.tolist()) + "".join(
        "3 " + " ".join(map(str, f)) + "\n" for f in F.tolist())
    return head.encode("latin-1") + body.encode()


def run(tmp_path: Path, capsys, name: str, data: bytes | str, *extra: str, cmd: str = "unwrap"):
    """Write ``data`` to ``name``, run the command with a pre-existing output; (exit code, stderr, output path)."""
    src = tmp_path / name
    src.write_bytes(data.encode("latin-1") if isinstance(data, str) else data)
    out = tmp_path / ("out.npy" if cmd == "geodesics" else "out.obj")
    out.write_text("previous content\n")
    args = [cmd, str(src), "-o", str(out), "--quiet", *extra]
    if cmd == "geodesics" and "--source" not in extra:
        args += ["--source", "0"]
    try:
        code = main(args)
    except SystemExit as exc:  # a value refused while the command line is parsed (one line, exit 2)
        code = exc.code
    return code, capsys.readouterr().err, out


def assert_refused(code, err, out, expect: str, name: str | None = None):
    assert code == 2, err
    assert err.startswith("heatparam: error:") and err.count("\n") == 1, err
    assert expect in err, err
    if name is not None:
        assert name in err, err  # the message names the file
    assert not any(leak in err for leak in LEAKS), err
    assert out.read_text() == "previous content\n"  # a failed run leaves the old output alone
    assert not list(out.parent.glob(".*.tmp"))


def assert_accepted(code, err, out, V=V4, F=F4):
    assert code == 0, err
    Vo, Fo, UV, _ = formats.load_uv_obj(out)
    assert np.array_equal(Vo, V) and len(Fo) == len(F)
    assert np.isfinite(UV).all()


# ----------------------------------------------------------------------------------------------------------
# valid files that must be accepted
# ----------------------------------------------------------------------------------------------------------
ACCEPTED = {
    "latin1_comment.obj": "# exported by Fran\xe7ois, caf\xe9 \xa9 2024\n" + obj_text(),
    "latin1_object_name.obj": "o pi\xe8ce_\xe9tir\xe9e\ng groupe\xb2\nusemtl acier\xb0\n" + obj_text(),
    "utf8_bom.obj": "\ufeff# utf-8 with a byte-order mark\n".encode().decode("latin-1") + obj_text(),
    "crlf.obj": obj_text().replace("\n", "\r\n"),
    "tabs.obj": obj_text().replace(" ", "\t"),
    "negative_indices.obj": obj_text(neg=True),
    "v_vt_vn.obj": "vt 0 0\nvn 0 0 1\n" + obj_text(corner="{v}/1/1"),
    "v__vn.obj": "vn 0 0 1\n" + obj_text(corner="{v}//1"),
    "mtllib_s_o_g.obj": "mtllib part.mtl\no part\ns 1\n" + obj_text().replace("f ", "g side\nusemtl red\nf ", 1),
    "continuation.obj": obj_text().replace("v 0.0 0.0", "v 0.0 \\\n 0.0", 1).replace("f 1 2", "f 1 \\\n2", 1),
    "inline_comment.obj": obj_text().replace("\n", " # note\n"),
    "quads.obj": obj_text(F=QUADS),
    "latin1_comment.off": "OFF\n# export\xe9 par Ren\xe9\n" + off_text(header="{nv} {nf} 0\n"),
    "counts_on_header.off": off_text(header="OFF {nv} {nf} 0\n"),
    "colours.off": off_text(header="COFF\n{nv} {nf} 0\n", vextra=" 255 0 0 255", fextra=" 0.5 0.5 0.5"),
    "no_header.off": off_text(header="{nv} {nf} 0\n"),
    "quads.off": off_text(F=QUADS),
}


@pytest.mark.parametrize("name", sorted(ACCEPTED))
def test_valid_text_files_accepted(tmp_path, capsys, name):
    F = F4 if "quads" not in name else np.vstack([QUADS[:, [0, 1, 2]], QUADS[:, [0, 2, 3]]])
    assert_accepted(*run(tmp_path, capsys, name, ACCEPTED[name]), F=F)


@pytest.mark.parametrize("name,data", [("latin1_name.stl", stl_ascii(name="pi\xe8ce")),
                                       ("binary_says_solid.stl", stl_binary()),
                                       ("latin1_comment.ply", ply_text())])
def test_valid_binary_and_ply_files_accepted(tmp_path, capsys, name, data):
    code, err, out = run(tmp_path, capsys, name, data)
    assert code == 0, err
    Vo, Fo, UV, _ = formats.load_uv_obj(out)
    assert len(Vo) == 16 and len(Fo) == len(F4) and np.isfinite(UV).all()  # STL: float32, corners merged


def test_negative_and_positive_indices_read_the_same(tmp_path):
    a, b = tmp_path / "a.obj", tmp_path / "b.obj"
    a.write_text(obj_text())
    b.write_text(obj_text(neg=True))
    for (Va, Fa), (Vb, Fb) in [(formats.load_mesh(a), formats.load_mesh(b))]:
        assert np.array_equal(Va, Vb) and np.array_equal(Fa, Fb) and np.array_equal(Fa, F4)


def test_unreferenced_vertex_before_the_border(tmp_path, capsys):
    """A face removed leaves vertex 12 (a border corner) unreferenced, before border vertices 13-15: the stages
    work on the compact mesh and must index its loops there (an IndexError in LSCM, found by the fuzz)."""
    F = F4[~(F4 == 12).any(axis=1)]
    code, err, out = run(tmp_path, capsys, "hole_in_index.obj", obj_text(F=F))
    assert code == 0, err
    Vo, Fo, UV, _ = formats.load_uv_obj(out)
    assert np.array_equal(Vo, V4) and np.array_equal(Fo, F) and np.isfinite(UV).all()


# ----------------------------------------------------------------------------------------------------------
# malformed and junk files: refused in one line naming the file
# ----------------------------------------------------------------------------------------------------------
JUNK = bytes(np.random.default_rng(7).integers(0, 256, 3000, dtype=np.uint8))
REFUSED = [
    ("junk.stl", JUNK, "binary STL"),
    ("junk.off", JUNK, "cannot read"),
    ("junk.ply", b"ply\n" + JUNK, "cannot read"),
    ("junk.obj", JUNK, "no triangles"),
    ("junk.glb", JUNK, "not a valid GLB file"),
    ("empty.stl", b"", "not an STL file"),
    ("empty.off", b"", "empty"),
    ("truncated_binary.stl", stl_binary()[:-7], "truncated or corrupt binary STL"),
    ("odd_vertex_count.stl", stl_ascii().replace(b"vertex 0.0 0.0", b"vrtx 0.0 0.0", 1), "not a multiple of 3"),
    ("nan_text.stl", stl_ascii().replace(b"vertex 0.0 0.0", b"vertex zero 0.0", 1), "not a number"),
    ("index_zero.obj", obj_text().replace("f 1 ", "f 0 ", 1), "index 0"),
    ("relative_before_start.obj", "v 0 0 0\nv 1 0 0\nf -1 -2 -3\n", "before the first vertex"),
    ("one_corner.obj", obj_text() + "f 1\n", "at least 3 corners"),
    ("edges_only.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\nl 2 3\n", "only lines or curves (2): a wireframe"),
    ("word_coordinate.obj", obj_text().replace("v 0.0", "v zero", 1), "not a number"),
    ("word_index.obj", obj_text().replace("f 1 ", "f one ", 1), "not a vertex index"),
    ("out_of_range.obj", obj_text() + "f 1 2 99\n", "out of range"),
    ("truncated_vertices.off", "OFF\n16 18 0\n0 0 0\n1 0 0\n", "ends after 2 of the 16 vertices"),
    ("truncated_faces.off", "".join(off_text().splitlines(True)[:-2]), "ends after 16 of the 18 faces"),
    ("huge_counts.off", "OFF\n999999999999 999999999999 0\n0 0 0\n", "ends after 1 of the 999999999999"),
    ("binary.off", b"OFF BINARY\n\x00\x00\x00\x10" + JUNK[:64], "binary OFF"),
    ("four_d.off", "4OFF\n3 1 0\n0 0 0 1\n1 0 0 1\n0 1 0 1\n3 0 1 2\n", "4D"),
    ("float_index.off", off_text().replace("3 0 1 5", "3 0 1.5 5", 1), "not a whole number"),
    ("two_corner_face.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n", "at least 3 corners"),
    ("short_face.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n", "announces 3 corners"),
    ("not_off.off", "HELLO\n1 2 3\n", "expected the 'OFF' header"),
    ("no_header_end.ply", b"ply\nformat ascii 1.0\nelement vertex 3\n", "not a PLY file"),
    ("huge_element.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 999999999999\nproperty float x\n"
     b"property float y\nproperty float z\nend_header\n\x00\x00\x80\x3f", "cannot read"),
    ("nan_coordinate.off", off_text().replace("1.0 0.0", "nan 0.0", 1), "NaN"),
]


@pytest.mark.parametrize("name,data,expect", REFUSED, ids=[r[0] for r in REFUSED])
def test_bad_files_refused_in_one_line(tmp_path, capsys, name, data, expect):
    assert_refused(*run(tmp_path, capsys, name, data), expect)


def test_non_manifold_file_becomes_an_atlas(tmp_path, capsys):
    """A face added on an interior edge (three faces on it) was refused as non-manifold; the repair splits it
    (lossless) and the mesh flattens as an atlas: exit 0, finite UVs, v and faces as read."""
    code, err, out = run(tmp_path, capsys, "duplicated_face.obj", obj_text() + "f 1 2 6\n")
    assert code == 0 and "Traceback" not in err, err
    V, F, UV, FUV = formats.load_uv_obj(out)
    assert np.isfinite(UV).all() and len(F) == obj_text().count("\nf ") + 1


@pytest.mark.parametrize("name", ["junk.obj", "junk.stl", "junk.off"])
def test_reader_errors_name_the_file(tmp_path, capsys, name):
    data = {"junk.obj": obj_text().replace("f 1 ", "f 0 ", 1), "junk.stl": JUNK, "junk.off": "OFF\n3 1\n0 0\n"}[name]
    code, err, out = run(tmp_path, capsys, name, data)
    assert_refused(code, err, out, "cannot read", name=str(tmp_path / name))


# ----------------------------------------------------------------------------------------------------------
# evaluate: any OBJ with vt
# ----------------------------------------------------------------------------------------------------------
UV_OBJ = obj_text(corner="{v}/{v}").replace("f ", "".join(f"vt {x!r} {y!r}\n" for x, y, _ in V4.tolist()) + "f ", 1)


@pytest.mark.parametrize("name,text,expect", [
    ("latin1.obj", "# r\xe9sum\xe9 \xa9\n" + UV_OBJ.replace("v 0.0 0.0", "v 0.0 \\\n 0.0", 1), None),
    ("bad_vt.obj", UV_OBJ.replace("vt 0.0 0.0", "vt x 0.0", 1), "(line 17): malformed OBJ line"),
    ("no_vt.obj", obj_text(), "no texture coordinates"),
])
def test_evaluate_hostile(tmp_path, capsys, name, text, expect):
    src = tmp_path / name
    src.write_bytes(text.encode("latin-1"))
    code = main(["evaluate", str(src), "--quiet"])
    err = capsys.readouterr().err
    if expect is None:
        assert code == 0, err
    else:
        assert code == 2 and err.count("\n") == 1 and expect in err, err
        assert not any(leak in err for leak in LEAKS), err


# ----------------------------------------------------------------------------------------------------------
# geodesics: source indices and time steps
# ----------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("extra,expect", [
    (("--source", "99999999999999999999"), "out of range"),
    (("--source", "-1"), "out of range"),
    (("--source", "16"), "out of range"),
    (("--time-step", "inf"), "--time-step"),
    (("--t-coef", "inf"), "--t-coef"),
])
def test_geodesics_bad_sources_and_time_steps(tmp_path, capsys, extra, expect):
    code, err, out = run(tmp_path, capsys, "g.obj", obj_text(), *extra, cmd="geodesics")
    assert_refused(code, err, out, expect)


@pytest.mark.parametrize("coef", ["1e300", "1e-300", "1e-12", "1e12"])
def test_geodesics_never_write_nan(tmp_path, capsys, coef):
    code, err, out = run(tmp_path, capsys, "g.obj", obj_text(), "--t-coef", coef, cmd="geodesics")
    if code == 0:
        assert np.isfinite(np.load(out)).all()
    else:  # refused by the options table (--t-coef) or the heat method (its time step)
        assert_refused(code, err, out, "t-coef" if "--t-coef" in err else "time step")


# ----------------------------------------------------------------------------------------------------------
# numerical failures inside: a fallback, reported, never NaN
# ----------------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def limbs():
    """Thin limbs on a curved surface with exactly degenerate slivers and needles (5% each): libigl's LSCM
    fails, the heat geodesics and MDS are non-finite, the polish's scaffold meets coincident boundary points."""
    V, F = thin_limbs_disk(n_limbs=6, limb_length=4.0, limb_width=0.02, h=0.03, bend=2.0, twist=1.0)
    return degrade(V, F, slivers=0.05, needles=0.05, squeeze=0.0), F


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # zero-area faces: the heat stage divides by zero areas
def test_thin_limbs_with_slivers_fall_back_to_tutte(tmp_path, limbs):
    V, F = limbs
    src, out, rep = tmp_path / "limbs.obj", tmp_path / "o.obj", tmp_path / "r.json"
    formats.save_uv_obj(src, V, F, np.zeros((len(V), 2)))
    assert main(["unwrap", str(src), "-o", str(out), "--report", str(rep), "--quiet"]) == 0
    import json

    r = json.loads(rep.read_text())
    start = r["method"]["refine"]["start"]
    # the slivers' conformal layout (mollified cotangents) folds beyond repair, as it failed before mollification
    assert start["layout"] == "tutte" and ("conformal_failed" in start or start["conformal_flips"] > 0)
    # MDS is no start either: non-finite (degenerate faces) or, since the operators keep every intrinsic triangle
    # valid (operators._consistent_lengths), folded beyond repair
    assert "mds_rejected" in start or (start["flips"] > 0 and not start["repair"]["repaired"])
    _, _, UV, _ = formats.load_uv_obj(out)
    assert np.isfinite(UV).all()
    assert r["metrics"]["flips"] == 0 and r["metrics"]["boundary_crossings"] == 0


def test_thin_limbs_conformal_failure_is_a_heatparam_error():
    from heatparam import HeatparamError
    from heatparam.layout import conformal as mds

    V, F = thin_limbs_disk(n_limbs=4, limb_length=2.5, limb_width=0.03, h=0.05, bend=1.0, twist=0.5)
    V = degrade(V, F, slivers=0.02, needles=0.02, squeeze=1e-6)
    # igl::lscm failed here with a RuntimeError (a traceback); the spectral conformal map (no pins) solves it: either
    # way the answer is a finite layout or a one-line HeatparamError
    try:
        uv = mds.conformal_layout(V, F)
    except HeatparamError as exc:
        assert "conformal layout failed" in str(exc)
    else:
        assert np.isfinite(uv).all()
    V[F[0, 0]] = np.inf  # non-finite geometry: the factorization cannot be trusted
    with pytest.raises(HeatparamError, match="conformal layout failed"):
        mds.conformal_layout(V, F)


def test_refine_rejects_a_non_finite_start():
    from heatparam import datasets, refine
    from heatparam.refine import start

    sh = datasets.flat_disk(h=0.15)
    bad = np.full((len(sh.V), 2), np.nan)
    x, rep = refine.refine(sh.V, sh.F, bad, lscm=start.LscmStart(None, -1, -1, None, "forced"))
    # the flat disk's projection onto its plane is an isometry, the start once MDS and the conformal layout fail
    assert rep["start"]["mds_rejected"] == "non-finite coordinates" and rep["start"]["layout"] == "projection"
    assert np.isfinite(x).all() and rep["bijective"]


def test_polish_solver_failure_keeps_the_last_bijective_layout(monkeypatch):
    from heatparam import datasets
    from heatparam.layout import tutte
    from heatparam.refine import energy, newton

    sh = datasets.flat_disk(h=0.15)
    g, area = energy.surface_gradients(sh.V, sh.F)
    loops = [tutte.build_disk(sh.V, sh.F).outer]
    x0 = tutte.tutte(sh.V, tutte.build_disk(sh.V, sh.F))

    def boom(*a, **k):
        raise RuntimeError("The Pardiso solver failed with error code -4")

    monkeypatch.setattr(newton, "newton_direction", boom)
    x, info = newton.polish(x0, sh.F, g, area, loops)
    assert "numerical failure" in info["stop"] and np.array_equal(x, x0)


def test_refine_never_hands_on_a_non_finite_polish(monkeypatch):
    from heatparam import datasets, refine

    sh = datasets.flat_disk(h=0.15)

    class NanPolish:  # what multilevel_polish hands back (a newton.Polish), gone non-finite
        done = True

        def __init__(self, x):
            self.x = np.full_like(x, np.nan)

        def report(self):
            return {"stop": "converged"}

    def nan_polish(V, F, x, *a, **k):
        return NanPolish(x), {"levels": 1}

    monkeypatch.setattr(refine, "multilevel_polish", nan_polish)  # as refine() calls it
    x, rep = refine.refine(sh.V, sh.F, None)
    assert np.isfinite(x).all() and "start layout is kept" in rep["polish"]["fallback"] and rep["bijective"]


def test_unexpected_failure_is_one_line(tmp_path, capsys, monkeypatch):
    import heatparam.pipeline

    def boom(*a, **k):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(heatparam.pipeline, "parameterize", boom)
    code, err, out = run(tmp_path, capsys, "g.obj", obj_text())
    assert_refused(code, err, out, "the computation failed")


# ----------------------------------------------------------------------------------------------------------
# Ctrl-C at any moment
# ----------------------------------------------------------------------------------------------------------
def test_interrupt_swallowed_by_a_library_is_not_lost(tmp_path, monkeypatch):
    """trimesh's import catches BaseException: the flag survives it, the import and the write re-raise it."""
    (tmp_path / "swallower.py").write_text(
        "import os, signal, time\ntry:\n    os.kill(os.getpid(), signal.SIGINT)\n    time.sleep(0.5)\n"
        "except BaseException:\n    pass\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    out = tmp_path / "o.txt"
    with interrupt.handling():
        with pytest.raises(KeyboardInterrupt):
            interrupt.guarded_import("swallower")
        with pytest.raises(KeyboardInterrupt), formats.atomic_write(out) as fh:
            fh.write("x")
    assert not out.exists() and not list(tmp_path.glob(".*.tmp"))
    assert signal.getsignal(signal.SIGINT) is not interrupt._handler  # restored


def test_interrupt_in_importlib_machinery_is_noted_then_raised():
    """A SIGINT that lands in importlib's own code (a module lock's weakref callback, where a raised exception is
    only printed, traceback and all, and the run goes on) is noted; the next check raises it. Elsewhere the handler
    raises at once."""
    import sys
    from types import SimpleNamespace

    in_importlib = SimpleNamespace(f_code=SimpleNamespace(co_filename="<frozen importlib._bootstrap>"))
    with interrupt.handling():
        interrupt._handler(signal.SIGINT, in_importlib)  # no exception here
        assert interrupt.interrupted()
        with pytest.raises(KeyboardInterrupt):
            interrupt.check()
    with interrupt.handling(), pytest.raises(KeyboardInterrupt):
        interrupt._handler(signal.SIGINT, sys._getframe())


def test_ctrl_c_at_any_moment_is_clean(tmp_path):
    """SIGINT from the interpreter's start to the end of the run: exit 130 (or, before Python has installed any
    handler, the signal's own exit), at most one line, never a traceback, no output written, old output kept."""
    from heatparam.formats.meshuv import write_glb

    src = tmp_path / "in.glb"  # a GLB: trimesh is imported, whose import swallows KeyboardInterrupt
    V, F = grid(12)
    write_glb(src, V, V[:, :2], F, np.arange(len(V)))
    env = dict(os.environ, PYTHONPATH=SRC)
    cmd = [sys.executable, "-m", "heatparam", "unwrap", str(src), "-o", str(tmp_path / "o.obj"), "--quiet"]
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import heatparam.__main__"], env=env, timeout=60)
    # until heatparam's main() runs no handler can exist (README says so): the interpreter's start, the package
    # and its __main__ module loaded (a Ctrl-C 35 ms in, while runpy compiled __main__, was Python's traceback)
    startup = time.perf_counter() - t0
    t0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    total = time.perf_counter() - t0
    assert done.returncode == 0, done.stderr
    (tmp_path / "o.obj").unlink()
    existing = tmp_path / "kept.obj"
    for k, d in enumerate(np.linspace(2 * startup, 0.9 * total, 10)):
        out = tmp_path / f"o{k}.obj"
        cmd[-2] = str(out if k % 2 else existing)
        if k % 2 == 0:
            existing.write_text("previous content\n")
        p = subprocess.Popen(cmd, env=env, stderr=subprocess.PIPE, text=True)
        time.sleep(d)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=300)
        assert "Traceback" not in err and err.count("\n") <= 1, (d, err)
        if p.returncode == 0:  # the run had finished, or was writing (it completes its outputs first)
            assert out.exists() if k % 2 else existing.read_text() != "previous content\n"
            continue
        assert p.returncode in (130, -signal.SIGINT), (d, p.returncode, err)
        target = out if k % 2 else existing  # this run's output: absent, or the old content kept
        assert (not target.exists() if k % 2 else target.read_text() == "previous content\n"), (d, p.returncode, err)
        assert not list(tmp_path.glob(".*.tmp"))


# ----------------------------------------------------------------------------------------------------------
# every refusal in words (issue 45): no None, no repr, no exception class, no nan; one line that says what to do
# ----------------------------------------------------------------------------------------------------------
LINE = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]])  # a mesh of zero-area faces only
LINE_F = np.array([[0, 2, 1], [1, 2, 3]])
V_NAN = V4.copy()
V_NAN[3, 1] = np.nan
F_OUT = F4.copy()
F_OUT[2, 1] = 99
WRITERS = {
    "obj": lambda V, F: obj_text(V, F).encode(),
    "off": lambda V, F: off_text(V, F).encode(),
    "stl": lambda V, F: stl_binary(V, F),
    "ply": lambda V, F: ply_bytes(V, F.tolist()),
    "be.ply": lambda V, F: ply_bytes(V, F.tolist(), fmt="binary_big_endian"),
}


def _bad_files():
    """(name, bytes) of every kind of bad file, in every format: empty, truncated, junk, junk after a header, no
    faces, indices out of range, NaN coordinates, zero-area faces only, wrong counts."""
    for fmt, make in WRITERS.items():
        good = make(V4, F4)
        yield f"empty.{fmt}", b""
        yield f"truncated.{fmt}", good[:len(good) // 2]
        yield f"junk.{fmt}", JUNK
        yield f"header_then_junk.{fmt}", good[:60] + JUNK
        yield f"nan.{fmt}", make(V_NAN, F4)
        yield f"zero_area_only.{fmt}", make(LINE, LINE_F)
        if fmt != "stl":  # (an STL has no vertices apart from its triangles)
            yield f"point_cloud.{fmt}", make(V4, np.zeros((0, 3), dtype=np.int64))
            yield f"out_of_range.{fmt}", make(V4, F_OUT)
    yield "counts.off", off_text().replace("OFF\n16 18", "OFF\n16 30").encode()
    yield "counts.ply", ply_bytes(V4, F4.tolist(), fmt="binary_little_endian").replace(b"face 18", b"face 40")
    yield "counts_ascii.ply", ply_bytes(V4, F4.tolist()).replace(b"vertex 16", b"vertex 20")
    yield "junk.glb", JUNK
    yield "empty.glb", b""


BAD_FILES = dict(_bad_files())


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_every_bad_file_is_refused_in_words(tmp_path, capsys, name):
    code, err, out = run(tmp_path, capsys, name, BAD_FILES[name])
    assert_refused(code, err, out, "")
    assert not leaked(err), err
    if name.startswith("point_cloud"):
        assert err.endswith("no faces: a point cloud; mesh it first, e.g. by Poisson reconstruction\n"), err


@pytest.mark.parametrize("fmt", ["binary_little_endian", "binary_big_endian"])
def test_tristrip_ply_unwraps(tmp_path, capsys, fmt):
    """A strip PLY with -1 restarts (rows of a grid) flattens like the same faces."""
    strip = [v for j in range(3) for v in [*(x for i in range(4) for x in ((j + 1) * 4 + i, j * 4 + i)), -1]][:-1]
    code, err, out = run(tmp_path, capsys, "strips.ply", ply_bytes(V4, strips=[strip], fmt=fmt))
    assert code == 0, err
    Vo, Fo, UV, _ = formats.load_uv_obj(out)
    assert len(Fo) == len(F4) and np.isfinite(UV).all() and np.allclose(Vo, V4)


def _closed_with_zero_area_face():
    from heatparam import datasets

    return split_edge(*datasets.closed_cube(n=3), 4)


@pytest.mark.parametrize("case", ["repeat", "quads", "float_index", "words", "no_faces", "none_faces", "inf",
                                  "zero_area_only", "zero_area_closed"])
def test_every_array_refusal_is_in_words(case):
    import heatparam

    V, F = {"repeat": (V4, np.vstack([F4, [[0, 0, 1]]])), "quads": (V4, QUADS), "float_index": (V4, F4 + 0.5),
            "words": (np.full((4, 3), "x"), F4[:2]), "no_faces": (V4, np.zeros((0, 3), dtype=int)),
            "none_faces": (V4, None), "inf": (np.where(np.arange(16)[:, None] == 2, np.inf, V4), F4),
            "zero_area_only": (LINE, LINE_F), "zero_area_closed": (LINE, np.array([[0, 1, 2], [0, 2, 1]]))}[case]
    with pytest.raises(heatparam.HeatparamError) as exc:
        heatparam.parameterize(V, F)
    msg = str(exc.value)
    assert "\n" not in msg and " — " in msg and not leaked(msg), msg  # what is wrong — what to do


def test_zero_area_faces_unwrap_and_their_warnings_are_in_words(tmp_path, capsys):
    import json

    V, F = _closed_with_zero_area_face()
    code, err, out = run(tmp_path, capsys, "zero.obj", obj_text(V, F), "--report", str(tmp_path / "r.json"))
    assert code == 0, err
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["mesh"]["zero_area_faces"] == 1 and rep["metrics"]["flips"] == 0
    assert not [w for w in rep["warnings"] if leaked(w)], rep["warnings"]


@pytest.mark.parametrize("name,value", [("refine", "bogus"), ("max_distortion", 0.5), ("max_distortion", float("nan")),
                                        ("pack", "x"), ("padding", -1), ("seed", 1.5), ("fill", None),
                                        ("t_coef", float("nan")), ("time_step", "bogus"), ("nonexistent", 1)])
def test_every_bad_option_value_is_refused_in_words(tmp_path, capsys, name, value):
    """Through the API (the value echoed as given, nothing else of Python's) and, where it can be typed, the CLI."""
    import heatparam

    with pytest.raises(heatparam.HeatparamError) as exc:
        heatparam.parameterize(V4, F4, **{name: value})
    assert "\n" not in str(exc.value) and not leaked(str(exc.value), value), exc.value
    if value is None or name == "nonexistent":
        return
    code, err, out = run(tmp_path, capsys, "g.obj", obj_text(), f"--{name.replace('_', '-')}", str(value))
    assert_refused(code, err, out, "")
    assert not leaked(err, value), err


def test_a_folder_as_input_says_so(tmp_path, capsys):
    out = tmp_path / "out.obj"
    out.write_text("previous content\n")
    code = main(["unwrap", str(tmp_path), "-o", str(out), "--quiet"])
    assert_refused(code, capsys.readouterr().err, out, "a folder, not a mesh file")
