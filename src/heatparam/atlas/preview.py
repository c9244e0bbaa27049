"""Atlas preview PNG: the 3D mesh with charts in distinct colours and seams drawn, beside the packed UV atlas
in the same colours. matplotlib, off-screen (Agg), written atomically."""

from __future__ import annotations

import os

import numpy as np

__all__ = ["chart_colors", "seam_edges", "save_atlas_preview"]


def chart_colors(k: int) -> np.ndarray:
    """(k,3) distinct RGB colours (golden-ratio hues, alternating lightness)."""
    import colorsys

    h = np.mod(np.arange(k) * 0.6180339887, 1.0)
    return np.array([colorsys.hls_to_rgb(x, 0.45 + 0.2 * (i % 2), 0.75) for i, x in enumerate(h)])


def seam_edges(F: np.ndarray, Fuv: np.ndarray) -> np.ndarray:
    """(s,2) input vertex pairs of the interior edges whose two sides use different UV rows."""
    from heatparam.atlas.repair import half_edge_opposites

    opp = half_edge_opposites(F)
    h = np.flatnonzero(opp > np.arange(len(opp)))
    o = opp[h]
    fa, ja, fb, jb = h // 3, h % 3, o // 3, o % 3
    same = (Fuv[fa, ja] == Fuv[fb, (jb + 1) % 3]) & (Fuv[fa, (ja + 1) % 3] == Fuv[fb, jb])
    return np.stack([F[fa, ja], F[fa, (ja + 1) % 3]], axis=1)[~same]


def save_atlas_preview(path: str | os.PathLike, V: np.ndarray, F: np.ndarray, result, title: str = "") -> None:
    """Write the preview: left the 3D mesh (an oblique view of its principal frame, painter's order) with each
    chart in its colour and the seams in black; right the atlas. ``result``: an ``AtlasResult``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PolyCollection

    from heatparam.formats.files import atomic_write

    k = int(result.chart.max()) + 1
    base = chart_colors(k)[result.chart]
    fig, axes = plt.subplots(1, 2, figsize=(12.8, 6.4), dpi=110)
    c = V.mean(axis=0)
    _, _, Wt = np.linalg.svd(V - c, full_matrices=False)
    # an oblique view (30° about two principal axes) so that closed shapes show three sides
    a = np.radians(30.0)
    Rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    Ry = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    P = (V - c) @ Wt.T @ (Rx @ Ry).T
    n = np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-300
    front = n[:, 2] > 0
    shade = np.clip(base * (0.35 + 0.65 * np.abs(n[:, 2]))[:, None], 0, 1)
    order = np.argsort(P[F, 2].mean(axis=1))
    ax = axes[0]
    ax.add_collection(PolyCollection(P[F[order]][:, :, :2], facecolors=shade[order], edgecolors="none"))
    # seams of front-facing faces, on top
    S = seam_edges(F, result.Fuv)
    if len(S):
        vis = np.zeros(len(V), dtype=bool)
        vis[F[front].ravel()] = True
        S = S[vis[S[:, 0]] & vis[S[:, 1]]]
        ax.add_collection(LineCollection(P[S][:, :, :2], colors="black", linewidths=0.8))
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_axis_off()
    ax.set_title(f"{title} — {k} charts, seams in black", fontsize=10)
    ax = axes[1]
    ax.add_collection(PolyCollection(result.uv[result.Fuv], facecolors=chart_colors(k)[result.chart],
                                     edgecolors="none"))
    ax.set_aspect("equal")
    ax.autoscale_view()
    tot = result.report.get("totals", {})
    ax.set_title(f"atlas ({result.report.get('pack', {}).get('mode', '')}): iso mean {tot.get('iso_mean', 0):.4f}, "
                 f"packing {tot.get('packing_efficiency', 0):.2f}", fontsize=10)
    fig.tight_layout()
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png")
    plt.close(fig)
