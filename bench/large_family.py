"""Issue 42's family of scan-like large parts: ``draw(seed) -> (V, F, description)``, deterministic per seed.

A part is one of six kinds, drawn with equal odds:

* ``developable``  a sheet rolled on a cylinder, a cone or a curve of varying curvature (exact isometries);
* ``cad``          a sheet-metal profile with filleted bends (flats joined by cylinder arcs) and bolt-pattern holes;
* ``cap``          a doubly curved cap (elliptic paraboloid or sphere, a few bumps);
* ``mask``         a face mask: an oval on a face-like height field with two eye holes close together;
* ``saddle``       a saddle or monkey saddle;
* ``range``        one range image of a curved object, triangulated pixel by pixel: ragged border, dropouts as holes,
                   bowties, islands and loose points where pixels are missing, depth noise along the rays.

The first five are meshed in a planar domain (outer loop with low-frequency wobble, 0-10 holes of varied shape,
size and placement, some pairs close together like eyes; a regular lattice at the spacing that gives the drawn
face count, 150k-400k faces), warped in the plane for a non-uniform density (up to ~4x in triangle area), lifted
to 3D, then given noise of 0-0.3 x the mean edge length (normal along the normals, normal in 3D, uniform in 3D, or
normal with a few outliers of 1-3 edges) and real-scan defects, each with its own odds: bowtie vertices (two
non-adjacent faces of a vertex's ring removed), small floating islands (copies of small patches off the surface),
loose points (unreferenced vertices), a few zero-area faces (border slivers on a boundary edge's midpoint).

Run ``python bench/large_family.py 0 1 2`` to print the parts' descriptions; ``--ply DIR`` writes them as binary PLY.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from matplotlib.path import Path as PolyPath
from scipy.spatial import cKDTree

from heatparam import datasets
from heatparam.mesh.planar import polygon_area

KINDS = ("developable", "cad", "cap", "mask", "saddle", "range")
NOISE = ("normal_along_normals", "normal_3d", "uniform_3d", "normal_with_outliers")


def draw(seed: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """The part of ``seed``: V (n,3) float64, F (m,3) int64 and a description (JSON-able dict: kind, sizes, holes,
    noise, density warp, defects)."""
    rng = np.random.default_rng(seed)
    kind = KINDS[int(rng.integers(len(KINDS)))]
    faces = int(rng.uniform(150_000, 400_000))
    desc: dict = {"seed": int(seed), "kind": kind}
    if kind == "range":
        V, F = range_image(rng, faces, desc)
    else:
        V, F = sheet(rng, kind, faces, desc)
        V = add_noise(rng, V, F, desc)
    V, F = scan_defects(rng, V, F, desc)
    size = float(np.exp(rng.uniform(np.log(80.0), np.log(600.0))))  # mm across, as scanners write parts
    V = V * (size / float(np.linalg.norm(np.ptp(V, axis=0))))
    desc.update(vertices=len(V), faces=len(F), diagonal_mm=round(size, 1))
    return V, F, desc


# ------------------------------------------------------------------------------------------------ planar domains


def _wobbly(rng, center, a: float, b: float, h: float, amp: float, angle: float = 0.0) -> np.ndarray:
    """Closed counter-clockwise loop on an ellipse (semi-axes a, b, rotated by angle) whose radius wobbles by
    ``amp`` (relative) in a few low harmonics, spacing <= h. (k,2)."""
    t = np.linspace(0.0, 2 * np.pi, 8193)[:-1]
    k = np.arange(2, 7)
    c, ph = amp * rng.uniform(-1, 1, len(k)) / k, rng.uniform(0, 2 * np.pi, len(k))
    r = 1.0 + np.cos(np.outer(t, k) + ph) @ c
    p = np.column_stack([a * r * np.cos(t), b * r * np.sin(t)])
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    p = p @ rot.T + np.asarray(center)
    closed = np.vstack([p, p[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    n = max(12, int(np.ceil(s[-1] / (0.9 * h))))
    tt = np.arange(n) * s[-1] / n
    return np.column_stack([np.interp(tt, s, closed[:, 0]), np.interp(tt, s, closed[:, 1])])


def _rounded_rect(w: float, hgt: float, r: float, h: float) -> np.ndarray:
    """Counter-clockwise rectangle [-w/2, w/2] x [-hgt/2, hgt/2] with corner radius r, spacing <= h."""
    cx, cy = w / 2 - r, hgt / 2 - r
    parts = []
    for (sx, sy), t0 in zip([(1, -1), (1, 1), (-1, 1), (-1, -1)], [-np.pi / 2, 0, np.pi / 2, np.pi], strict=True):
        parts.append(datasets._arc((sx * cx, sy * cy), r, t0, t0 + np.pi / 2, h))
        end = np.array([sx * cx, sy * cy]) + r * np.array([np.cos(t0 + np.pi / 2), np.sin(t0 + np.pi / 2)])
        nxt = {(1, -1): (1, 1), (1, 1): (-1, 1), (-1, 1): (-1, -1), (-1, -1): (1, -1)}[(sx, sy)]
        t1 = t0 + np.pi / 2
        start = np.array([nxt[0] * cx, nxt[1] * cy]) + r * np.array([np.cos(t1), np.sin(t1)])
        parts.append(datasets._segment(tuple(end), tuple(start), h))
    return np.vstack(parts)


def _outer(rng, kind: str, h_guess: float) -> tuple[np.ndarray, float]:
    """The outer loop of a kind (about unit size) and its half-size."""
    if kind in ("developable", "cad"):
        w, hgt = rng.uniform(1.6, 3.0), rng.uniform(1.0, 1.8)
        return _rounded_rect(w, hgt, rng.uniform(0.02, 0.3) * min(w, hgt), h_guess), min(w, hgt) / 2
    if kind == "mask":
        a = rng.uniform(0.9, 1.1)
        return _wobbly(rng, (0.0, 0.0), a * 0.8, a, h_guess, 0.05), 0.8 * a
    a, b = rng.uniform(0.8, 1.2), rng.uniform(0.7, 1.2)
    return _wobbly(rng, (0.0, 0.0), a, b, h_guess, rng.uniform(0.0, 0.15), rng.uniform(0, np.pi)), min(a, b)


def _hole(rng, center, size: float, h: float) -> np.ndarray:
    """A clockwise hole loop of about ``size`` radius: circle, ellipse, slot or wobbly blob."""
    shape = int(rng.integers(4))
    ang = rng.uniform(0, np.pi)
    if shape == 0:
        loop = datasets.circle(tuple(center), size, h)
    elif shape == 1:
        loop = _wobbly(rng, center, size, size * rng.uniform(0.35, 0.9), h, 0.0, ang)
    elif shape == 2:
        d = size * rng.uniform(0.4, 0.8) * np.array([np.cos(ang), np.sin(ang)])
        loop = datasets._stadium(tuple(center - d), tuple(center + d), size - np.linalg.norm(d) * 0.9, h)
    else:
        loop = _wobbly(rng, center, size, size * rng.uniform(0.6, 1.0), h, 0.25, ang)
    return loop[::-1].copy()


def _place_holes(rng, kind: str, outer: np.ndarray, half: float, h: float) -> tuple[list[np.ndarray], list[dict]]:
    """0-10 holes inside ``outer``, at least a few edges from it and from each other; the mask gets two eyes close
    together, other kinds a close pair with odds 1/3."""
    tree, inside, margin = cKDTree(outer), PolyPath(outer), 4 * h
    placed: list[tuple[np.ndarray, float]] = []

    def fits(c: np.ndarray, r: float) -> bool:
        return bool(inside.contains_point(c)) and tree.query(c)[0] > r * 1.3 + margin

    n = int(rng.integers(0, 11)) if kind != "mask" else int(rng.integers(2, 6))
    if kind == "mask" or (n >= 2 and rng.random() < 1 / 3):  # a pair close together, like eyes
        gap, r = rng.uniform(0.03, 0.12) * half, rng.uniform(0.08, 0.2) * half
        c = np.array([0.0, rng.uniform(0.1, 0.3) * half]) if kind == "mask" else rng.uniform(-0.4, 0.4, 2) * half
        pair = [(c - [r + gap / 2, 0], r), (c + [r + gap / 2, 0], r)]
        if all(fits(q, s) for q, s in pair):
            placed += pair
    for _ in range(400):
        if len(placed) >= n:
            break
        r = half * np.exp(rng.uniform(np.log(0.015), np.log(0.25)))
        c = rng.uniform(outer.min(axis=0), outer.max(axis=0))
        if fits(c, r) and all(np.linalg.norm(c - q) > 1.3 * (r + s) + margin for q, s in placed):
            placed.append((c, r))
    loops = [_hole(rng, c, r, h) for c, r in placed]
    return loops, [{"center": [round(float(x), 3) for x in c], "radius": round(float(r), 4)} for c, r in placed]


def mesh_loops(loops: list[np.ndarray], h: float) -> tuple[np.ndarray, np.ndarray]:
    """Triangulate a planar domain (outer loop first, then holes; samples <= h apart) on a regular lattice of
    spacing h, as ``heatparam.datasets.mesh_domain`` does, with the lattice's distance to the border from a k-d tree
    of the border sampled at h/8 instead of every point against every segment (quadratic at 400k faces).

    Returns uv (n,2) float64, F (m,3) int64 counter-clockwise."""
    loops = [datasets._orient(np.asarray(lp, dtype=np.float64), ccw=(i == 0)) for i, lp in enumerate(loops)]
    allb = np.vstack(loops)
    cand = datasets._lattice(allb.min(axis=0), allb.max(axis=0), h)
    cand = cand[datasets._inside(cand, loops)]
    dense = np.vstack([lp + t * (np.roll(lp, -1, axis=0) - lp) for lp in loops for t in np.arange(8) / 8])
    interior = cand[cKDTree(dense).query(cand)[0] > 0.55 * h]
    for _ in range(13):
        pts, T = datasets._constrained_candidates(loops, interior, h)
        loops, missing = datasets._split_missing_segments(loops, T, len(pts))
        if missing == 0:
            break
    used = np.unique(T)
    remap = np.full(len(pts), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return pts[used], remap[T]


def _density_warp(rng, uv: np.ndarray, desc: dict) -> np.ndarray:
    """A monotone per-axis warp x -> x + b sin(2 pi k x / L) L / (2 pi k) (|b| < 1): the lattice's triangles become
    up to (1+b)/(1-b) larger in one place than in another."""
    if rng.random() < 0.35:
        desc["density"] = "uniform"
        return uv
    out = uv.copy()
    b = rng.uniform(0.2, 0.6, 2)
    k = rng.integers(1, 3, 2)
    for ax in range(2):
        lo, L = uv[:, ax].min(), np.ptp(uv[:, ax])
        w = 2 * np.pi * k[ax] / L
        out[:, ax] = uv[:, ax] + b[ax] * np.sin(w * (uv[:, ax] - lo)) / w
    desc["density"] = f"sine warp b={b.round(2).tolist()} k={k.tolist()}"
    return out


def sheet(rng, kind: str, faces: int, desc: dict) -> tuple[np.ndarray, np.ndarray]:
    """A planar domain of the kind, meshed to about ``faces`` faces, warped, lifted to 3D."""
    sub = int(rng.integers(2**32))
    outer, half = _outer(np.random.default_rng(sub), kind, 0.01)
    h = float(np.sqrt(4 * polygon_area(outer) / (np.sqrt(3) * faces)))
    outer, half = _outer(np.random.default_rng(sub), kind, h)  # the same outline, sampled at h
    holes, hdesc = _place_holes(rng, kind, outer, half, h)
    uv, F = mesh_loops([outer, *holes], h)
    uv = _density_warp(rng, uv, desc)
    desc["holes"] = len(holes)
    desc["hole_list"] = hdesc
    return LIFTS[kind](rng, uv, half, desc), F


# ------------------------------------------------------------------------------------------------------- lifts


def _profile(uv: np.ndarray, kappa: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Roll the plane along x onto the curve of curvature kappa(s) (sampled at s, covering uv's x): an exact
    isometry (x -> arc length along the curve, y -> the extrusion direction)."""
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (kappa[1:] + kappa[:-1]) * np.diff(s))])
    X = np.concatenate([[0.0], np.cumsum(0.5 * (np.cos(theta[1:]) + np.cos(theta[:-1])) * np.diff(s))])
    Z = np.concatenate([[0.0], np.cumsum(0.5 * (np.sin(theta[1:]) + np.sin(theta[:-1])) * np.diff(s))])
    x = uv[:, 0]
    return np.column_stack([np.interp(x, s, X), uv[:, 1], np.interp(x, s, Z)])


def _lift_developable(rng, uv, half, desc):
    s = np.linspace(uv[:, 0].min(), uv[:, 0].max(), 20001)
    style = int(rng.integers(3))
    if style == 0:
        R = half * rng.uniform(0.6, 4.0)
        desc["surface"] = f"cylinder R={R:.2f}"
        return _profile(uv, np.full_like(s, 1 / R), s)
    if style == 1:
        L = np.ptp(s)
        kappa = rng.uniform(0.2, 0.8) / half * np.sin(2 * np.pi * rng.uniform(0.5, 1.5) * (s - s[0]) / L
                                                       + rng.uniform(0, 2 * np.pi))
        desc["surface"] = "rolled on a curve of varying curvature"
        return _profile(uv, kappa, s)
    sector = rng.uniform(0.8, 1.6) * np.pi
    d = np.ptp(uv[:, 1]) / (2 * np.tan(0.4 * sector)) + half * rng.uniform(0.3, 1.0)
    p = uv + np.array([d - uv[:, 0].min(), -uv[:, 1].mean()])
    desc["surface"] = f"cone sector {sector:.2f}"
    return datasets.wrap_cone(p[:, [0, 1]], sector)


def _lift_cad(rng, uv, half, desc):
    """Flats joined by filleted bends of 30-90 degrees (cumulative angle kept within +-100 degrees)."""
    s = np.linspace(uv[:, 0].min(), uv[:, 0].max(), 40001)
    L = np.ptp(s)
    nb = int(rng.integers(1, 5))
    kappa = np.zeros_like(s)
    at = np.sort(rng.uniform(0.1, 0.9, nb)) * L + s[0]
    total = 0.0
    for a in at:
        ang = rng.uniform(np.pi / 6, np.pi / 2) * rng.choice([-1, 1])
        if abs(total + ang) > np.radians(100):
            ang = -ang
        total += ang
        r = half * rng.uniform(0.02, 0.15)
        kappa[(s >= a) & (s < a + r * abs(ang))] = np.sign(ang) / r
    desc["surface"] = f"sheet-metal profile, {nb} filleted bends"
    return _profile(uv, kappa, s)


def _lift_cap(rng, uv, half, desc):
    k1, k2 = rng.uniform(0.3, 1.2, 2) / half
    z = -0.5 * (k1 * uv[:, 0] ** 2 + k2 * uv[:, 1] ** 2)
    for _ in range(int(rng.integers(0, 4))):
        c, w = rng.uniform(-0.6, 0.6, 2) * half, rng.uniform(0.1, 0.3) * half
        z += rng.uniform(-0.3, 0.3) * w * np.exp(-np.sum((uv - c) ** 2, axis=1) / (2 * w * w))
    desc["surface"] = f"elliptic paraboloid k=({k1:.2f}, {k2:.2f}) with bumps"
    return np.column_stack([uv, z])


def _lift_mask(rng, uv, half, desc):
    x, y = uv[:, 0] / half, uv[:, 1] / half
    kx, ky = rng.uniform(0.8, 1.6), rng.uniform(0.3, 0.8)
    z = -0.5 * half * (kx * x**2 + ky * y**2)
    z += half * rng.uniform(0.12, 0.25) * np.exp(-(x**2) / 0.02 - (y + 0.1) ** 2 / 0.12)  # nose
    z += half * rng.uniform(0.02, 0.06) * np.exp(-((y - 0.45) ** 2) / 0.01)  # brow
    desc["surface"] = "face mask (cap, nose, brow)"
    return np.column_stack([uv, z])


def _lift_saddle(rng, uv, half, desc):
    x, y = uv[:, 0] / half, uv[:, 1] / half
    if rng.random() < 0.7:
        a, b = rng.uniform(0.2, 0.7, 2)
        desc["surface"] = f"saddle ({a:.2f}, {b:.2f})"
        return np.column_stack([uv, 0.5 * half * (a * x**2 - b * y**2)])
    a = rng.uniform(0.1, 0.3)
    desc["surface"] = f"monkey saddle {a:.2f}"
    return np.column_stack([uv, half * a * (x**3 - 3 * x * y**2)])


LIFTS = {"developable": _lift_developable, "cad": _lift_cad, "cap": _lift_cap, "mask": _lift_mask,
         "saddle": _lift_saddle}


# -------------------------------------------------------------------------------------------------------- noise


def mean_edge(V: np.ndarray, F: np.ndarray) -> float:
    """Mean length of the faces' edges (each interior edge counted twice)."""
    return float(np.mean(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=2)))


def vertex_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals, (n,3) (zero where a vertex is in no face)."""
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    N = np.column_stack([np.bincount(F.ravel(), np.repeat(fn[:, k], 3), minlength=len(V)) for k in range(3)])
    return N / np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)


def add_noise(rng, V: np.ndarray, F: np.ndarray, desc: dict) -> np.ndarray:
    """Noise of 0-0.3 x the mean edge length: normal along the normals, normal or uniform in 3D, or normal along
    the normals with 0.02-0.1% outliers moved 1-3 edges."""
    e = mean_edge(V, F)
    rel = rng.uniform(0.0, 0.3)
    kind = NOISE[int(rng.integers(len(NOISE)))]
    N = vertex_normals(V, F)
    if kind == "normal_3d":
        D = rel * e * rng.standard_normal(V.shape)
    elif kind == "uniform_3d":
        D = rel * e * np.sqrt(3) * rng.uniform(-1, 1, V.shape)
    else:
        D = rel * e * rng.standard_normal(len(V))[:, None] * N
    desc["noise"] = f"{kind} {rel:.3f}"
    if kind == "normal_with_outliers":
        idx = rng.choice(len(V), max(1, int(len(V) * rng.uniform(2e-4, 1e-3))), replace=False)
        D[idx] += (rng.uniform(1, 3, len(idx)) * rng.choice([-1, 1], len(idx)) * e)[:, None] * N[idx]
        desc["noise"] += f" + {len(idx)} outliers"
    return V + D


# ------------------------------------------------------------------------------------------------ range images


def _range_depth(rng, X: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, str]:
    """A smooth height field over normalized image coordinates (object towards the camera): (H,W), its name."""
    style = int(rng.integers(3))
    if style == 0:
        z = 0.5 * (1.2 * X**2 + 0.5 * Y**2) - 0.2 * np.exp(-(X**2) / 0.02 - (Y + 0.1) ** 2 / 0.1)
        return z, "face-like"
    if style == 1:
        return 0.5 * rng.uniform(0.3, 1.2) * X**2, "cylinder-like"
    z = 0.5 * rng.uniform(-0.5, 0.8) * (X**2 + Y**2)
    for _ in range(int(rng.integers(2, 6))):
        c, w = rng.uniform(-0.6, 0.6, 2), rng.uniform(0.1, 0.35)
        z += rng.uniform(-0.15, 0.15) * np.exp(-((X - c[0]) ** 2 + (Y - c[1]) ** 2) / (2 * w * w))
    return z, "free-form"


def _range_mask(rng, X: np.ndarray, Y: np.ndarray, desc: dict) -> np.ndarray:
    """Valid pixels: a wobbly silhouette with a ragged (pixel-noisy) border and 0-8 dropout blobs."""
    th, r = np.arctan2(Y, X), np.hypot(X / 0.95, Y / 0.85)
    k = np.arange(2, 9)
    c, ph = rng.uniform(-0.1, 0.1, len(k)) / np.sqrt(k), rng.uniform(0, 2 * np.pi, len(k))
    edge = 1.0 + np.cos(th[..., None] * k + ph) @ c
    px = np.ptp(X) / X.shape[1]
    valid = r < edge + rng.uniform(1.0, 4.0) * px * rng.standard_normal(X.shape) / np.maximum(r, 0.1)
    nd = int(rng.integers(0, 9))
    for _ in range(nd):
        cc = rng.uniform(-0.6, 0.6, 2)
        a = np.exp(rng.uniform(np.log(2 * px), np.log(0.15)))
        b = a * rng.uniform(0.3, 1.0)
        valid &= ((X - cc[0]) / a) ** 2 + ((Y - cc[1]) / b) ** 2 > 1
    desc["dropouts"] = nd
    return valid


def _grid_faces(valid: np.ndarray) -> np.ndarray:
    """Two triangles per quad of valid pixels, one where exactly three are valid (its valid corners), (m,3)."""
    H, W = valid.shape
    idx = np.arange(H * W).reshape(H, W)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    va, vb, vc, vd = valid[:-1, :-1], valid[:-1, 1:], valid[1:, :-1], valid[1:, 1:]
    tris = [(a, c, b, va & vc & vb), (b, c, d, vb & vc & vd & va),
            (b, c, d, vb & vc & vd & ~va), (a, d, b, va & vd & vb & ~vc), (a, c, d, va & vc & vd & ~vb)]
    return np.vstack([np.column_stack([p[m], q[m], r[m]]) for p, q, r, m in tris]).astype(np.int64)


def range_image(rng, faces: int, desc: dict) -> tuple[np.ndarray, np.ndarray]:
    """One perspective range image of a curved object, triangulated on the pixel grid; long edges (depth jumps)
    dropped; depth noise of 0-0.3 pixel footprints along the rays; isolated valid pixels stay as loose points."""
    aspect = rng.uniform(1.0, 1.5)
    W = int(np.sqrt(faces / 2 / 0.52 * aspect))
    H = int(W / aspect)
    X, Y = np.meshgrid(np.linspace(-1.1 * aspect, 1.1 * aspect, W), np.linspace(-1.1, 1.1, H))
    z, name = _range_depth(rng, X, Y)
    valid = _range_mask(rng, X / aspect, Y, desc)
    f = 1.0 / np.tan(np.radians(rng.uniform(15, 25)))
    depth = 4.0 + z
    gz = np.hypot(*np.gradient(z, 2.2 / H))
    valid &= gz < np.tan(np.radians(80))  # grazing angles return nothing
    rel = rng.uniform(0.0, 0.3)
    pix = depth.mean() * 2.2 / H / f
    depth = depth + rel * pix * rng.standard_normal(depth.shape)
    V = np.column_stack([(X * depth / f).ravel(), (Y * depth / f).ravel(), -depth.ravel()])
    F = _grid_faces(valid)
    L = np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=2).max(axis=1)
    F = F[L < 4 * pix * 1.5]
    keep = np.flatnonzero(valid.ravel())
    remap = np.full(len(V), -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    desc.update(surface=f"range image {W}x{H} of a {name} object", noise=f"depth normal {rel:.3f}",
                density="perspective")
    return V[keep], remap[F]


# ------------------------------------------------------------------------------------------------ scan defects


def _boundary_edges(F: np.ndarray, n: int) -> np.ndarray:
    """Directed edges (as in their face) with no reverse twin, (k,2)."""
    E = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    key, rev = E[:, 0] * n + E[:, 1], E[:, 1] * n + E[:, 0]
    return E[~np.isin(key, rev)]


def _bowties(rng, F: np.ndarray, n: int, count: int) -> np.ndarray:
    """Remove two faces of an interior vertex's ring that share no edge: the vertex joins two fans."""
    bnd = np.zeros(n, dtype=bool)
    bnd[_boundary_edges(F, n).ravel()] = True
    order = np.argsort(F.ravel(), kind="stable")
    starts = np.searchsorted(F.ravel()[order], np.arange(n + 1))
    drop: list[int] = []
    for v in rng.permutation(np.flatnonzero(~bnd))[: count * 4]:
        ring = order[starts[v] : starts[v + 1]] // 3
        if len(ring) < 5 or bnd[F[ring].ravel()].any():
            continue
        f1 = ring[0]
        far = [f for f in ring[1:] if len(set(F[f].tolist()) & set(F[f1].tolist())) == 1]
        drop += [int(f1), int(far[int(rng.integers(len(far)))])]
        if len(drop) >= 2 * count:
            break
    return np.delete(F, drop, axis=0)


def _islands(rng, V: np.ndarray, F: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Copies of small patches (faces within 2-6 edges of a vertex) floated 2-10 edges off the surface."""
    e = mean_edge(V, F)
    N = vertex_normals(V, F)
    C = V[F].mean(axis=1)
    tree = cKDTree(C)
    Vs, Fs = [V], [F]
    n = len(V)
    for v in rng.choice(len(V), count, replace=False):
        if not np.any(N[v]):
            continue
        patch = F[tree.query_ball_point(V[v], rng.uniform(2, 6) * e)]
        ids, inv = np.unique(patch, return_inverse=True)
        Vs.append(V[ids] + N[v] * rng.uniform(2, 10) * e * rng.choice([-1, 1]))
        Fs.append(inv.reshape(-1, 3) + n)
        n += len(ids)
    return np.vstack(Vs), np.vstack(Fs)


def _slivers(rng, V: np.ndarray, F: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Zero-area faces: a boundary edge (a, b) gets the face (b, a, midpoint)."""
    E = _boundary_edges(F, len(V))
    pick = E[rng.choice(len(E), min(count, len(E)), replace=False)]
    M = 0.5 * (V[pick[:, 0]] + V[pick[:, 1]])
    newF = np.column_stack([pick[:, 1], pick[:, 0], len(V) + np.arange(len(pick))])
    return np.vstack([V, M]), np.vstack([F, newF])


def scan_defects(rng, V: np.ndarray, F: np.ndarray, desc: dict) -> tuple[np.ndarray, np.ndarray]:
    """Each with its own odds: bowties (1-8), islands (1-25), loose points (1-800), zero-area faces (1-5)."""
    d = {}
    if rng.random() < 0.4:
        d["bowties"] = int(rng.integers(1, 9))
        F = _bowties(rng, F, len(V), d["bowties"])
    if rng.random() < 0.4:
        d["islands"] = int(rng.integers(1, 26))
        V, F = _islands(rng, V, F, d["islands"])
    if rng.random() < 0.4:
        d["loose_points"] = int(rng.integers(1, 801))
        e = mean_edge(V, F)
        V = np.vstack([V, V[rng.choice(len(V), d["loose_points"])] + rng.normal(0, 3 * e, (d["loose_points"], 3))])
    if rng.random() < 0.4:
        d["zero_area_faces"] = int(rng.integers(1, 6))
        V, F = _slivers(rng, V, F, d["zero_area_faces"])
    desc["defects"] = d
    return V, F


# ------------------------------------------------------------------------------------------------------ output


def write_ply(path: str | Path, V: np.ndarray, F: np.ndarray) -> None:
    """Binary little-endian PLY (float64 vertices, uint8 + int32 face lists), as scanners write them."""
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(V)}\nproperty double x\nproperty double y\n"
            f"property double z\nelement face {len(F)}\nproperty list uchar int vertex_indices\nend_header\n")
    rec = np.zeros(len(F), dtype=[("n", "u1"), ("f", "<i4", 3)])
    rec["n"], rec["f"] = 3, F
    with open(path, "wb") as fh:
        fh.write(head.encode("ascii"))
        fh.write(np.ascontiguousarray(V, dtype="<f8").tobytes())
        fh.write(rec.tobytes())


def summary(desc: dict) -> str:
    """One short line: kind, surface, faces, holes, noise, density, defects."""
    d = desc.get("defects", {})
    defects = ", ".join(f"{v} {k.replace('_', ' ')}" for k, v in d.items()) or "no defects"
    holes = desc.get("holes", f"{desc.get('dropouts', 0)} dropouts")
    return (f"{desc['kind']}: {desc.get('surface', '')}; {desc['faces']} faces; holes {holes}; "
            f"noise {desc.get('noise', '')}; density {desc.get('density', '')}; {defects}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seeds", nargs="+", type=int)
    ap.add_argument("--ply", default=None, help="write each part as DIR/part<seed>.ply")
    ap.add_argument("--json", action="store_true", help="print the full description")
    args = ap.parse_args()
    for seed in args.seeds:
        V, F, desc = draw(seed)
        if args.ply:
            Path(args.ply).mkdir(parents=True, exist_ok=True)
            write_ply(Path(args.ply) / f"part{seed}.ply", V, F)
        print(json.dumps(desc) if args.json else f"{seed}: {summary(desc)}", flush=True)


if __name__ == "__main__":
    main()
