"""Test meshes with known flat layouts (exact developable surfaces), and layout-error measures.

Every generator builds a planar domain (outer loop + hole loops, all lengths in the same units), meshes it
(boundary sampled at spacing ``<= h``, interior points on a regular triangular lattice of spacing ``h``,
``scipy.spatial.Delaunay``, triangles kept when their centroid is inside the domain), then bends the flat
mesh into 3D with an exact isometry of the plane (cylinder, cone) or, for the non-developable cap, a smooth
lift onto a sphere.

Chord note: the 3D triangles are flat chords of the curved surface, so the *discrete* mesh is not exactly
isometric to ``uv_true``: a 3D edge is a chord of the bent (geodesic-length) 2D edge and is shorter by the
relative amount ``~ (kappa * l)**2 / 24`` (``kappa`` the normal curvature along the edge, ``l`` its length).
The default resolutions keep that below 1e-3 (cylinder ``~(h/R)**2/24``); ``uv_true`` is the layout of the
*smooth* surface, i.e. the answer a perfect isometric parameterization converges to as ``h -> 0``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from matplotlib.path import Path
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Delaunay

from heatparam.mesh.planar import polygon_area, signed_areas

__all__ = [
    "Shape",
    "SHAPES",
    "bend_cylinder",
    "cone_s_strip",
    "curved_cap_with_holes",
    "cylinder_patch",
    "cylinder_with_holes",
    "flat_disk",
    "flat_square",
    "noisy_scan_part",
    "closed_cube",
    "capped_cylinder",
    "cone_with_base",
    "torus",
    "circle",
    "polygon",
    "lift_sphere",
    "mesh_domain",
    "scale_shape",
    "wrap_cone",
]


@dataclass(frozen=True, eq=False)
class Shape:
    """A test mesh and its exact flat layout.

    Attributes
    ----------
    V : (n,3) float64 vertex positions in 3D.
    F : (m,3) int64 triangles, counter-clockwise in the flat domain (positive signed area in ``uv_true``).
    uv_true : (n,2) float64 exact isometric flat layout, or ``None`` when the surface is not developable
        (``curved_cap_with_holes``).
    name : registry name of the generator.
    """

    V: np.ndarray
    F: np.ndarray
    uv_true: np.ndarray | None
    name: str

    def __post_init__(self) -> None:
        object.__setattr__(self, "V", np.ascontiguousarray(self.V, dtype=np.float64))
        object.__setattr__(self, "F", np.ascontiguousarray(self.F, dtype=np.int64))
        if self.uv_true is not None:
            object.__setattr__(self, "uv_true", np.ascontiguousarray(self.uv_true, dtype=np.float64))
            if self.uv_true.shape != (self.V.shape[0], 2):
                raise ValueError(f"uv_true must be ({self.V.shape[0]}, 2), got {self.uv_true.shape}")
        if self.V.ndim != 2 or self.V.shape[1] != 3 or self.F.ndim != 2 or self.F.shape[1] != 3:
            raise ValueError(f"V must be (n,3) and F (m,3), got {self.V.shape} and {self.F.shape}")

    @property
    def n_vertices(self) -> int:
        return int(self.V.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.F.shape[0])

    @property
    def developable(self) -> bool:
        return self.uv_true is not None

    def __repr__(self) -> str:
        return f"Shape(name={self.name!r}, n_vertices={self.n_vertices}, n_faces={self.n_faces})"


# ----------------------------------------------------------------------------------------------------------
# boundary sampling
# ----------------------------------------------------------------------------------------------------------


def _segment(p0: tuple[float, float], p1: tuple[float, float], h: float) -> np.ndarray:
    """Points on the segment p0 -> p1 at spacing <= h, p0 included, p1 excluded. (k,2)."""
    p0a, p1a = np.asarray(p0, dtype=np.float64), np.asarray(p1, dtype=np.float64)
    n = max(1, int(np.ceil(np.linalg.norm(p1a - p0a) / h - 1e-9)))
    t = np.arange(n) / n
    return p0a + t[:, None] * (p1a - p0a)


def _arc(
    center: tuple[float, float], radius: float, t0: float, t1: float, h: float, min_n: int = 3
) -> np.ndarray:
    """Points on the circular arc at angles t0 -> t1 (radians, either direction), chord spacing <= h.

    The end point (angle t1) is excluded, so a full circle is ``_arc(c, r, 0, 2*pi, h)``. (k,2).
    """
    sweep = abs(t1 - t0)
    chord = lambda k: 2.0 * radius * np.sin(sweep / (2 * k))  # noqa: E731
    n = max(min_n, int(np.ceil(radius * sweep / h - 1e-9)))
    while chord(n) > h:  # arc length >= chord, so this only triggers by rounding
        n += 1
    t = t0 + (t1 - t0) * np.arange(n) / n
    return np.asarray(center, dtype=np.float64) + radius * np.column_stack([np.cos(t), np.sin(t)])


def circle(center: tuple[float, float], radius: float, h: float, clockwise: bool = False) -> np.ndarray:
    """Closed loop on a circle, (k,2), counter-clockwise unless ``clockwise``."""
    pts = _arc(center, radius, 0.0, 2 * np.pi, h, min_n=8)
    return pts[::-1].copy() if clockwise else pts


def polygon(corners: np.ndarray, h: float) -> np.ndarray:
    """Closed loop through the polygon corners (c,2), every side subdivided at spacing <= h. (k,2)."""
    corners = np.asarray(corners, dtype=np.float64)
    return np.vstack([_segment(corners[i], corners[(i + 1) % len(corners)], h) for i in range(len(corners))])


def _orient(loop: np.ndarray, ccw: bool) -> np.ndarray:
    return loop if (polygon_area(loop) > 0) == ccw else loop[::-1].copy()


def _stadium(c0: tuple[float, float], c1: tuple[float, float], r: float, h: float) -> np.ndarray:
    """Closed counter-clockwise loop around the segment c0-c1 at distance r (a slot with round ends)."""
    c0a, c1a = np.asarray(c0, dtype=np.float64), np.asarray(c1, dtype=np.float64)
    ang = float(np.arctan2(*(c1a - c0a)[::-1]))
    n = np.array([-np.sin(ang), np.cos(ang)])
    return np.vstack(
        [
            _segment(tuple(c0a - r * n), tuple(c1a - r * n), h),
            _arc(tuple(c1a), r, ang - np.pi / 2, ang + np.pi / 2, h),
            _segment(tuple(c1a + r * n), tuple(c0a + r * n), h),
            _arc(tuple(c0a), r, ang + np.pi / 2, ang + 3 * np.pi / 2, h),
        ]
    )


def _ellipse(center: tuple[float, float], a: float, b: float, h: float) -> np.ndarray:
    """Closed counter-clockwise loop on the axis-aligned ellipse, arc-length spacing <= h. (k,2)."""
    t = np.linspace(0.0, 2 * np.pi, 4097)
    p = np.column_stack([a * np.cos(t), b * np.sin(t)])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    n = max(8, int(np.ceil(s[-1] / h - 1e-9)))
    tt = np.interp(np.arange(n) * s[-1] / n, s, t)
    return np.asarray(center, dtype=np.float64) + np.column_stack([a * np.cos(tt), b * np.sin(tt)])


# ----------------------------------------------------------------------------------------------------------
# domain meshing
# ----------------------------------------------------------------------------------------------------------


def _dist_to_segments(P: np.ndarray, A: np.ndarray, B: np.ndarray, chunk: int = 2048) -> np.ndarray:
    """Distance from each point P (N,2) to the nearest segment A[j]-B[j] (M,2). (N,)."""
    d = B - A
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    out = np.empty(len(P))
    for s in range(0, len(P), chunk):
        p = P[s : s + chunk, None, :] - A[None, :, :]  # (c,M,2)
        t = np.clip(np.einsum("cmk,mk->cm", p, d) / dd, 0.0, 1.0)
        out[s : s + chunk] = np.sqrt(np.min(np.sum((p - t[..., None] * d) ** 2, axis=2), axis=1))
    return out


def _inside(P: np.ndarray, loops: list[np.ndarray]) -> np.ndarray:
    """Points strictly inside loops[0] and outside every hole loops[1:]. (N,) bool."""
    mask = Path(loops[0]).contains_points(P)
    for hole in loops[1:]:
        mask &= ~Path(hole).contains_points(P)
    return mask


def _lattice(lo: np.ndarray, hi: np.ndarray, h: float) -> np.ndarray:
    """Regular triangular lattice of spacing h covering the box [lo, hi]. (N,2)."""
    dy = h * np.sqrt(3.0) / 2.0
    ys = lo[1] + dy * np.arange(int(np.ceil((hi[1] - lo[1]) / dy)) + 1)
    xs = lo[0] + h * np.arange(int(np.ceil((hi[0] - lo[0]) / h)) + 2)
    X = xs[None, :] + 0.5 * h * (np.arange(len(ys)) % 2)[:, None]
    Y = np.broadcast_to(ys[:, None], X.shape)
    return np.column_stack([X.ravel(), Y.ravel()])


def mesh_domain(
    loops: list[np.ndarray], h: float, min_boundary_distance: float = 0.55, max_refine: int = 12
) -> tuple[np.ndarray, np.ndarray]:
    """Triangulate a polygonal domain with holes.

    Parameters
    ----------
    loops : list of (k_i,2) closed loops (last point not repeated), outer loop first, then holes. Consecutive
        samples should be ``<= h`` apart. The domain is exactly the polygon through these samples.
    h : target edge length (interior lattice spacing).
    min_boundary_distance : interior lattice points closer than this times h to the boundary are skipped.
    max_refine : rounds of splitting boundary segments that Delaunay did not recover.

    Returns
    -------
    uv : (n,2) float64 vertices (every loop sample is a vertex; the boundary polygon is unchanged).
    F : (m,3) int64 triangles, counter-clockwise, forming a connected manifold triangulation of the domain
        in which every boundary-loop segment is an edge.
    """
    loops = [_orient(np.asarray(lp, dtype=np.float64), ccw=(i == 0)) for i, lp in enumerate(loops)]
    allb = np.vstack(loops)
    lo, hi = allb.min(axis=0), allb.max(axis=0)
    cand = _lattice(lo, hi, h)
    cand = cand[_inside(cand, loops)]
    A = allb
    B = np.vstack([np.roll(lp, -1, axis=0) for lp in loops])
    interior = cand[_dist_to_segments(cand, A, B) > min_boundary_distance * h]

    for _ in range(max_refine + 1):
        pts, T = _constrained_candidates(loops, interior, h)
        loops, missing = _split_missing_segments(loops, T, len(pts))
        if missing == 0:
            break
    else:
        raise RuntimeError("could not recover all boundary segments as Delaunay edges")

    used = np.unique(T)
    remap = np.full(len(pts), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    uv, F = pts[used], remap[T]
    _check_manifold(F, len(uv))
    return uv, F


def _constrained_candidates(loops: list[np.ndarray], interior: np.ndarray, h: float
                            ) -> tuple[np.ndarray, np.ndarray]:
    """Delaunay triangles of the loops' samples then the interior points (pts), counter-clockwise, without
    slivers and inside the domain: (pts, T)."""
    pts = np.vstack([np.vstack(loops), interior])
    tri = Delaunay(pts)
    if len(tri.coplanar):
        raise RuntimeError("Delaunay dropped coincident/coplanar input points")
    T = tri.simplices.astype(np.int64)
    sa = signed_areas(pts, T)
    T[sa < 0] = T[sa < 0][:, [0, 2, 1]]
    keep = np.abs(sa) > 1e-10 * h * h
    T = T[keep]
    return pts, T[_inside(pts[T].mean(axis=1), loops)]


def _split_missing_segments(loops: list[np.ndarray], T: np.ndarray, n: int) -> tuple[list[np.ndarray], int]:
    """The loops with a midpoint inserted into every segment that is not an edge of T (loop samples numbered
    first, n points in all), and the number of such segments."""
    sizes = [len(lp) for lp in loops]
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    E = np.vstack([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]])
    ekeys = set((np.minimum(E[:, 0], E[:, 1]) * n + np.maximum(E[:, 0], E[:, 1])).tolist())
    new_loops, missing = [], 0
    for lp, s in zip(loops, starts, strict=True):
        i = s + np.arange(len(lp))
        j = s + (np.arange(len(lp)) + 1) % len(lp)
        k = np.minimum(i, j) * n + np.maximum(i, j)
        ok = np.fromiter((kk in ekeys for kk in k.tolist()), dtype=bool, count=len(k))
        missing += int((~ok).sum())
        if ok.all():
            new_loops.append(lp)
            continue
        mids = 0.5 * (lp + np.roll(lp, -1, axis=0))
        out = [lp[:, None, :], np.where(~ok[:, None], mids, np.nan)[:, None, :]]
        merged = np.concatenate(out, axis=1).reshape(-1, 2)
        new_loops.append(merged[~np.isnan(merged[:, 0])])
    return new_loops, missing


def _check_manifold(F: np.ndarray, n: int) -> None:
    """Raise unless F is a connected, edge- and vertex-manifold, consistently oriented triangulation."""
    E = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    _, counts = np.unique(E, axis=0, return_counts=True)
    if counts.max() > 1:
        raise RuntimeError("inconsistent orientation or non-manifold edge")
    und = np.sort(E, axis=1)
    _, ucount = np.unique(und, axis=0, return_counts=True)
    if ucount.max() > 2:
        raise RuntimeError("non-manifold edge")
    adj = coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n))
    if connected_components(adj, directed=False)[0] != 1:
        raise RuntimeError("mesh is not connected")
    # vertex manifold: each boundary vertex has exactly one outgoing and one incoming boundary half-edge
    key = E[:, 0] * n + E[:, 1]
    rev = E[:, 1] * n + E[:, 0]
    bnd = E[~np.isin(key, rev)]
    if len(bnd) and (
        np.bincount(bnd[:, 0], minlength=n).max() > 1 or np.bincount(bnd[:, 1], minlength=n).max() > 1
    ):
        raise RuntimeError("non-manifold vertex (two fans)")


# ----------------------------------------------------------------------------------------------------------
# isometric bendings of the plane
# ----------------------------------------------------------------------------------------------------------


def bend_cylinder(uv: np.ndarray, radius: float) -> np.ndarray:
    """Roll the plane onto a cylinder of the given radius around the y axis (exact isometry).

    ``(x, y) -> (R sin(x/R), y, R cos(x/R))``; the normal of a counter-clockwise uv triangle points outward.

    Parameters
    ----------
    uv : (n,2) planar points. radius : R > 0.

    Returns
    -------
    (n,3) float64.
    """
    x, y = uv[:, 0] / radius, uv[:, 1]
    return np.column_stack([radius * np.sin(x), y, radius * np.cos(x)])


def wrap_cone(uv: np.ndarray, sector_angle: float) -> np.ndarray:
    """Wrap the plane (developed cone, apex at the origin) onto a cone (exact isometry away from the apex).

    A point at polar coordinates (r, theta) maps to ``(r s cos(theta/s), r s sin(theta/s), -r sqrt(1-s^2))``
    with ``s = sector_angle / (2 pi)``: apex at the origin, cone opening downward, slant distance ``r``
    preserved; the normal of a counter-clockwise uv triangle points outward. Injective for points whose polar
    angle in (-pi, pi] spans less than ``sector_angle``.

    Parameters
    ----------
    uv : (n,2) planar points. sector_angle : alpha in (0, 2 pi).

    Returns
    -------
    (n,3) float64.
    """
    if not 0 < sector_angle < 2 * np.pi:
        raise ValueError("sector_angle must be in (0, 2 pi)")
    s = sector_angle / (2 * np.pi)
    r = np.hypot(uv[:, 0], uv[:, 1])
    phi = np.arctan2(uv[:, 1], uv[:, 0]) / s
    return np.column_stack([r * s * np.cos(phi), r * s * np.sin(phi), -r * np.sqrt(1 - s * s)])


def lift_sphere(uv: np.ndarray, sphere_radius: float) -> np.ndarray:
    """Lift the plane onto a sphere: ``(x, y) -> (x, y, sqrt(R^2 - x^2 - y^2) - R)`` (NOT isometric).

    Parameters
    ----------
    uv : (n,2) planar points with ``|uv| < R``. sphere_radius : R.

    Returns
    -------
    (n,3) float64 (the cap's top is at the origin, normals of counter-clockwise uv triangles point up).
    """
    r2 = np.sum(uv**2, axis=1)
    if np.any(r2 >= sphere_radius**2):
        raise ValueError("domain does not fit under the sphere")
    return np.column_stack([uv, np.sqrt(sphere_radius**2 - r2) - sphere_radius])


# ----------------------------------------------------------------------------------------------------------
# generators
# ----------------------------------------------------------------------------------------------------------


def cylinder_patch(radius: float = 1.0, angle: float = 2.0, height: float = 1.5, h: float = 0.04) -> Shape:
    """Rectangle ``[0, radius*angle] x [0, height]`` rolled onto a cylinder of the given radius.

    Defaults: 2.0 x 1.5 patch, ~2.2k vertices, chord shortening of edges <= (h/R)^2/24 ~ 7e-5 relative.
    One boundary loop.
    """
    w = radius * angle
    uv, F = mesh_domain([polygon(np.array([[0, 0], [w, 0], [w, height], [0, height]]), h)], h)
    uv = uv - np.array([w / 2, height / 2])  # centre the patch on the z axis (symmetric arc)
    return Shape(bend_cylinder(uv, radius), F, uv, "cylinder_patch")


def cylinder_with_holes(
    radius: float = 1.0,
    angle: float = 2.4,
    height: float = 1.8,
    hole_radii: tuple[float, float] = (0.3, 0.35),
    notch_depth: float = 0.6,
    notch_width: float = 0.5,
    h: float = 0.045,
) -> Shape:
    """Cylinder patch ``[0, radius*angle] x [0, height]`` with two round holes and a V-shaped notch.

    The notch is a triangular bite into the bottom side (centred at 0.55 of the width, tip ``notch_depth`` up,
    opening ``notch_width`` wide): a concave border. Holes are centred at (0.25 w, 0.65 height) and
    (0.78 w, 0.5 height). Defaults: 2.4 x 1.8 patch, ~2.2k vertices, three boundary loops.
    """
    w = radius * angle
    cx = 0.55 * w
    outer = np.array(
        [
            [0, 0],
            [cx - notch_width / 2, 0],
            [cx, notch_depth],
            [cx + notch_width / 2, 0],
            [w, 0],
            [w, height],
            [0, height],
        ]
    )
    holes = [
        circle((0.25 * w, 0.65 * height), hole_radii[0], h, clockwise=True),
        circle((0.78 * w, 0.5 * height), hole_radii[1], h, clockwise=True),
    ]
    uv, F = mesh_domain([polygon(outer, h), *holes], h)
    uv = uv - np.array([w / 2, height / 2])
    return Shape(bend_cylinder(uv, radius), F, uv, "cylinder_with_holes")


def _s_loop(a: float, width: float, sweep: float, h: float) -> np.ndarray:
    """Closed loop of a band of the given width around an S curve of two arcs of radius a (centres (0, +-a)).

    The upper arc turns counter-clockwise around (0, a) from angle ``3pi/2 - sweep`` to ``3pi/2`` (the middle
    of the S at the origin), the lower one clockwise around (0, -a) from ``pi/2`` to ``pi/2 - sweep``; the two
    are symmetric under a half turn. Flat end caps.
    """
    hw = width / 2
    t_top = 1.5 * np.pi - sweep
    t_bot = 0.5 * np.pi - sweep
    return np.vstack(
        [
            _arc((0.0, a), a - hw, t_top, 1.5 * np.pi, h),  # upper arc, inner side
            _arc((0.0, -a), a + hw, 0.5 * np.pi, t_bot, h),  # lower arc, outer side
            _segment(
                tuple(np.array([0.0, -a]) + (a + hw) * np.array([np.cos(t_bot), np.sin(t_bot)])),
                tuple(np.array([0.0, -a]) + (a - hw) * np.array([np.cos(t_bot), np.sin(t_bot)])),
                h,
            ),
            _arc((0.0, -a), a - hw, t_bot, 0.5 * np.pi, h),  # lower arc, inner side
            _arc((0.0, a), a + hw, 1.5 * np.pi, t_top, h),  # upper arc, outer side
            _segment(
                tuple(np.array([0.0, a]) + (a + hw) * np.array([np.cos(t_top), np.sin(t_top)])),
                tuple(np.array([0.0, a]) + (a - hw) * np.array([np.cos(t_top), np.sin(t_top)])),
                h,
            ),
        ]
    )


def cone_s_strip(
    arc_radius: float = 0.5,
    width: float = 0.3,
    sweep: float = 1.5 * np.pi,
    apex_distance: float = 1.6,
    sector_angle: float = np.pi,
    h: float = 0.03,
) -> Shape:
    """S-shaped strip trimmed on a cone (the paper's Figure 12 'S-trimmed-on-cone' case).

    The strip is a band of ``width`` around an S-shaped centre curve made of two opposite circular arcs of
    radius ``arc_radius``, each sweeping ``sweep`` radians (pi = two semicircles; the default 3pi/2 curls the
    arms in so the gap between an arm's tip and the middle of the S, ``~1.24 a - width``, is narrow compared
    with the strip length ``2 a sweep``). The S is centred at ``(apex_distance, 0)`` in the developed plane of
    a cone of ``sector_angle`` (apex at the origin, outside the domain) and wrapped onto the cone with
    :func:`wrap_cone`. Defaults: ~2.0k vertices, chord shortening below ~3e-4 relative. One boundary loop.
    """
    if sweep < np.pi or sweep > 1.9 * np.pi:
        raise ValueError("sweep must be in [pi, 1.9 pi]")
    uv, F = mesh_domain([_s_loop(arc_radius, width, sweep, h)], h)
    uv = uv + np.array([apex_distance, 0.0])
    theta = np.arctan2(uv[:, 1], uv[:, 0])
    if uv[:, 0].min() <= 0 or np.ptp(theta) >= sector_angle:
        raise ValueError("the S must lie in a sector of angle < sector_angle away from the apex")
    return Shape(wrap_cone(uv, sector_angle), F, uv, "cone_s_strip")


def curved_cap_with_holes(
    semi_axes: tuple[float, float] = (1.0, 0.8), sphere_radius: float = 4.0, h: float = 0.035
) -> Shape:
    """Face-mask-like elliptic patch lifted onto a sphere: two elliptic eye holes and a thin mouth slot.

    NOT developable (positive Gaussian curvature ``1/sphere_radius^2``), so ``uv_true`` is ``None``. The
    planar domain (ellipse with the given semi-axes, eyes at ``(+-0.4 ax, 0.25 ay)``, a round-ended mouth slot
    of half-width 0.05 ax around ``y = -0.45 ay``) is lifted by :func:`lift_sphere`. Default sphere radius is
    4x the patch half-width (a gently curved cap). Defaults: ~2.3k vertices, four boundary loops.
    """
    ax, ay = semi_axes
    loops = [
        _ellipse((0.0, 0.0), ax, ay, h),
        _ellipse((-0.4 * ax, 0.25 * ay), 0.2 * ax, 0.12 * ay, h)[::-1],
        _ellipse((0.4 * ax, 0.25 * ay), 0.2 * ax, 0.12 * ay, h)[::-1],
        _stadium((-0.35 * ax, -0.45 * ay), (0.35 * ax, -0.45 * ay), 0.05 * ax, h)[::-1],
    ]
    uv, F = mesh_domain(loops, h)
    return Shape(lift_sphere(uv, sphere_radius), F, None, "curved_cap_with_holes")


def flat_disk(radius: float = 1.0, h: float = 0.04) -> Shape:
    """Planar disk (z = 0, ``uv_true = V[:, :2]``). Defaults: ~2.3k vertices, one boundary loop."""
    uv, F = mesh_domain([circle((0.0, 0.0), radius, h)], h)
    return Shape(np.column_stack([uv, np.zeros(len(uv))]), F, uv, "flat_disk")


def flat_square(side: float = 1.5, h: float = 0.035) -> Shape:
    """Planar square ``[-side/2, side/2]^2`` (z = 0, ``uv_true = V[:, :2]``). Defaults: ~2.1k vertices."""
    s = side / 2
    uv, F = mesh_domain([polygon(np.array([[-s, -s], [s, -s], [s, s], [-s, s]]), h)], h)
    return Shape(np.column_stack([uv, np.zeros(len(uv))]), F, uv, "flat_square")


def scale_shape(shape: Shape, s: float) -> Shape:
    """Uniformly scaled copy (V and uv_true times s; F and name unchanged)."""
    uv = None if shape.uv_true is None else shape.uv_true * s
    return Shape(shape.V * s, shape.F.copy(), uv, shape.name)


SHAPES: dict[str, Callable[..., Shape]] = {
    "cylinder_patch": cylinder_patch,
    "cylinder_with_holes": cylinder_with_holes,
    "cone_s_strip": cone_s_strip,
    "curved_cap_with_holes": curved_cap_with_holes,
    "flat_disk": flat_disk,
    "flat_square": flat_square,
}


def DEMO_SHAPE() -> Shape:  # noqa: N802 - a constant-like factory used by `heatparam demo`
    """The demo surface: :func:`noisy_scan_part` (a noisy scan-like part with two holes, in mm)."""
    return noisy_scan_part()


def noisy_scan_part(scale: float = 100.0, noise: float = 0.1, h: float = 0.03, seed: int = 0) -> Shape:
    """A scan-like sheet-metal part: a ``2.4 x 1.8`` rectangle with two round holes (radii 0.3 and 0.35, centred
    at (0.25, 0.65) and (0.72, 0.4) of the width and height) rolled onto a unit-radius cylinder, at ``scale``
    model units per unit (default: a 100 mm radius, a 240 × 180 mm flat pattern), with scanner noise.

    Every coordinate gets Gaussian noise of ``noise`` × the mean edge length (seeded by ``seed``: deterministic).
    The noise pulls a conformal layout away from an isometry, so the heat stage runs (it is not skipped) and its
    MDS layout competes as the refinement's start (start energy 1.0066; the spectral conformal map's 1.0029 wins).
    Defaults: 4806 vertices, 9197 faces, one outer loop and two hole loops.

    Returns
    -------
    Shape : V (n,3) noisy vertices in model units, F (m,3), ``uv_true`` (n,2) the noise-free flat layout in
        the same units (the answer up to noise), name ``"noisy_scan_part"``.
    """
    w, height = 2.4, 1.8
    holes = [circle((0.25 * w, 0.65 * height), 0.3, h, clockwise=True),
             circle((0.72 * w, 0.4 * height), 0.35, h, clockwise=True)]
    uv, F = mesh_domain([polygon(np.array([[0, 0], [w, 0], [w, height], [0, height]]), h), *holes], h)
    uv = (uv - np.array([w / 2, height / 2])) * scale
    V = bend_cylinder(uv, scale)
    edge = float(np.mean(np.linalg.norm(V[F[:, 1]] - V[F[:, 0]], axis=1)))
    V = V + noise * edge * np.random.default_rng(seed).standard_normal(V.shape)
    return Shape(V, F, uv, "noisy_scan_part")


# closed shapes for atlases: (V, F) with outward-facing triangles, one welded closed surface; each
# unfolds to a few charts at exact isometry (the cube to a net, the cylinder and the cone to their sides and caps)
def _weld(parts: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate (P, T) pieces, weld coincident points (rounded to 1e-9 of the extent), drop collapsed faces."""
    P = np.concatenate([p for p, _ in parts])
    offs = np.cumsum([0] + [len(p) for p, _ in parts[:-1]])
    T = np.concatenate([t + o for (_, t), o in zip(parts, offs, strict=True)])
    ext = float(np.ptp(P, axis=0).max())
    key = np.round(P / (ext * 1e-9)).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    V = P[first]
    F = inv.ravel()[T]
    ok = (F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])
    return V.astype(np.float64), F[ok].astype(np.int64)


def _grid_faces(nu: int, nv: int) -> np.ndarray:
    """Triangles of a (nu+1)×(nv+1) point grid (index i*(nv+1)+j), counter-clockwise in (i, j)."""
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = (i * (nv + 1) + j).ravel()
    b, c, d = a + nv + 1, a + nv + 2, a + 1
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def closed_cube(side: float = 1.0, n: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """A cube, each face an n×n grid of squares split in two: exactly developable away from its 8 corners
    (each corner has angle defect π/2), so it unfolds to one net at isometry."""
    s = np.linspace(0.0, side, n + 1)
    U, W = np.meshgrid(s, s, indexing="ij")
    u, w = U.ravel(), W.ravel()
    parts = []
    for axis in range(3):
        for hi in (0.0, side):
            P = np.zeros((len(u), 3))
            a1, a2 = (axis + 1) % 3, (axis + 2) % 3
            P[:, axis] = hi
            P[:, a1], P[:, a2] = u, w
            T = _grid_faces(n, n)
            if hi == 0.0:  # outward normal -axis: reverse
                T = T[:, ::-1]
            parts.append((P, T))
    return _weld(parts)


def _revolve(profile: np.ndarray, n_theta: int) -> tuple[np.ndarray, np.ndarray]:
    """Surface of revolution about z of a (k,2) profile (radius, z), outward when the profile runs with the
    surface on its left as seen from outside (radius decreasing upwards for a cone's side)."""
    th = np.linspace(0.0, 2 * np.pi, n_theta, endpoint=False)
    P = np.array([[r * np.cos(t), r * np.sin(t), z] for t in th for r, z in profile])
    k = len(profile)
    T = []
    for i in range(n_theta):
        i2 = (i + 1) % n_theta
        for j in range(k - 1):
            a, b, c, d = i * k + j, i2 * k + j, i2 * k + j + 1, i * k + j + 1
            T += [(a, b, c), (a, c, d)]
    return P, np.array(T, dtype=np.int64)


def _disk_profile(radius: float, z: float, rings: int, up: bool) -> np.ndarray:
    r = np.linspace(radius, 0.0, rings + 1)
    prof = np.column_stack([r, np.full_like(r, z)])
    return prof if up else prof[::-1]


def capped_cylinder(radius: float = 0.5, height: float = 1.5, n_theta: int = 48, n_z: int = 18,
                    rings: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """A closed prism-like cylinder (side: ``n_theta`` planar strips) with flat caps: developable pieces
    (side unrolls to a rectangle, caps are flat) meeting at two sharp circles."""
    z = np.linspace(0.0, height, n_z + 1)
    side = _revolve(np.column_stack([np.full_like(z, radius), z]), n_theta)
    top = _revolve(_disk_profile(radius, height, rings, up=True), n_theta)
    bottom = _revolve(_disk_profile(radius, 0.0, rings, up=False), n_theta)
    return _weld([side, top, bottom])


def cone_with_base(radius: float = 0.6, height: float = 1.2, n_theta: int = 48, n_s: int = 18,
                   rings: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """A closed pyramid-like cone (side: ``n_theta`` planar triangles fanned to the apex) on a flat disk: the side
    unrolls to a sector once cut from the apex to the base, the base is flat."""
    t = np.linspace(0.0, 1.0, n_s + 1)
    side = _revolve(np.column_stack([radius * (1 - t), height * t]), n_theta)
    bottom = _revolve(_disk_profile(radius, 0.0, rings, up=False), n_theta)
    return _weld([side, bottom])


def torus(major: float = 1.0, minor: float = 0.35, n_major: int = 48, n_minor: int = 20
          ) -> tuple[np.ndarray, np.ndarray]:
    """A closed torus of revolution (genus 1, not developable)."""
    a = np.linspace(0.0, 2 * np.pi, n_minor, endpoint=False)
    prof = np.column_stack([major + minor * np.cos(a), minor * np.sin(a)])
    prof = np.vstack([prof, prof[:1]])  # close the profile; the weld joins the seam
    return _weld([_revolve(prof, n_major)])
