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
    # the legend's top is the preview's (one scale for the two pictures of a map)
    from heatparam.formats.pattern import build_pattern, face_iso
    from heatparam.formats.preview import distortion_range

    top = [t.text for t in root.iterfind(".//s:g[@id='legend']/s:text", NS) if t.text.endswith("+")]
    iso = face_iso(build_pattern(*m.arrays), m.V)
    assert top == [f"{distortion_range(iso):.3f}+"]


def _text_boxes(svg_path):
    """Every label of an SVG as (text, axis-aligned box) from its position, font size, length and rotation: a glyph
    taken 0.6 font sizes wide, the box centred on (x, y) (the labels are centred both ways)."""
    out = []
    for g in ET.parse(svg_path).getroot().iterfind("s:g", NS):
        if g.get("id") not in ("seams", "annotation"):
            continue
        for t in g.iterfind("s:text", NS):
            if t.get("class") not in ("label", "chart"):
                continue  # the notes under the pattern
            x, y, size = float(t.get("x")), float(t.get("y")), float(t.get("font-size"))
            angle = float(t.get("transform", "rotate(0").split("(")[1].split()[0].rstrip(")"))
            w, h = 0.6 * size * len(t.text), size
            c, s = abs(np.cos(np.radians(angle))), abs(np.sin(np.radians(angle)))
            hx, hy = (c * w + s * h) / 2, (s * w + c * h) / 2
            out.append((t.text, np.array([x - hx, y - hy, x + hx, y + hy])))
    return out


@pytest.fixture(scope="module")
def cow_atlas():
    import heatparam
    from heatparam import formats

    from conftest import shared_mesh

    V, F = formats.load_mesh(shared_mesh("cow.off"))
    return V, F, heatparam.parameterize(V, F)


def _cow_svg(tmp_path, cow_atlas, **kw):
    V, F, r = cow_atlas
    pattern = layout_charts(build_pattern(V, F, r.uv, r.Fuv, r.uv_vertex, chart=r.chart))
    info = write_svg(tmp_path / "cow.svg", pattern, units="m", title="cow.off", **kw)
    return tmp_path / "cow.svg", pattern, info


def test_atlas_labels_never_overlap(tmp_path, cow_atlas):
    """The cow's 30 charts: no two label boxes overlap, each chart id sits inside its chart, and what did not fit is
    counted in a note rather than piled up."""
    from matplotlib.path import Path

    path, pattern, info = _cow_svg(tmp_path, cow_atlas)
    boxes = _text_boxes(path)
    assert len(boxes) > 30
    B = np.array([b for _, b in boxes])
    overlap = ((B[:, None, 0] < B[None, :, 2]) & (B[None, :, 0] < B[:, None, 2])
               & (B[:, None, 1] < B[None, :, 3]) & (B[None, :, 1] < B[:, None, 3]))
    np.fill_diagonal(overlap, False)
    pairs = [(boxes[i][0], boxes[j][0]) for i, j in zip(*np.nonzero(overlap), strict=True) if i < j]
    assert not pairs, pairs[:5]
    root = ET.parse(path).getroot()
    ids = {t.text: t for t in root.iterfind(".//s:text[@class='chart']", NS) if t.text[0] == "C"}
    assert len(ids) + info["labels_left_out"]["chart"] == len(pattern.charts)
    assert "C4" in ids and "C5" in ids  # the largest charts keep their ids
    # an id's centre, back in UV (the SVG's origin is the pattern's corner less a margin of twice the text height),
    # lies inside its own chart
    from heatparam.formats.dxf import text_height

    (lo, hi), margin = pattern.bbox, 2 * text_height(pattern)
    for ch in pattern.charts:
        t = ids.get(f"C{ch.id}")
        if t is not None:
            uv = (float(t.get("x")) + lo[0] - margin, hi[1] + margin - float(t.get("y")))
            assert Path(pattern.uv[ch.outer.rows]).contains_point(uv), ch.id
    notes = " ".join(t.text for t in root.iterfind(".//s:text", NS) if t.get("class") is None)
    if sum(info["labels_left_out"].values()):
        assert "not drawn, no room" in notes


def test_texture_atlas_is_labelled_in_texture_space(tmp_path, cow_atlas):
    """pack texture: the SVG says texture space and pixels, never mm, and is the texture's size in pixels."""
    V, F, _ = cow_atlas
    import heatparam

    r = heatparam.parameterize(V, F, pack="texture", resolution=512)
    pattern = layout_charts(build_pattern(V, F, r.uv, r.Fuv, r.uv_vertex, chart=r.chart))
    write_svg(tmp_path / "t.svg", pattern, units="mm", title="cow.off", texture=512)
    root = ET.parse(tmp_path / "t.svg").getroot()
    texts = [t.text for t in root.iterfind(".//s:text", NS)]
    assert "units: texture space, 1 = 512 px" in texts
    assert root.get("data-units") == "texture" and root.get("width").endswith("px")
    W = float(root.get("viewBox").split()[2])
    assert float(root.get("width")[:-2]) == pytest.approx(W * 512, rel=1e-5)
    assert not any("iso mean" in t for t in texts)  # no distortion at the texture's scale
    assert all(" mm," not in t for t in texts if t.startswith("outline"))  # the outline in pixels, 3D in mm
    assert render(tmp_path / "t.svg", 24)[..., 3].max() > 0  # cairosvg renders it
