"""Preview pictures (paper Figures 10-12): the UV layout coloured by isometric distortion, flips marked,
beside the 3D mesh textured with a checkerboard through the map. matplotlib, off-screen (Agg)."""

from __future__ import annotations

import os

import numpy as np

#: Faces drawn at most per panel; larger meshes are drawn from an even subsample of faces in the 3D panel.
MAX_FACES_3D = 200_000


def _figure(ncols: int):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows, cols = (2, 2) if ncols == 4 else (1, ncols)
    fig, axes = plt.subplots(rows, cols, figsize=(6.4 * cols, 6.4 * rows), dpi=110 if rows == 1 else 80)
    return plt, fig, np.atleast_1d(axes).ravel()


def draw_layout(ax, F: np.ndarray, uv: np.ndarray, iso: np.ndarray, flipped: np.ndarray, vmax: float = 2.0,
                title: str = "") -> None:
    """UV triangles coloured by isometric distortion (1 = isometric), flipped triangles in red."""
    from matplotlib.collections import PolyCollection

    cmap = _cmap()
    vals = np.clip(np.nan_to_num(iso, nan=vmax, posinf=vmax), 1.0, vmax)
    colors = cmap((vals - 1.0) / (vmax - 1.0))
    colors[flipped] = (0.9, 0.0, 0.0, 1.0)
    ax.add_collection(PolyCollection(uv[F], facecolors=colors, edgecolors="none", antialiaseds=False))
    if flipped.any():
        c = uv[F[flipped]].mean(axis=1)
        ax.scatter(c[:, 0], c[:, 1], s=12, marker="x", color="red", linewidths=0.8, label=f"{flipped.sum()} flipped")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_title(title or "UV layout: isometric distortion", fontsize=10)
    import matplotlib.cm as cm
    import matplotlib.colors as mc

    sm = cm.ScalarMappable(norm=mc.Normalize(1.0, vmax), cmap=cmap)
    ax.figure.colorbar(sm, ax=ax, fraction=0.04, pad=0.02, label="max(σ1, 1/σ2)")


def _cmap():
    import matplotlib

    return matplotlib.colormaps["viridis"]


def draw_checker_3d(ax, V: np.ndarray, F: np.ndarray, uv: np.ndarray, cells: int = 16, title: str = "") -> None:
    """The 3D mesh in an orthographic view along its thinnest principal axis, checkerboard through the map."""
    if len(F) > MAX_FACES_3D:
        F = F[np.linspace(0, len(F) - 1, MAX_FACES_3D).astype(np.int64)]
    # Subdivide (3D and UV together) so the checker squares have smooth edges on coarse meshes.
    levels = int(np.clip(np.floor(np.log(MAX_FACES_3D / 2 / max(len(F), 1)) / np.log(4)), 0, 2))
    if levels:
        import igl

        P, F = igl.upsample(np.hstack([V, uv]), F, levels)
        V, uv = P[:, :3], P[:, 3:]
    span = float(np.ptp(uv, axis=0).max()) or 1.0
    uvc = uv[F].mean(axis=1) / (span / cells)
    checker = (np.floor(uvc[:, 0]) + np.floor(uvc[:, 1])) % 2
    base = np.where(checker[:, None] > 0, [[0.95, 0.55, 0.1]], [[0.15, 0.2, 0.55]])
    _draw_shaded(ax, V, F, base, _principal_frame(V), edges=False)
    ax.set_title(title or "3D mesh, checkerboard through the map", fontsize=10)


def save_preview(path: str | os.PathLike, V: np.ndarray, F: np.ndarray, uv: np.ndarray, title: str = "",
                 fill_surface=None) -> None:
    """Write the preview PNG atomically: the UV layout coloured by isometric distortion beside the 3D mesh with
    a checkerboard through the map (paper Figures 10-12). With ``fill_surface`` (a pipeline ``FillSurface``),
    two more panels show M* with M over it (Figure 7) and M*'s MDS layout with M's trimmed layout (Figure 9)."""
    from heatparam import metrics
    from heatparam.formats.files import atomic_write

    pf = metrics.per_face_distortion(V, F, uv)
    plt, fig, axes = _figure(2 if fill_surface is None else 4)
    draw_layout(axes[0], F, uv, pf.iso, pf.flipped, title=f"{title} — UV layout (isometric distortion)")
    draw_checker_3d(axes[1], V, F, uv)
    if fill_surface is not None:
        from matplotlib.collections import PolyCollection

        fs = fill_surface
        draw_fill_overlay(axes[2], V, F, fs.V, fs.F, f"fill surface M* ({fs.method}, {len(fs.V)} vertices) "
                          "with M over it")
        ax = axes[3]
        ax.add_collection(PolyCollection(fs.uv[fs.F], facecolors=(0.8, 0.8, 0.8), edgecolors=(0.6, 0.6, 0.6),
                                         linewidths=0.1))
        ax.add_collection(PolyCollection(fs.uv_points[F], facecolors=(0.35, 0.5, 0.85, 0.7), edgecolors="none"))
        ax.set_aspect("equal")
        ax.autoscale_view()
        ax.set_title("MDS layout of M* (grey) and its trim to M (blue), before refinement", fontsize=10)
    fig.tight_layout()
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png")
    plt.close(fig)


def _principal_frame(V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centre (3,) and rows of the principal axes (3,3) of V: view along the thinnest axis (the last row)."""
    c = V.mean(axis=0)
    _, _, Wt = np.linalg.svd(V - c, full_matrices=False)
    return c, Wt


def _draw_shaded(ax, V: np.ndarray, F: np.ndarray, base: np.ndarray, frame, edges: bool) -> None:
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


def draw_fill_overlay(ax, V: np.ndarray, F: np.ndarray, Vs: np.ndarray, Fs: np.ndarray, title: str) -> None:
    """The fill surface M* (grey) with M drawn over it (translucent blue), in M's principal frame (Figure 7b)."""
    from matplotlib.collections import PolyCollection

    frame = _principal_frame(V)
    draw_surface_3d(ax, Vs, Fs, color=(0.8, 0.8, 0.8), frame=frame, edges=len(Fs) < 10_000)
    c, Wt = frame
    P = (V - c) @ Wt.T
    ax.add_collection(PolyCollection(P[F][:, :, :2], facecolors=(0.35, 0.5, 0.85, 0.55), edgecolors="none"))
    ax.autoscale_view()
    ax.set_title(title, fontsize=10)


def draw_surface_3d(ax, V: np.ndarray, F: np.ndarray, color=(0.75, 0.75, 0.8), frame=None, edges: bool = False,
                    title: str = "") -> None:
    """Shaded orthographic view of (V, F) in ``frame`` = (centre, axes) (default: V's principal frame)."""
    base = np.broadcast_to(np.asarray(color, dtype=float), (len(F), 3))
    _draw_shaded(ax, V, F, base, frame if frame is not None else _principal_frame(V), edges)
    if title:
        ax.set_title(title, fontsize=10)


def save_fill_figure(path: str | os.PathLike, V: np.ndarray, F: np.ndarray, Vs: np.ndarray, Fs: np.ndarray,
                     title: str = "") -> None:
    """Paper Figure 7: (a) the mesh M, (b) the fill surface M* (grey) with M drawn over it (blue), one view."""
    from heatparam.formats.files import atomic_write

    plt, fig, axes = _figure(2)
    draw_surface_3d(axes[0], V, F, color=(0.35, 0.5, 0.85), frame=_principal_frame(V), title=f"{title} — (a) mesh M")
    draw_fill_overlay(axes[1], V, F, Vs, Fs, f"(b) fill surface M* ({len(Vs)} vertices) with M over it")
    fig.tight_layout()
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=64)
    plt.close(fig)


def save_fill_comparison(path: str | os.PathLike, V: np.ndarray, F: np.ndarray, uv_without: np.ndarray,
                         uv_with: np.ndarray, labels: tuple[str, str] = ("without fill", "with fill"),
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
