"""Raster nesting (mesh.nest) and the sheets it fills (formats.pattern.layout_charts, unwrap --sheet): conservative
rasters, outlines that never overlap and stay inside their sheet (read back from the DXF), rotations as the grain
allows, the same layout for the same seed, one-line refusals."""

import ezdxf
import numpy as np
import pytest
import shapely

from heatparam import datasets
from heatparam.cli import main
from heatparam.errors import HeatparamError
from heatparam.formats.pattern import Sheets, build_pattern, layout_charts
from heatparam.mesh.nest import Piece, orientations
from heatparam.unwrap import unwrap_file

from conftest import shared_mesh


def test_raster_holds_every_pixel_a_triangle_touches():
    rng = np.random.default_rng(1)
    for _ in range(20):
        T = rng.uniform(0, 12, (1, 3, 2))
        piece = Piece(T[0], np.array([[0, 1, 2]]), [np.eye(2)])
        shape = piece.shapes(1.0, 0)[0]
        tri = shapely.Polygon(T[0] - shape.lo)
        h, w = shape.raster.shape
        for i in range(h):
            for j in range(w):
                box = shapely.box(j, i, j + 1, i + 1)
                if tri.intersection(box).area > 1e-9:  # touched with some area: must be set
                    assert shape.raster[i, j], (i, j)
                if not tri.intersects(box.buffer(1e-6)):
                    assert not shape.raster[i, j], (i, j)


def test_orientation_rules():
    P = np.array([[0.0, 0.0], [3.0, 1.0], [2.5, 2.5], [-0.5, 1.5]])
    assert len(orientations(P, "none")) == 1 and np.allclose(orientations(P, "none")[0], np.eye(2))
    assert [round(R[0, 0]) for R in orientations(P, "180")] == [1, -1]
    free = orientations(P, "free")
    assert len(free) == 8 and all(np.allclose(R @ R.T, np.eye(2)) and np.linalg.det(R) > 0 for R in free)
    fine = orientations(P, "fine")
    assert len(fine) == 20 and all(any(np.allclose(R, Q) for Q in fine) for R in free)
    with pytest.raises(ValueError):
        orientations(P, "sideways")


def _strips():
    """The part with holes cut in six strips: a pattern of six charts stacked at the origin."""
    s = datasets.cylinder_with_holes()
    x = s.uv_true[s.F].mean(axis=1)[:, 0]
    chart = np.digitize(x, np.linspace(x.min(), x.max(), 7)[1:-1])
    rows = np.arange(3 * len(s.F)).reshape(-1, 3)
    uv = s.uv_true[s.F].reshape(-1, 2)
    return lambda: build_pattern(s.V, s.F, uv, rows, s.F.ravel(), chart)


@pytest.mark.parametrize("grain, fill", [("none", 0.3), ("180", 0.3), ("free", 0.3), ("free", 1.5)])
def test_sheets_nest_outlines_apart_inside_their_sheet_and_repeatably(grain, fill):
    """Sheets of (pieces' area) / fill: one sheet, or (fill > 1) several, each piece inside its own frame."""
    make = _strips()
    base = make()
    area = sum(shapely.area(shapely.polygons(base.uv[base.Fuv])))
    sheet = (float(np.sqrt(area / fill)),) * 2 if fill < 1 else (float(area / fill / 2.0), 2.0)  # strips 1.8 tall
    gap = 0.01 * sheet[0]
    pat = layout_charts(make(), sheet, gap, grain=grain, nest_time=1.0, seed=3)
    again = layout_charts(make(), sheet, gap, grain=grain, nest_time=1.0, seed=3)
    if not again.nesting["stopped_by_time"] and not pat.nesting["stopped_by_time"]:
        assert np.array_equal(pat.uv, again.uv)
    polys = []
    for c in pat.charts:
        allowed = [np.eye(2)] if grain == "none" else [np.eye(2), -np.eye(2)] if grain == "180" else None
        assert allowed is None or any(np.allclose(c.turn, R) for R in allowed)
        d0 = base.uv[c.rows] - base.uv[c.rows][0]
        assert np.allclose(pat.uv[c.rows] - pat.uv[c.rows][0], d0 @ c.turn.T)  # moved and turned only
        region = shapely.union_all(shapely.polygons(pat.uv[pat.Fuv[c.faces]]))
        x0, y0, w, h = pat.sheets[c.sheet]
        assert shapely.box(x0 + gap, y0 + gap, x0 + w - gap, y0 + h - gap).buffer(1e-12).contains(region)
        polys.append(region)
    for i in range(len(polys)):
        for j in range(i):
            assert polys[i].distance(polys[j]) >= gap * (1 - 1e-9)
    assert len(pat.sheet_use) == len(pat.sheets) and np.all((pat.sheet_use > 0) & (pat.sheet_use < 1))
    assert len(pat.sheets) >= 2 if fill > 1 else len(pat.sheets) == 1
    assert np.all(np.diff(pat.sheets[:, 0]) > sheet[0])  # side by side, apart


def test_bunny_on_one_sheet_of_area_over_055(tmp_path):
    """The acceptance case: the bunny's charts on ONE square sheet of area (3D area) / 0.55 within the default time;
    outlines read back from the DXF do not overlap and lie inside the frame."""
    V0 = shared_mesh("stanford-bunny.obj")
    out = tmp_path / "b.dxf"
    from heatparam.formats import load_mesh

    V, F = load_mesh(V0)
    a3 = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1).sum()
    side = float(np.sqrt(a3 / 0.55))
    res = unwrap_file(V0, [out, tmp_path / "b.svg"], units="m", sheet=Sheets((side, side)))
    assert res.report["pattern"]["sheets"] == 1
    doc = ezdxf.readfile(out)
    msp = doc.modelspace()
    frames = [shapely.Polygon(e.get_points("xy")) for e in msp.query('LWPOLYLINE[layer=="SHEET"]')]
    outlines = [shapely.Polygon(e.get_points("xy")) for e in msp.query('LWPOLYLINE[layer=="OUTLINE"]')]
    assert len(frames) == 1 and len(outlines) == res.report["pattern"]["charts"] > 1
    for i, p in enumerate(outlines):
        assert frames[0].contains(p)
        for q in outlines[:i]:
            assert not p.overlaps(q) and not p.within(q) and not q.within(p) and p.intersection(q).area == 0
    note = f"sheet 1 of 1: {res.report['pattern']['sheet_use'][0]:.1%} used"
    assert any(e.dxf.text == note for e in msp.query("TEXT")) and note in (tmp_path / "b.svg").read_text()


def test_bad_sheet_input_is_one_line_exit_2_nothing_written(tmp_path, capsys):
    s = datasets.flat_disk(1.0, h=0.2)
    src = tmp_path / "d.obj"
    src.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in s.V) + "".join(f"f {a + 1} {b + 1} {c + 1}\n"
                                                                           for a, b, c in s.F))
    out = tmp_path / "d.dxf"
    for flags, expect in ((["--sheet", "1x1"], ["chart 0 (", " x ", "does not fit on a 1 x 1 mm sheet"]),
                          (["--sheet", "5x5", "--gap", "0"], ["--gap"]),
                          (["--sheet", "5x5", "--gap", "inf"], ["--gap"]),
                          (["--sheet", "5x5", "--nest-time", "-1"], ["--nest-time"]),
                          (["--sheet", "5x5", "--nest-time", "nan"], ["--nest-time"]),
                          (["--sheet", "0x5"], ["--sheet"])):
        assert _exit_code(["unwrap", str(src), "-o", str(out), "--quiet", "--units", "mm", *flags]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and all(e in err[0] for e in expect), err
        assert not out.exists()
    with pytest.raises(HeatparamError, match="does not fit"):
        layout_charts(build_pattern(s.V, s.F, s.uv_true, s.F, np.arange(len(s.V))), (0.5, 5.0))


def _exit_code(argv: list[str]) -> int:
    """The CLI's exit code, whether it returns it or argparse exits with it."""
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code)


def test_dilated_runs_are_the_square_dilation():
    """Each shape's runs are the runs of its raster dilated by a (2 gap + 1)² square (scipy's dilation)."""
    from scipy import ndimage

    s = datasets.noisy_scan_part(scale=1.0, noise=0.0, h=0.1)
    for gap in (0, 1, 3):
        for shape in Piece(s.uv_true, s.F, orientations(s.uv_true, "free")).shapes(40.0, gap):
            dil = ndimage.binary_dilation(np.pad(shape.raster, gap), np.ones((2 * gap + 1,) * 2, dtype=bool))
            got = np.zeros_like(dil)
            for r, a, b in shape.runs + gap:
                got[r, a:b + 1] = True
            assert np.array_equal(got, dil)
            lengths = shape.runs[:, 2] - shape.runs[:, 1] + 1
            for r, longest in shape.rows:
                assert longest == lengths[shape.runs[:, 0] == r].max()


@pytest.mark.parametrize("kw, name", [({"sheet": (0.0, 5.0)}, "sheet"), ({"sheet": (5.0, float("inf"))}, "sheet"),
                                      ({"gap": -1.0}, "gap"), ({"gap": float("nan")}, "gap"),
                                      ({"nest_time": -1.0}, "nest_time"), ({"nest_time": float("inf")}, "nest_time")])
def test_layout_refuses_bad_sheet_arguments_in_one_line(kw, name):
    s = datasets.flat_disk(1.0, h=0.2)
    args = {"sheet": (5.0, 5.0), **kw}
    with pytest.raises(HeatparamError, match=f"^{name} must be") as e:
        layout_charts(build_pattern(s.V, s.F, s.uv_true, s.F, np.arange(len(s.V))), **args)
    assert "\n" not in str(e.value)
