"""Preview pictures (paper Figures 10-12): the UV layout coloured by isometric distortion, flips marked,
beside the 3D mesh textured with a checkerboard through the map. matplotlib, off-screen (Agg)."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from heatparam.formats.units import uv_length, uv_unit

#: Faces drawn at most per panel; larger meshes are drawn from an even subsample of faces in the 3D panel.
MAX_FACES_3D = 200_000


#: Line colours over both views (the distortion colour map is viridis; flipped faces are red).
OUTLINE_COLOR = "black"
HOLE_COLOR = "#ff7f0e"  # orange
SEAM_COLOR = "#e6007e"  # magenta
FLIP_COLOR = (0.9, 0.0, 0.0, 1.0)
#: The 3D checkerboard without charts: greys, so the coloured lines stand out.
CHECKER_LIGHT = (0.92, 0.92, 0.90)
CHECKER_DARK = (0.42, 0.45, 0.52)
#: The colour bar tops out at this percentile of the (finite, unflipped) isometric distortion, at least FLOOR.
VMAX_PERCENTILE = 99.0
VMAX_FLOOR = 1.05


@dataclass(frozen=True)
class MapEdges:
    """The UV boundary edges of a map, by kind, as pairs of ``uv`` rows.

    outline : (a,2) int64, the outer border of the surface (its longest boundary loop in 3D).
    holes : (b,2) int64, the other boundary loops of the surface (holes).
    seams : (c,2) int64, UV boundary edges whose 3D edge is interior (each 3D edge appears once per side).
    n_holes : number of hole loops; n_seams : number of connected seam paths (in 3D).
    welded : (n_uv,) int64, the 3D vertex of each uv row (rows with the same id are one surface point).
    """

    outline: np.ndarray
    holes: np.ndarray
    seams: np.ndarray
    n_holes: int
    n_seams: int
    welded: np.ndarray


def map_edges(V: np.ndarray, F: np.ndarray, vertex: np.ndarray | None = None) -> MapEdges:
    """Split the UV boundary of a (possibly cut-open) map into outer border, hole loops and seams.

    Parameters
    ----------
    V : (n_uv,3) float64, the 3D position of each uv row (``V_in[uv_vertex]`` for a seamed map).
    F : (m,3) int64, faces on uv rows (``Result.Fuv``).
    vertex : (n_uv,) int64, the input vertex of each uv row (``Result.uv_vertex``); None: rows at exactly the
        same 3D position are the same vertex.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from heatparam.mesh.topology import boundary_edges, loops_outer_first

    F = np.asarray(F, dtype=np.int64)
    if vertex is None:
        _, welded = np.unique(V, axis=0, return_inverse=True)
    else:
        welded = np.asarray(vertex, dtype=np.int64)
    welded = welded.reshape(-1)
    nw = int(welded.max()) + 1 if len(welded) else 0
    Vw = np.zeros((nw, 3))
    Vw[welded] = V
    Fw = welded[F]
    be = boundary_edges(F)  # (b,2) uv rows
    # how many faces use each 3D edge: 1 = the surface's border, 2 = interior (a UV boundary edge there is a seam)
    E3 = np.sort(np.concatenate([Fw[:, [0, 1]], Fw[:, [1, 2]], Fw[:, [2, 0]]]), axis=1)
    keys, counts = np.unique(E3[:, 0] * nw + E3[:, 1], return_counts=True)
    bw = np.sort(welded[be], axis=1)
    used = counts[np.searchsorted(keys, bw[:, 0] * nw + bw[:, 1])]
    seam = used >= 2
    loop_of = np.full(nw, -1, dtype=np.int64)
    loops = loops_outer_first(Vw, Fw) if (~seam).any() else []
    for rank, lp in enumerate(loops):
        loop_of[lp] = rank
    outer = ~seam & (loop_of[bw[:, 0]] == 0)
    n_seams = 0
    if seam.any():
        s = np.unique(bw[seam], axis=0)
        verts, local = np.unique(s, return_inverse=True)
        local = local.reshape(-1, 2)
        g = coo_matrix((np.ones(len(s)), (local[:, 0], local[:, 1])), shape=(len(verts), len(verts)))
        n_seams = int(connected_components(g, directed=False)[0])
    return MapEdges(be[outer], be[~seam & ~outer], be[seam], max(len(loops) - 1, 0), n_seams, welded)


def count_charts(F: np.ndarray, n_uv: int) -> int:
    """Connected pieces of the layout (faces sharing a uv row), (m,3) int64 faces on uv rows."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    F = np.asarray(F, dtype=np.int64)
    if len(F) == 0:
        return 0
    g = coo_matrix((np.ones(2 * len(F)), (np.concatenate([F[:, 0], F[:, 0]]), np.concatenate([F[:, 1], F[:, 2]]))),
                   shape=(n_uv, n_uv))
    labels = connected_components(g, directed=False)[1]
    return int(len(np.unique(labels[F[:, 0]])))


def distortion_range(iso: np.ndarray, flipped: np.ndarray | None = None, q: float = VMAX_PERCENTILE,
                     floor: float = VMAX_FLOOR) -> float:
    """Top of the distortion colour scale (the bottom is 1, an isometry): the ``q``-th percentile of the finite
    values of unflipped faces, at least ``floor`` (a near-isometric map keeps a readable scale).

    iso : (m,) float64 ``max(σ1, 1/σ2)`` per face; flipped : (m,) bool or None.
    """
    iso = np.asarray(iso, dtype=float)
    ok = np.isfinite(iso) if flipped is None else np.isfinite(iso) & ~np.asarray(flipped, dtype=bool)
    if not ok.any():
        return float(floor)
    return float(max(floor, np.percentile(iso[ok], q)))


def nice_length(x: float) -> float:
    """The largest 1, 2 or 5 × 10^k that is ≤ x (x > 0): scale bars and checker sizes in round model units."""
    if not np.isfinite(x) or x <= 0:
        return 1.0
    e = 10.0 ** np.floor(np.log10(x))
    return float(max(m for m in (1.0, 2.0, 5.0, 10.0) if m * e <= x * (1 + 1e-12)) * e)


def chart_colors(chart: np.ndarray) -> np.ndarray:
    """(m,3) RGB per face from its chart id, numbered in the order the ids first appear: tab20 without its
    oranges, reds and pinks (hole loops, flips, seams), cycling past 14 charts."""
    import matplotlib

    _, first, inv = np.unique(np.asarray(chart), return_index=True, return_inverse=True)
    rank = np.argsort(np.argsort(first))
    cmap = matplotlib.colormaps["tab20"]
    keep = [i for i in range(20) if i not in (2, 3, 6, 7, 12, 13)]
    palette = np.array([cmap(keep[i % len(keep)])[:3] for i in range(len(first))])
    return palette[rank[inv.reshape(-1)]]


def _figure(n: int, extra_height: float = 0.0):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows, cols = (1, n) if n <= 3 else (2, (n + 1) // 2)
    fig, axes = plt.subplots(rows, cols, figsize=(6.4 * cols, 6.4 * rows + extra_height), dpi=110 if rows == 1 else 80,
                             layout="constrained", squeeze=False)
    axes = axes.ravel()
    for ax in axes[n:]:
        ax.set_axis_off()
    return plt, fig, axes[:n]


def _segments(X2: np.ndarray, E: np.ndarray) -> np.ndarray:
    return X2[E] if len(E) else np.zeros((0, 2, 2))


def _draw_edges(ax, X2: np.ndarray, edges: MapEdges | None, front=None) -> list:
    """Outline, hole loops and seams over ``ax`` (X2: (n_uv,2) positions of the uv rows); legend handles.
    ``front(E)`` (3D views): (k,) bool, which of the (k,2) edges are in front of the surface; the hidden ones are
    drawn faint."""
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D

    if edges is None:
        return []
    handles = []
    for E, color, lw, label in ((edges.outline, OUTLINE_COLOR, 0.8, "outer border"),
                                (edges.holes, HOLE_COLOR, 1.4, f"hole loops ({edges.n_holes})"),
                                (edges.seams, SEAM_COLOR, 1.6, "seams")):
        if len(E):
            seen = np.ones(len(E), dtype=bool) if front is None else front(E)
            ax.add_collection(LineCollection(_segments(X2, E[seen]), colors=color, linewidths=lw, zorder=3,
                                             capstyle="round"))
            if not seen.all():
                ax.add_collection(LineCollection(_segments(X2, E[~seen]), colors=color, linewidths=0.6 * lw,
                                                 alpha=0.3, linestyles=(0, (2, 2)), zorder=3))
            handles.append(Line2D([], [], color=color, lw=2 * lw, label=label))
    return handles


def _front_of(P: np.ndarray, F: np.ndarray, Q: np.ndarray):
    """A test ``front(E)``: whether the midpoints of edges E (k,2) of the points Q (n_uv,3) (view coordinates,
    z towards the viewer) are in front of the surface P (p,3), F (f,3), by a depth buffer of the faces' corners,
    edge midpoints and centroids on a grid of about one mean projected edge per cell. A point is hidden when the
    surface in its cell is more than three mean 3D edge lengths nearer the viewer (the line lies on the surface
    itself)."""
    A, B, C = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
    edge3 = float(np.mean(np.linalg.norm(B - A, axis=1))) if len(F) else 1.0
    edge2 = float(np.mean(np.linalg.norm((B - A)[:, :2], axis=1))) if len(F) else 1.0
    lo = P[:, :2].min(axis=0)
    size = float((P[:, :2].max(axis=0) - lo).max()) or 1.0
    res = int(np.clip(size / max(edge2, 1e-300), 64, 1024))
    S = np.concatenate([A, B, C, (A + B) / 2, (B + C) / 2, (C + A) / 2, (A + B + C) / 3])
    zb = np.full(res * res, -np.inf)

    def cell(X: np.ndarray) -> np.ndarray:
        ij = np.clip(((X[:, :2] - lo) / (size / res)).astype(np.int64), 0, res - 1)
        return ij[:, 0] * res + ij[:, 1]

    np.maximum.at(zb, cell(S), S[:, 2])

    def front(E: np.ndarray) -> np.ndarray:
        M = (Q[E[:, 0]] + Q[E[:, 1]]) / 2
        return M[:, 2] >= zb[cell(M)] - 3 * edge3

    return front


def _scale_bar(ax, units: str | None, texture: int | None = None) -> None:
    """A horizontal scale bar of a round length in model units (or texture space), lower left of the data."""
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    x0, x1 = ax.get_xlim()
    length = nice_length(abs(x1 - x0) / 5)
    label = uv_length(length, units, texture)
    ax.add_artist(AnchoredSizeBar(ax.transData, length, label, loc="lower left", pad=0.4, borderpad=0.5,
                                  sep=4, frameon=True, size_vertical=0, fontproperties={"size": 9}))


def draw_layout(ax, F: np.ndarray, uv: np.ndarray, iso: np.ndarray, flipped: np.ndarray, *, vmax: float | None = None,
                title: str = "", units: str | None = None, edges: MapEdges | None = None,
                legend: bool = True, texture: int | None = None) -> float:
    """UV triangles coloured by isometric distortion (1 = isometric) up to ``vmax`` (None:
    :func:`distortion_range` of the data), flipped triangles in red, ``edges`` drawn over them, a scale bar in
    ``units`` (in texture space of ``texture`` pixels when given). Returns the vmax used.

    F : (m,3) int64; uv : (n_uv,2) float64; iso : (m,) float64; flipped : (m,) bool.
    """
    import matplotlib.cm as cm
    import matplotlib.colors as mc
    from matplotlib.collections import PolyCollection
    from matplotlib.lines import Line2D

    vmax = distortion_range(iso, flipped) if vmax is None else float(vmax)
    cmap = _cmap()
    vals = np.clip(np.nan_to_num(iso, nan=vmax, posinf=vmax), 1.0, vmax)
    colors = cmap((vals - 1.0) / (vmax - 1.0))
    colors[flipped] = FLIP_COLOR
    ax.add_collection(PolyCollection(uv[F], facecolors=colors, edgecolors="none", antialiaseds=False))
    handles = _draw_edges(ax, uv, edges)
    nflip = int(np.count_nonzero(flipped))
    if nflip:
        c = uv[F[flipped]].mean(axis=1)
        ax.scatter(c[:, 0], c[:, 1], s=14, marker="x", color="red", linewidths=0.9, zorder=4)
        handles.append(Line2D([], [], color="red", marker="x", lw=0, label=f"flipped ({nflip})"))
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.margins(x=0.04, y=0.12)  # room for the scale bar under the layout
    ax.autoscale_view()
    _uv_axes(ax, units, texture)
    ax.set_title(title or "UV layout: isometric distortion", fontsize=10)
    if legend and handles:
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=len(handles), fontsize=8,
                  frameon=False)
    sm = cm.ScalarMappable(norm=mc.Normalize(1.0, vmax), cmap=cmap)
    cb = ax.figure.colorbar(sm, ax=ax, fraction=0.04, pad=0.02, extend="max")
    cb.set_label(f"isometric distortion max(σ1, 1/σ2); top = {VMAX_PERCENTILE:g}th percentile", fontsize=8)
    cb.ax.tick_params(labelsize=8)
    return vmax


def draw_charts(ax, F: np.ndarray, uv: np.ndarray, chart: np.ndarray, *, units: str | None = None,
                edges: MapEdges | None = None, title: str = "", texture: int | None = None) -> None:
    """UV triangles in one colour per chart (``chart`` (m,) ids), ``edges`` over them, a scale bar."""
    from matplotlib.collections import PolyCollection

    ax.add_collection(PolyCollection(uv[F], facecolors=chart_colors(chart), edgecolors="none", antialiaseds=False))
    handles = _draw_edges(ax, uv, edges)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.margins(x=0.04, y=0.12)
    ax.autoscale_view()
    _uv_axes(ax, units, texture)
    ax.set_title(title or f"UV layout: {len(np.unique(chart))} charts", fontsize=10)
    if handles:
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=len(handles), fontsize=8,
                  frameon=False)


def _uv_axes(ax, units: str | None, texture: int | None) -> None:
    """Axis labels and the scale bar of a UV panel: in model units, or texture space (``texture`` pixels)."""
    unit = f" ({uv_unit(units, texture)})"
    ax.set_xlabel(f"u{unit}", fontsize=9)
    ax.set_ylabel(f"v{unit}", fontsize=9)
    ax.tick_params(labelsize=8)
    _scale_bar(ax, units, texture)


def _cmap():
    import matplotlib

    return matplotlib.colormaps["viridis"]


def draw_checker_3d(ax, V: np.ndarray, F: np.ndarray, uv: np.ndarray, *, cells: int = 16, title: str = "",
                    chart: np.ndarray | None = None, edges: MapEdges | None = None, units: str | None = None,
                    texture: int | None = None) -> None:
    """The 3D mesh in an orthographic view along its thinnest principal axis, a checkerboard of round-sized
    squares (UV units: model units, or texture space of ``texture`` pixels) through the map; faces tinted by
    ``chart`` (m,) when given; ``edges`` (outline, holes, seams) drawn over it."""
    frame = _principal_frame(V)
    V0 = V
    span = float(np.ptp(uv, axis=0).max()) if len(uv) else 1.0
    cell = nice_length(span / cells) if span > 0 else 1.0
    idx = np.arange(len(F))
    if len(F) > MAX_FACES_3D:
        idx = np.linspace(0, len(F) - 1, MAX_FACES_3D).astype(np.int64)
        F = F[idx]
    # Subdivide (3D and UV together) so the checker squares have smooth edges on coarse meshes; igl.upsample
    # numbers the 4^levels children of face f as f * 4^levels + k.
    levels = int(np.clip(np.floor(np.log(MAX_FACES_3D / 2 / max(len(F), 1)) / np.log(4)), 0, 2))
    if levels:
        import igl

        P, Fs = igl.upsample(np.hstack([V, uv]), F, levels)
        if len(Fs) == len(F) * 4**levels:
            V, uv, F = P[:, :3], P[:, 3:], Fs
            idx = np.repeat(idx, 4**levels)
    uvc = uv[F].mean(axis=1) / cell
    checker = (np.floor(uvc[:, 0]) + np.floor(uvc[:, 1])) % 2
    if chart is not None:
        tint = chart_colors(np.asarray(chart)[idx])
        base = np.where(checker[:, None] > 0, tint, 0.55 * tint)
    else:
        base = np.where(checker[:, None] > 0, [CHECKER_LIGHT], [CHECKER_DARK])
    _draw_shaded(ax, V, F, base, frame=frame, edges=False)
    if edges is not None:
        c, Wt = frame
        P0 = (V0 - c) @ Wt.T
        _draw_edges(ax, P0[:, :2], edges, front=_front_of((V - c) @ Wt.T, F, P0))
    ax.set_title(title or f"3D mesh, checkerboard through the map: squares of {uv_length(cell, units, texture)}",
                 fontsize=10)


def headline(metrics: dict, charts: int, edges: MapEdges | None, seam_length: str = "") -> str:
    """The numbers a user counts: distortion, flips, crossings, charts, holes and the seams' 3D length (as text
    with its unit; "" without seams)."""

    def num(key: str, fmt: str) -> str:
        v = metrics.get(key)
        return "n/a" if v is None else format(v, fmt)

    parts = [f"iso mean {num('iso_mean', '.4f')}", f"p95 {num('iso_p95', '.4f')}",
             f"flipped {num('flips', 'd')}", f"boundary crossings {num('boundary_crossings', 'd')}",
             f"charts {charts}"]
    if edges is not None:
        parts += [f"holes {edges.n_holes}", *([f"seam length {seam_length}"] if seam_length else [])]
    return "   ·   ".join(parts)


def save_preview(path: str | os.PathLike, V: np.ndarray, F: np.ndarray, uv: np.ndarray, *, title: str = "",
                 fill_surface=None, units: str | None = "mm", chart: np.ndarray | None = None,
                 metrics: dict | None = None, vertex: np.ndarray | None = None, texture: int | None = None
                 ) -> list[str]:
    """Write the preview PNG atomically.

    Panels: the UV layout coloured by isometric distortion (colour bar from 1 to the data's 99th percentile,
    flipped faces red, a scale bar in ``units``), the layout by chart (only with ``chart`` of more than one id),
    and the 3D mesh with a checkerboard through the map (paper Figures 10-12; faces tinted by chart). The outer
    border, hole loops and seams (UV boundary edges whose 3D edge is interior) are drawn on the layout and the
    3D view. The headline numbers (iso mean and p95, flips, boundary crossings, charts, holes, seam length) head the
    figure. With ``fill_surface`` (a pipeline ``FillSurface``), two more panels show M* with M over it
    (Figure 7) and M*'s MDS layout with M's trimmed layout (Figure 9).

    Parameters
    ----------
    V : (n_uv,3) float64, the 3D point of each uv row (``V[result.uv_vertex]`` for a seamed map).
    F : (m,3) int64, faces on uv rows (``result.Fuv``).
    uv : (n_uv,2) float64, the map in model units.
    units : the model's length unit for the axes, the scale bar and the seam length (None: "model units").
    chart : (m,) int per-face chart id, or None (charts are then the layout's connected pieces).
    metrics : the report's ``metrics`` (iso_mean, iso_p95, flips, boundary_crossings); None: computed here.
    vertex : (n_uv,) int64 input vertex of each uv row (``result.uv_vertex``); None: rows at one 3D point weld.
    texture : the texture's size in pixels when ``uv`` is texture space ([0,1]², ``pack texture``): the UV panels
        are labelled in it instead of ``units``.

    Returns
    -------
    The figure's texts (headline, titles, axis and scale-bar labels), so that a caller can check what it says.
    """
    from heatparam import metrics as mt
    from heatparam.formats.files import atomic_write

    V, F, uv, chart = _checked(V, F, uv, chart)
    pf = mt.per_face_distortion(V, F, uv)
    if metrics is None:
        metrics = mt.summary(V, F, uv)
    edges = map_edges(V, F, vertex)
    charts = len(np.unique(chart)) if chart is not None else count_charts(F, len(uv))
    show_charts = chart is not None and charts > 1
    n = 2 + show_charts + (2 if fill_surface is not None else 0)
    plt, fig, axes = _figure(n, extra_height=0.5)
    seams = float(np.linalg.norm(V[edges.seams[:, 0]] - V[edges.seams[:, 1]], axis=1).sum()) / 2  # once per side
    seam_length = f"{seams:.4g} {units or 'model units'}" if seams else ""
    fig.suptitle(f"{title + chr(10) if title else ''}{headline(metrics, charts, edges, seam_length)}", fontsize=11)
    draw_layout(axes[0], F, uv, pf.iso, pf.flipped, units=units, edges=edges, texture=texture,
                title=f"UV layout ({uv_unit(units, texture)}): isometric distortion")
    k = 1
    if show_charts:
        draw_charts(axes[1], F, uv, chart, units=units, edges=edges, texture=texture)
        k = 2
    draw_checker_3d(axes[k], V, F, uv, chart=chart if show_charts else None, edges=edges, units=units,
                    texture=texture)
    if fill_surface is not None:
        _draw_fill_panels(axes[k + 1 : k + 3], V, F, fill_surface)
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png")
    texts = [t.get_text() for t in fig.findobj(lambda a: hasattr(a, "get_text")) if t.get_text()]
    plt.close(fig)
    return texts


def _checked(V, F, uv, chart) -> tuple:
    """The preview's arrays as float64 / int64, ``chart`` flattened; ValueError when it has not one id per face."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    uv = np.asarray(uv, dtype=np.float64)
    if chart is not None:
        chart = np.asarray(chart).reshape(-1)
        if len(chart) != len(F):
            raise ValueError(f"chart has {len(chart)} ids for {len(F)} faces")
    return V, F, uv, chart


def _draw_fill_panels(axes, V: np.ndarray, F: np.ndarray, fs) -> None:
    """The fill surface M* with M over it (Figure 7), and M*'s MDS layout with M's trimmed layout (Figure 9)."""
    from matplotlib.collections import PolyCollection

    ax_surface, ax_layout = axes
    draw_fill_overlay(ax_surface, V, F, fs.V, fs.F, title=f"fill surface M* ({fs.method}, {len(fs.V)} vertices) "
                      "with M over it")
    ax_layout.add_collection(PolyCollection(fs.uv[fs.F], facecolors=(0.8, 0.8, 0.8), edgecolors=(0.6, 0.6, 0.6),
                                            linewidths=0.1))
    ax_layout.add_collection(PolyCollection(fs.uv_points[F], facecolors=(0.35, 0.5, 0.85, 0.7),
                                            edgecolors="none"))
    ax_layout.set_aspect("equal")
    ax_layout.autoscale_view()
    ax_layout.set_title("MDS layout of M* (grey) and its trim to M (blue), before refinement", fontsize=10)


def _principal_frame(V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centre (3,) and rows of the principal axes (3,3) of V: view along the thinnest axis (the last row)."""
    c = V.mean(axis=0)
    _, _, Wt = np.linalg.svd(V - c, full_matrices=False)
    return c, Wt


def _draw_shaded(ax, V: np.ndarray, F: np.ndarray, base: np.ndarray, *, frame, edges: bool) -> None:
    """Orthographic view of (V, F) in ``frame`` = (centre, axes): faces in ``base`` colours (m,3) times a
    Lambert shade, far faces first (painter's algorithm)."""
    from matplotlib.collections import PolyCollection

    c, Wt = frame
    P = (V - c) @ Wt.T  # x, y in the view plane, z along the view
    n = np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-300
    colors = np.clip(base * (0.35 + 0.65 * np.abs(n[:, 2]))[:, None], 0, 1)
    order = np.argsort(P[F, 2].mean(axis=1))
    ax.add_collection(PolyCollection(P[F[order]][:, :, :2], facecolors=colors[order],
                                     edgecolors=(0, 0, 0, 0.25) if edges else "none",
                                     linewidths=0.2 if edges else 0.0, antialiaseds=edges))
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_axis_off()


def draw_fill_overlay(ax, V: np.ndarray, F: np.ndarray, Vs: np.ndarray, Fs: np.ndarray, *, title: str) -> None:
    """The fill surface M* (grey) with M drawn over it (translucent blue), in M's principal frame (Figure 7b)."""
    from matplotlib.collections import PolyCollection

    frame = _principal_frame(V)
    draw_surface_3d(ax, Vs, Fs, color=(0.8, 0.8, 0.8), frame=frame, edges=len(Fs) < 10_000)
    c, Wt = frame
    P = (V - c) @ Wt.T
    ax.add_collection(PolyCollection(P[F][:, :, :2], facecolors=(0.35, 0.5, 0.85, 0.55), edgecolors="none"))
    ax.autoscale_view()
    ax.set_title(title, fontsize=10)


def draw_surface_3d(ax, V: np.ndarray, F: np.ndarray, *, color=(0.75, 0.75, 0.8), frame=None, edges: bool = False,
                    title: str = "") -> None:
    """Shaded orthographic view of (V, F) in ``frame`` = (centre, axes) (default: V's principal frame)."""
    base = np.broadcast_to(np.asarray(color, dtype=float), (len(F), 3))
    _draw_shaded(ax, V, F, base, frame=frame if frame is not None else _principal_frame(V), edges=edges)
    if title:
        ax.set_title(title, fontsize=10)


def save_fill_figure(path: str | os.PathLike, V: np.ndarray, F: np.ndarray, Vs: np.ndarray, Fs: np.ndarray, *,
                     title: str = "") -> None:
    """Paper Figure 7: (a) the mesh M, (b) the fill surface M* (grey) with M drawn over it (blue), one view."""
    from heatparam.formats.files import atomic_write

    plt, fig, axes = _figure(2)
    draw_surface_3d(axes[0], V, F, color=(0.35, 0.5, 0.85), frame=_principal_frame(V), title=f"{title} — (a) mesh M")
    draw_fill_overlay(axes[1], V, F, Vs, Fs, title=f"(b) fill surface M* ({len(Vs)} vertices) with M over it")
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=64)
    plt.close(fig)


def save_fill_comparison(path: str | os.PathLike, V: np.ndarray, F: np.ndarray, uv_without: np.ndarray,
                         uv_with: np.ndarray, *, labels: tuple[str, str] = ("without fill", "with fill"),
                         title: str = "") -> None:
    """Paper Figures 10/12: checkerboard on M and the UV layout, without (top) and with (bottom) the fill."""
    import matplotlib

    from heatparam import metrics
    from heatparam.formats.files import atomic_write

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(11, 10), dpi=80)
    for row, (uv, lab) in enumerate(zip((uv_without, uv_with), labels, strict=True)):
        pf = metrics.per_face_distortion(V, F, uv)
        nflip = int(pf.flipped.sum())
        draw_checker_3d(axes[row, 0], V, F, uv, title=f"{title} {lab}: checkerboard on M")
        draw_layout(axes[row, 1], F, uv, pf.iso, pf.flipped, title=f"{lab}: UV layout, {nflip} flipped")
    fig.tight_layout()
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png")
    plt.close(fig)
