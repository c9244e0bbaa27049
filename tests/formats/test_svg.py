"""SVG flat patterns rendered by cairosvg: non-blank, physical size as declared, loops as in the DXF, strain map."""

import io as _io
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from heatparam.cli import main
from heatparam.formats.pattern import build_pattern, layout_charts
from heatparam.formats.svg import write_svg
from heatparam.mesh.topology import boundary_loops

from formats_cases import cylinder_map, edge_stretch_bounds, halftunnel_map, polyline_length, two_chart_atlas, write_off

cairosvg = pytest.importorskip("cairosvg")
Image = pytest.importorskip("PIL.Image")

NS = {"s": "http://www.w3.org/2000/svg"}
MM_PER = {"mm": 1.0, "cm": 10.0, "in": 25.4}


def points(el):
    return np.array([[float(v) for v in p.split(",")] for p in el.get("points").split()])


def render(path, dpi):
    png = cairosvg.svg2png(url=str(path), dpi=dpi)
    return np.asarray(Image.open(_io.BytesIO(png)).convert("RGBA"))


def physical_mm(length: str) -> float:
    for u, f in MM_PER.items():
        if length.endswith(u):
            return float(length[: -len(u)]) * f
    raise AssertionError(length)


@pytest.mark.parametrize("units,model_mm", [("mm", 1.0), ("cm", 10.0), ("in", 25.4), ("m", 1000.0), ("ft", 304.8)])
def test_physical_size_and_render(tmp_path, units, model_mm):
    """The root's width/height are the pattern's extent (viewBox, model units) times the unit's size; cairosvg's
    PNG has that size at the chosen dpi (±1 px) and is not blank."""
    m = cylinder_map()
    src = write_off(tmp_path / "c.off", m.V, m.F)
    out = tmp_path / "c.svg"
    assert main(["unwrap", str(src), "-o", str(out), "--units", units, "--quiet"]) == 0
    root = ET.parse(out).getroot()
    vb = [float(x) for x in root.get("viewBox").split()]
    w_mm, h_mm = physical_mm(root.get("width")), physical_mm(root.get("height"))
    assert w_mm == pytest.approx(vb[2] * model_mm, rel=1e-5) and h_mm == pytest.approx(vb[3] * model_mm, rel=1e-5)
    dpi = 2000.0 / (w_mm / 25.4) if units != "mm" else 300  # about 2000 px wide (a mm-sized part: 300 dpi)
    img = render(out, dpi)
    assert abs(img.shape[1] - w_mm / 25.4 * dpi) <= 1 and abs(img.shape[0] - h_mm / 25.4 * dpi) <= 1
    ink = (img[..., 3] > 0) & (img[..., :3].min(axis=2) < 200)
    assert ink.sum() > 200  # lines and text were drawn
    assert root.get("data-units") == units


def test_loops_groups_and_lengths(tmp_path):
    """outline/holes groups: one closed polygon per loop (as many as the map's UV boundary loops and the DXF's);
    each loop's SVG length / 3D length within the map's edge stretch range; y is flipped but lengths kept."""
    m = cylinder_map()
    pat = layout_charts(build_pattern(*m.arrays))
    out = tmp_path / "c.svg"
    write_svg(out, pat, units="mm")
    root = ET.parse(out).getroot()
    outl = root.findall(".//s:g[@id='outline']/s:polygon", NS)
    holes = root.findall(".//s:g[@id='holes']/s:polygon", NS)
    assert len(outl) == 1 and len(holes) == 2 and len(outl) + len(holes) == len(boundary_loops(m.Fuv))
    lo, hi = edge_stretch_bounds(m)
    L3 = sorted(lp.length_3d for c in pat.charts for lp in c.loops)
    L2 = sorted(polyline_length(points(e)) for e in outl + holes)
    for a, b in zip(L2, L3, strict=True):
        assert lo <= a / b <= hi and abs(a / b - 1) < 0.01
    ids = {g.get("id") for g in root.iter("{http://www.w3.org/2000/svg}g")}
    assert {"outline", "holes", "seams", "annotation"} <= ids and "strain" not in ids
    img = render(out, 600)
    assert (img[..., :3].min(axis=2) < 128).sum() > 500  # the black cut line is there


def test_seams_and_charts(tmp_path):
    """Two charts (laid apart) and halftunnel's seams: each seam label on two polylines, the groups distinct."""
    for m in (two_chart_atlas(), halftunnel_map()):
        pat = layout_charts(build_pattern(*m.arrays))
        out = tmp_path / "s.svg"
        write_svg(out, pat)
        root = ET.parse(out).getroot()
        seams = root.findall(".//s:g[@id='seams']/s:polyline", NS)
        labels = [e.get("data-label") for e in seams]
        assert labels and all(labels.count(x) == 2 for x in labels)
        texts = [t.text for t in root.findall(".//s:g[@id='seams']/s:text", NS)]
        assert sorted(texts) == sorted(labels)
        n_loops = sum(len(boundary_loops(m.Fuv[m.chart == c] if m.chart is not None else m.Fuv))
                      for c in (np.unique(m.chart) if m.chart is not None else [0]))
        assert len(root.findall(".//s:g[@id='outline']/s:polygon", NS)) + len(
            root.findall(".//s:g[@id='holes']/s:polygon", NS)) == n_loops


def test_strain_map(tmp_path):
    """--strain-map: one filled polygon per face coloured by distortion, a legend; the render is mostly colour."""
    m = halftunnel_map()
    src = write_off(tmp_path / "h.off", m.V, m.F)
    out = tmp_path / "h.svg"
    assert main(["unwrap", str(src), "-o", str(out), "--strain-map", "--quiet"]) == 0
    root = ET.parse(out).getroot()
    faces = root.findall(".//s:g[@id='strain']/s:polygon", NS)
    assert len(faces) == len(m.F)
    colours = {f.get("fill") for f in faces}
    assert len(colours) > 5  # halftunnel's map is not isometric everywhere: several colours
    assert root.find(".//s:g[@id='legend']", NS) is not None
    img = render(out, 20)
    rgb = img[..., :3].astype(int)
    coloured = (img[..., 3] > 0) & (np.ptp(rgb, axis=2) > 40)  # saturated pixels (viridis), not grey/white
    assert coloured.mean() > 0.2
