"""The preview PNG: layout coloured by distortion on a data-scaled colour bar, a scale bar, hole loops and seams
on both views, charts in distinct colours, headline numbers."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from heatparam import datasets, metrics  # noqa: E402
from heatparam.formats import preview  # noqa: E402
from heatparam.mesh import cut_open, hole_seams, loops_outer_first  # noqa: E402


@pytest.fixture(scope="module")
def part():
    """A developable cylinder patch with two holes and its exact flat layout (a near-isometric map)."""
    return datasets.cylinder_with_holes(h=0.09)


@pytest.fixture(scope="module")
def cut(part):
    """The part cut open from each hole to the border: (V per uv row, F on uv rows, uv, input vertex, paths)."""
    paths = hole_seams(part.V, part.F, loops_outer_first(part.V, part.F))
    Vs, Fs, src = cut_open(part.V, part.F, paths)
    return Vs, Fs, part.uv_true[src], src, paths


def _png(path) -> np.ndarray:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[2] in (3, 4)
    return img


def _nonblank(img: np.ndarray) -> None:
    rgb = img[..., :3]
    assert rgb.std() > 0.05  # not a blank canvas
    assert (rgb.min(axis=2) < 0.5).mean() > 0.02  # a fair share of dark (drawn) pixels


def test_preview_one_chart(tmp_path, part):
    p = tmp_path / "one.png"
    preview.save_preview(p, part.V, part.F, part.uv_true, title="part", units="mm")
    img = _png(p)
    _nonblank(img)
    assert img.shape[1] > 1.6 * img.shape[0]  # two panels side by side


def test_preview_charts_and_seams(tmp_path, part, cut):
    Vs, Fs, uv, src, _ = cut
    chart = (uv[Fs].mean(axis=1)[:, 0] > 0).astype(np.int64)  # two charts: left and right half
    one, two = tmp_path / "seams.png", tmp_path / "charts.png"
    preview.save_preview(one, Vs, Fs, uv, vertex=src)
    preview.save_preview(two, Vs, Fs, uv, chart=chart, vertex=src)
    a, b = _png(one), _png(two)
    _nonblank(b)
    assert b.shape[1] > 1.3 * a.shape[1]  # a third panel: the layout by chart
    # seams are drawn in their colour on the figure
    seam_rgb = np.array(matplotlib.colors.to_rgb(preview.SEAM_COLOR))
    assert (np.abs(a[..., :3] - seam_rgb).max(axis=2) < 0.08).sum() > 50
    with pytest.raises(ValueError, match="chart"):
        preview.save_preview(tmp_path / "bad.png", Vs, Fs, uv, chart=chart[:-1])


def test_map_edges_splits_border_holes_and_seams(part, cut):
    Vs, Fs, _, src, paths = cut
    for vertex in (src, None):  # given, or welded by 3D position
        e = preview.map_edges(Vs, Fs, vertex)
        assert e.n_holes == 2 and e.n_seams == len(paths) == 2
        assert len(e.seams) == 2 * sum(len(p) - 1 for p in paths)  # each cut edge, once per side
        assert len(e.outline) + len(e.holes) == len(metrics.boundary_edges(part.F))
    e = preview.map_edges(part.V, part.F)  # uncut: no seams
    assert e.n_seams == 0 and len(e.seams) == 0 and e.n_holes == 2
    assert preview.count_charts(Fs, len(Vs)) == 1


def test_colour_range_follows_the_data(part):
    iso = np.concatenate([np.linspace(1.0, 3.0, 1000), [np.inf]])
    flipped = np.zeros(len(iso), dtype=bool)
    assert preview.distortion_range(iso, flipped) == pytest.approx(np.percentile(iso[:-1], 99))
    assert preview.distortion_range(np.full(10, 1.001)) == preview.VMAX_FLOOR
    flipped[-100:] = True  # flipped faces (the inf and the 99 highest) do not set the scale
    assert preview.distortion_range(iso, flipped) == pytest.approx(np.percentile(iso[:-100], 99))
    # drawn: an isometric map gets the floor, a stretched one a colour bar up to its own distortion
    tops = []
    for sx in (1.0, 1.5):
        uv = part.uv_true * [sx, 1.0]
        pf = metrics.per_face_distortion(part.V, part.F, uv)
        fig, ax = plt.subplots()
        vmax = preview.draw_layout(ax, part.F, uv, pf.iso, pf.flipped, units="mm")
        assert fig.axes[-1].get_ylim()[1] == pytest.approx(vmax)  # the colour bar's top
        plt.close(fig)
        tops.append(vmax)
    assert tops[0] == preview.VMAX_FLOOR
    assert 1.2 < tops[1] < 1.6 and tops[1] != 2.0


def test_scale_bar_and_checker_sizes_are_round():
    assert preview.nice_length(37.0) == 20.0 and preview.nice_length(0.07) == pytest.approx(0.05)
    assert preview.nice_length(10.0) == 10.0 and preview.nice_length(99.0) == 50.0


def test_headline_numbers():
    text = preview.headline({"iso_mean": 1.23456, "iso_p95": 1.5, "flips": 0, "boundary_crossings": 2}, 3, None)
    for s in ("iso mean 1.2346", "p95 1.5000", "flipped 0", "boundary crossings 2", "charts 3"):
        assert s in text


def test_chart_colours_are_distinct_and_avoid_line_colours():
    c = preview.chart_colors(np.array([5, 5, 9, 2, 9]))
    assert np.array_equal(c[0], c[1]) and np.array_equal(c[2], c[4])
    assert len({tuple(x) for x in c}) == 3
    lines = [matplotlib.colors.to_rgb(x) for x in (preview.SEAM_COLOR, preview.HOLE_COLOR, preview.FLIP_COLOR)]
    palette = preview.chart_colors(np.arange(14))
    assert min(np.abs(palette - np.array(x)).max(axis=1).min() for x in lines) > 0.15


def test_texture_space_labels(tmp_path, part):
    """pack texture: UVs in [0,1]² are labelled as texture space with pixels at the resolution, never in mm; true
    scale keeps the model's unit."""
    uv = part.uv_true - part.uv_true.min(axis=0)
    uv /= uv.max()  # into [0,1]², as the texture packing leaves it
    texts = " | ".join(preview.save_preview(tmp_path / "t.png", part.V, part.F, uv, units="mm", texture=1024))
    assert "u (texture space, 1 = 1024 px)" in texts and "v (texture space, 1 = 1024 px)" in texts
    assert "0.2 = 204.8 px" in texts  # the scale bar: a round length and its pixels
    assert "squares of 0.05 = 51.2 px" in texts  # the checkerboard
    assert "mm" not in texts
    texts = " | ".join(preview.save_preview(tmp_path / "s.png", part.V, part.F, part.uv_true, units="cm"))
    assert "u (cm)" in texts and "texture" not in texts and " cm" in texts


def test_headline_counts_charts_and_seam_length(tmp_path, part, cut):
    """The headline counts what a user counts: charts, holes, and the seams' 3D length with its unit (not the
    connected seam graphs)."""
    Vs, Fs, uv, src, paths = cut
    texts = preview.save_preview(tmp_path / "c.png", Vs, Fs, uv, vertex=src, units="mm")
    length = sum(np.linalg.norm(np.diff(part.V[p], axis=0), axis=1).sum() for p in paths)
    head = next(t for t in texts if "iso mean" in t)
    assert f"seam length {length:.4g} mm" in head and "charts 1" in head and "seams " not in head
    head = next(t for t in preview.save_preview(tmp_path / "u.png", part.V, part.F, part.uv_true) if "iso mean" in t)
    assert "seam length" not in head  # no seams, nothing to count
