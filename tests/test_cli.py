"""Command line: round trip, subcommands, and one test per bad-input case (exit 2, one line, no file)."""

import json
import re
import subprocess
import sys

import numpy as np
import pytest

from heatparam import datasets, formats
from heatparam.cli import DEMO_DESCRIPTION, build_parser, main
from heatparam.options import GROUPS, cli_options

from conftest import shared_mesh


def write_off(path, V, F):
    with open(path, "w") as fh:
        fh.write(f"OFF\n{len(V)} {len(F)} 0\n")
        np.savetxt(fh, V, fmt="%.17g")
        np.savetxt(fh, np.column_stack([np.full(len(F), 3), F]), fmt="%d")


@pytest.fixture(scope="module")
def patch_off(tmp_path_factory):
    sh = datasets.cylinder_patch(h=0.08)
    p = tmp_path_factory.mktemp("in") / "patch.off"
    write_off(p, sh.V, sh.F)
    return p, sh


def test_unwrap_round_trip(tmp_path, patch_off):
    src, sh = patch_off
    out, rep, prev = tmp_path / "out.obj", tmp_path / "r.json", tmp_path / "p.png"
    before = src.read_bytes()
    code = main(["unwrap", str(src), "-o", str(out), "--report", str(rep), "--preview", str(prev), "--quiet",
                 "--fill", "none"])
    assert code == 0
    assert src.read_bytes() == before  # the input is never touched
    V, F, UV, FUV = formats.load_uv_obj(out)
    assert np.allclose(V, sh.V, rtol=0, atol=1e-15)  # vertices in input order, exactly
    assert np.array_equal(F, sh.F) and np.array_equal(FUV, sh.F)  # every face has vt, one vt per vertex
    assert UV.shape == (len(sh.V), 2)
    r = json.loads(rep.read_text())
    for key in ("parameters", "timings_s", "mesh", "metrics"):
        assert key in r
    assert r["mesh"]["boundary_loops"] == 1 and r["metrics"]["flips"] == 0
    assert prev.stat().st_size > 10_000 and prev.read_bytes()[:4] == b"\x89PNG"
    assert not list(tmp_path.glob(".*.tmp"))  # no temporary files left behind


def test_each_output_has_a_log_line_and_the_total_counts_them(tmp_path, patch_off, capsys):
    src, _ = patch_off
    out, svg, rep = tmp_path / "out.obj", tmp_path / "out.svg", tmp_path / "r.json"
    assert main(["unwrap", str(src), "-o", str(out), "-o", str(svg), "--report", str(rep), "--fill", "none"]) == 0
    err = capsys.readouterr().err
    assert "heatparam: write out.obj: " in err and "heatparam: write out.svg: " in err
    timings = json.loads(rep.read_text())["timings_s"]
    assert "write obj" in timings and "write svg" in timings  # the report is written last: not its own time
    total = float(err.strip().splitlines()[-1].rsplit(", ", 1)[1].removesuffix(" s"))
    assert total >= sum(timings.values()) - 0.01


def test_evaluate_prints_metrics(tmp_path, patch_off, capsys):
    src, _ = patch_off
    out = tmp_path / "out.obj"
    assert main(["unwrap", str(src), "-o", str(out), "--quiet", "--fill", "none"]) == 0
    capsys.readouterr()
    rep = tmp_path / "eval.json"
    assert main(["evaluate", str(out), "--report", str(rep)]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["flips"] == 0 and "iso_mean" in printed
    assert json.loads(rep.read_text())["metrics"] == printed


def test_geodesics_command(tmp_path, patch_off):
    src, sh = patch_off
    out = tmp_path / "d.npy"
    assert main(["geodesics", str(src), "--source", "0", "5", "-o", str(out), "--quiet"]) == 0
    D = np.load(out)
    assert D.shape == (len(sh.V), 2) and D[0, 0] == 0 and D[5, 1] == 0


def test_demo(tmp_path):
    assert main(["demo", "-o", str(tmp_path / "demo"), "--quiet"]) == 0
    for name in ("demo.obj", "demo-report.json", "demo-preview.png"):
        assert (tmp_path / "demo" / name).stat().st_size > 0
    # demo --help says what the run does: the heat stage runs, and the conformal layout wins the start
    report = json.loads((tmp_path / "demo" / "demo-report.json").read_text())
    start = report["method"]["refine"]["start"]
    assert report["method"]["geodesics"] in ("landmarks", "all-pairs") and start["layout"] == "conformal"
    assert "heat geodesics and MDS" in DEMO_DESCRIPTION and "the conformal one wins" in DEMO_DESCRIPTION


def _help(command: str, columns: int, monkeypatch) -> str:
    monkeypatch.setenv("COLUMNS", str(columns))  # argparse's width: shutil.get_terminal_size reads it first
    return build_parser()._subparsers._group_actions[0].choices[command].format_help()


@pytest.mark.parametrize("command", ["unwrap", "batch"])
@pytest.mark.parametrize("columns", [80, 100])
def test_help_is_short_grouped_and_has_examples(command, columns, monkeypatch):
    text = _help(command, columns, monkeypatch)
    assert len(text.splitlines()) <= 80, len(text.splitlines())
    assert "§" not in text and not re.search(r"\bstop \d", text, re.IGNORECASE)
    assert "\nexamples:\n  heatparam " + command in text and "docs/options.md" in text
    for title in GROUPS.values():
        assert f"\n{title}:\n" in text
    assert "\noptions:\n" not in text  # every flag sits in a group, --help in the last


def test_unwrap_help_one_line_per_option(monkeypatch):
    """At 100 columns every option's flag, its one-line help and its default share one line."""
    lines = _help("unwrap", 100, monkeypatch).splitlines()
    for o in cli_options():
        line = next(x for x in lines if x.strip().startswith(o.flag + " "))
        assert line.endswith(f"{o.short} (default: {o.default})"), line
    for flag in ("-o OUT, --output OUT", "--report", "--preview", "--units", "--sheet", "--strain-map",
                 "--fit-tolerance", "--quiet", "-h, --help"):
        line = next(x for x in lines if x.strip().startswith(flag))
        assert len(line.split("  ", 2)[-1].strip()) > 10, line  # the help beside the flag, not below


def test_unwrap_groups_in_order():
    unwrap = build_parser()._subparsers._group_actions[0].choices["unwrap"]
    titles = [g.title for g in unwrap._action_groups if g._group_actions]
    assert titles == ["positional arguments", "outputs", *GROUPS.values()]
    run = next(g for g in unwrap._action_groups if g.title == GROUPS["run"])
    assert [a.option_strings[-1] for a in run._group_actions] == ["--solver", "--seed", "--quiet", "--help"]


def test_top_level_help_names_what_unwrap_writes(monkeypatch):
    from heatparam.formats.exporters import map_formats

    monkeypatch.setenv("COLUMNS", "100")
    text = build_parser().format_help()
    line = next(x for x in text.splitlines() if x.strip().startswith("unwrap"))
    assert all(f.upper() in line for f in map_formats()) and "OBJ with UVs" not in line
    unwrap = _help("unwrap", 100, monkeypatch)
    assert "atlas" in unwrap.split("positional arguments")[0]  # the description: not only disks


@pytest.mark.parametrize("argv, flag", [(["--max-distortion", "0.5"], "--max-distortion"),
                                        (["--landmarks", "2"], "--landmarks")])
def test_cross_checked_values_are_refused_by_their_flag(tmp_path, patch_off, capsys, argv, flag):
    """Values the table's range allows but the validation's cross-checks refuse (cmd_unwrap's make_options) are
    named by their flag, as the parse-time refusals are."""
    src, _ = patch_off
    out = tmp_path / "o.obj"
    assert main(["unwrap", str(src), "-o", str(out), "--quiet", *argv]) == 2
    err = capsys.readouterr().err
    api = flag.removeprefix("--").replace("-", "_")
    assert err.startswith(f"heatparam: error: {flag} must be") and api not in err.replace(flag, "")
    assert err.count("\n") == 1 and not out.exists()


def test_out_of_range_value_named_once_by_its_flag(tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["unwrap", "in.obj", "-o", str(tmp_path / "o.obj"), "--max-distortion", "200"])
    err = capsys.readouterr().err
    assert "argument --max-distortion: must be between 0 and 100; got 200 " in err and "max_distortion" not in err


def test_console_script_bad_input_no_traceback(tmp_path):
    bad = tmp_path / "x.off"
    bad.write_text("this is not a mesh\n")
    r = subprocess.run([sys.executable, "-m", "heatparam.cli", "unwrap", str(bad), "-o", str(tmp_path / "o.obj")],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert not (tmp_path / "o.obj").exists()


def _bad_case(tmp_path, capsys, name, text, expect):
    src = tmp_path / name
    src.write_text(text)
    out = tmp_path / "out.obj"
    out.write_text("previous content\n")  # an existing output must survive a failed run
    code = main(["unwrap", str(src), "-o", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("heatparam: error:") and err.count("\n") == 1, err
    assert expect in err, err
    assert out.read_text() == "previous content\n"
    assert not list(tmp_path.glob(".*.tmp"))


QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"


@pytest.mark.parametrize(
    "name,text,expect",
    [
        ("empty.obj", "", "no triangles"),
        ("garbage.off", "OFF\n3 1 0\nnot numbers at all\n", "cannot read"),
        ("nan.obj", QUAD.replace("v 1 1 0", "v nan 1 0") + "f 1 2 3\nf 1 3 4\n", "NaN"),
        ("inf.obj", QUAD.replace("v 1 1 0", "v inf 1 0") + "f 1 2 3\nf 1 3 4\n", "infinite"),
        ("range.off", "OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 9\n", "out of range"),
        ("unknown.xyz", "1 2 3\n", "unsupported format"),
    ],
)
def test_bad_input(tmp_path, capsys, name, text, expect):
    _bad_case(tmp_path, capsys, name, text, expect)


@pytest.mark.parametrize(
    "name,text,charts",
    [
        ("nonmanifold_edge.obj", QUAD + "v 0.5 0.5 1\nf 1 2 3\nf 1 3 4\nf 1 3 5\n", 2),
        ("bowtie.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv -1 0 0\nv 0 -1 0\nf 1 2 3\nf 1 4 5\n", 2),
        ("two_parts.obj", QUAD + "v 5 5 0\nv 6 5 0\nv 6 6 0\nf 1 2 3\nf 1 3 4\nf 5 6 7\n", 2),
        ("flipped.obj", QUAD + "f 1 2 3\nf 1 4 3\n", 2),
        ("tetra.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n", 1),
    ],
)
def test_what_was_refused_for_its_topology_becomes_an_atlas(tmp_path, name, text, charts):
    """Non-manifold edges and vertices, several parts, inconsistent orientation, closed surfaces: these were
    refused; now repaired losslessly (v and faces as read) and flattened as an atlas of at least ``charts``."""
    src, out, rep = tmp_path / name, tmp_path / "out.obj", tmp_path / "r.json"
    src.write_text(text)
    assert main(["unwrap", str(src), "-o", str(out), "--report", str(rep), "--quiet"]) == 0
    from heatparam import formats

    V, F = formats.load_mesh(src)
    Vo, Fo, UV, FUV = formats.load_uv_obj(out)
    assert np.array_equal(Vo, V) and np.array_equal(Fo, F) and np.isfinite(UV).all()
    m = json.loads(rep.read_text())["metrics"]
    assert m["charts"] >= charts and m["flips"] == 0 and m["overlapping_triangle_pairs"] == 0


def test_missing_file(tmp_path, capsys):
    code = main(["unwrap", str(tmp_path / "nope.obj"), "-o", str(tmp_path / "o.obj")])
    assert code == 2 and "no such file" in capsys.readouterr().err


def test_closed_mesh_becomes_an_atlas(tmp_path):
    """cow.off (closed, genus 0) was refused; now an atlas: one vt per chart corner, v and faces unchanged,
    bijective with no overlap across charts (tests/atlas has the properties on cow, 3holes and the bunny)."""
    from heatparam import formats

    out, rep = tmp_path / "o.obj", tmp_path / "o.json"
    src = shared_mesh("cow.off")
    assert main(["unwrap", str(src), "-o", str(out), "--report", str(rep), "--quiet"]) == 0
    V, F = formats.load_mesh(src)
    Vo, Fo, UV, FUV = formats.load_uv_obj(out)
    assert np.array_equal(Vo, V) and np.array_equal(Fo, F) and len(UV) > len(V)
    m = json.loads(rep.read_text())["metrics"]
    assert m["charts"] > 1 and m["flips"] == 0 and m["overlapping_triangle_pairs"] == 0 and m["iso_mean"] <= 1.05
    ev = tmp_path / "ev.json"  # judged again from the written file, as any tool's map
    assert main(["evaluate", str(out), "--report", str(ev), "--quiet"]) == 0
    e = json.loads(ev.read_text())["metrics"]
    assert e["flips"] == 0 and e["boundary_crossings"] == 0 and e["iso_mean"] == pytest.approx(m["iso_mean"])


def test_zero_area_faces_handled_and_reported(tmp_path):
    sh = datasets.cylinder_patch(h=0.08)
    V, F = sh.V.copy(), sh.F.copy()
    # collapse one interior triangle onto a line: move a vertex onto the midpoint of the opposite edge
    f = F[len(F) // 2]
    V[f[2]] = 0.5 * (V[f[0]] + V[f[1]])
    src = tmp_path / "degenerate.off"
    write_off(src, V, F)
    rep = tmp_path / "r.json"
    assert main(["unwrap", str(src), "-o", str(tmp_path / "o.obj"), "--report", str(rep), "--quiet",
                 "--fill", "none"]) == 0
    r = json.loads(rep.read_text())
    assert r["mesh"]["zero_area_faces"] >= 1
    assert r["method"]["mollified_edge_length"] > 0
    assert any("zero-area" in w for w in r["warnings"])


def test_output_equal_to_input_refused(tmp_path, patch_off, capsys):
    src, _ = patch_off
    obj = tmp_path / "in.obj"
    formats.save_uv_obj(obj, *formats.load_mesh(src), np.zeros((len(formats.load_mesh(src)[0]), 2)))
    before = obj.read_bytes()
    assert main(["unwrap", str(obj), "-o", str(obj), "--quiet"]) == 2
    assert "is the input" in capsys.readouterr().err
    assert obj.read_bytes() == before


def test_all_pairs_guard(tmp_path, patch_off, capsys, monkeypatch):
    from heatparam import heat, memory, pipeline

    src, sh = patch_off
    raw, full = pipeline.RAW_BYTES_PER_VERTEX * len(sh.V), heat.all_pairs_bytes(len(sh.V))
    assert raw < full  # room for the landmark path's estimate, not for the n x n matrix
    monkeypatch.setattr(memory, "available_bytes", lambda: 0.5 * (raw + full) / memory.SAFETY_FRACTION)
    out = tmp_path / "o.obj"
    assert main(["unwrap", str(src), "-o", str(out), "--geodesics", "all-pairs", "--quiet", "--fill", "none",
                 "--refine", "none"]) == 2
    err = capsys.readouterr().err
    assert "GiB" in err and "landmarks" in err and not out.exists()


def test_refinement_memory_guard(tmp_path, patch_off, capsys, monkeypatch):
    """A mesh whose refinement would not fit is refused up front (exit 2, one line, nothing written)."""
    from heatparam import memory, pipeline, refine

    src, sh = patch_off
    out = tmp_path / "o.obj"
    raw = pipeline.RAW_BYTES_PER_VERTEX * len(sh.V)
    need = raw + refine.polish_bytes(len(sh.F))
    monkeypatch.setattr(memory, "available_bytes", lambda: 0.9 * need / memory.SAFETY_FRACTION)
    assert main(["unwrap", str(src), "-o", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "refining" in err and "--refine none" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
    # not even the raw map fits: the advice is to decimate
    monkeypatch.setattr(memory, "available_bytes", lambda: 0.9 * raw / memory.SAFETY_FRACTION)
    assert main(["unwrap", str(src), "-o", str(out), "--quiet", "--refine", "none"]) == 2
    err = capsys.readouterr().err
    assert "decimate" in err and len(err.strip().splitlines()) == 1 and not out.exists()


def test_negative_refine_multilevel_is_refused(tmp_path, patch_off, capsys):
    src, _ = patch_off
    out = tmp_path / "o.obj"
    with pytest.raises(SystemExit) as e:  # refused while parsing the arguments, as every table option is
        main(["unwrap", str(src), "-o", str(out), "--refine-multilevel", "-1", "--quiet"])
    err = capsys.readouterr().err
    assert e.value.code == 2 and "--refine-multilevel" in err and "Traceback" not in err and not out.exists()
    assert err.startswith("heatparam: error:") and err.count("\n") == 1  # one line, no usage block


def test_fill_options_reach_the_report(tmp_path):
    from heatparam import datasets as sh

    s = sh.cylinder_with_holes(h=0.09)
    src = tmp_path / "holes.off"
    write_off(src, s.V, s.F)
    rep = tmp_path / "r.json"
    assert main(["unwrap", str(src), "-o", str(tmp_path / "o.obj"), "--fill", "poisson", "--fill-depth", "7",
                 "--refine", "none", "--report", str(rep), "--quiet"]) == 0
    r = json.loads(rep.read_text())
    assert r["method"]["fill"]["used"] and r["method"]["fill"]["method"] == "poisson"
    assert r["method"]["fill"]["depth"] == 7 and r["parameters"]["fill_depth"] == 7
    assert "fill" in r["timings_s"] and r["method"]["fill"]["vertices"] > 0


def test_geodesics_on_a_closed_sphere(tmp_path):
    """Distances need no boundary: a closed icosphere (refused by unwrap) gets heat-method distances within 2.5%
    of the exact great-circle distances (measured 1.1% at 2562 vertices)."""
    import trimesh

    from heatparam import formats

    m = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    V, F = np.asarray(m.vertices), np.asarray(m.faces, dtype=np.int64)
    src = tmp_path / "sphere.obj"
    formats.save_uv_obj(src, V, F, V[:, :2])
    assert main(["unwrap", str(src), "-o", str(tmp_path / "u.obj"), "--quiet"]) == 0  # an atlas
    out = tmp_path / "d.npy"
    assert main(["geodesics", str(src), "--source", "0", "--quiet", "-o", str(out)]) == 0
    D = np.load(out)[:, 0]
    exact = np.arccos(np.clip(V @ V[0], -1.0, 1.0))
    far = exact > 0.1
    assert np.mean(np.abs(D[far] - exact[far]) / exact[far]) < 0.025


def test_geodesics_unreferenced_vertices_are_unreachable(tmp_path, capsys):
    sh = datasets.cylinder_patch(h=0.1)
    V = np.vstack([sh.V, [[5.0, 5.0, 5.0]]])  # one stray vertex no face uses
    src = tmp_path / "stray.obj"
    from heatparam import formats

    formats.save_uv_obj(src, V, sh.F, V[:, :2])
    out = tmp_path / "d.npy"
    assert main(["geodesics", str(src), "--source", "0", "-o", str(out)]) == 0
    D = np.load(out)
    assert D.shape == (len(V), 1) and np.isinf(D[-1, 0]) and np.isfinite(D[:-1]).all()
    assert "1 unreferenced vertices: inf" in capsys.readouterr().err
    assert main(["geodesics", str(src), "--source", str(len(V) - 1), "-o", str(tmp_path / "e.npy")]) == 2


def test_geodesics_still_refuses_what_operators_cannot_handle(tmp_path, capsys):
    two = tmp_path / "two.obj"
    two.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 0 0\nv 6 0 0\nv 5 1 0\nf 1 2 3\nf 4 5 6\n")
    assert main(["geodesics", str(two), "--source", "0", "-o", str(tmp_path / "d.npy")]) == 2
    err = capsys.readouterr().err
    assert "connected components" in err and err.count("\n") == 1
    assert not (tmp_path / "d.npy").exists()


def test_mds_start_option_reaches_the_report(tmp_path, patch_off):
    """Default on a developable patch: heat stage skipped, stress null in the JSON; --mds-start always runs it."""
    src, _ = patch_off
    runs = {}
    for mode in ("auto", "always"):
        rep = tmp_path / f"{mode}.json"
        assert main(["unwrap", str(src), "-o", str(tmp_path / f"{mode}.obj"), "--mds-start", mode,
                     "--report", str(rep), "--quiet"]) == 0
        runs[mode] = json.loads(rep.read_text())
    auto, always = runs["auto"], runs["always"]
    assert auto["parameters"]["mds_start"] == "auto" and always["parameters"]["mds_start"] == "always"
    assert auto["method"]["geodesics"].startswith("skipped") and auto["metrics"]["stress_rel_rms"] is None
    assert always["method"]["geodesics"] in ("all-pairs", "landmarks") and always["metrics"]["stress_rel_rms"] > 0
    assert auto["metrics"]["iso_mean"] == always["metrics"]["iso_mean"]


def test_unwrap_with_seams_writes_vt_per_seam_side(tmp_path):
    """halftunnel: the default cuts its holes open (report and warning say so); the OBJ keeps v and f v in input
    order and has more vt than v; `evaluate` on it reproduces the report's metrics. --seams none: one vt per v."""
    src = shared_mesh("halftunnel.off")
    V, F = formats.load_mesh(src)
    out, rep, prev = tmp_path / "h.obj", tmp_path / "h.json", tmp_path / "h.png"
    assert main(["unwrap", str(src), "-o", str(out), "--report", str(rep), "--preview", str(prev), "--quiet"]) == 0
    r = json.loads(rep.read_text())
    seams = r["method"]["seams"]
    assert seams["used"] and any("seams" in w for w in r["warnings"])
    V2, F2, UV, FUV = formats.load_uv_obj(out)
    assert np.array_equal(V2, V) and np.array_equal(F2, F)
    assert len(UV) == len(V) + seams["split_vertices"] and not np.array_equal(FUV, F)
    ev = tmp_path / "ev.json"
    assert main(["evaluate", str(out), "--report", str(ev), "--quiet"]) == 0
    m = json.loads(ev.read_text())["metrics"]
    assert m["bijective"] and m["iso_mean"] == pytest.approx(r["metrics"]["iso_mean"], rel=1e-9)
    assert prev.read_bytes()[:4] == b"\x89PNG"
    one = tmp_path / "one.obj"
    assert main(["unwrap", str(src), "-o", str(one), "--seams", "none", "--quiet"]) == 0
    _, _, UV1, FUV1 = formats.load_uv_obj(one)
    assert len(UV1) == len(V) and np.array_equal(FUV1, F)
