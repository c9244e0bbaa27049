"""A seeded family of CAD-like closed parts for the STEP crease rule (issue 45, ``bench_step.py --family``).

``draw(seed) -> (V, F, description, expected)``: a prism, the extrusion of a random 2D profile, meshed the way a
CAD export or a mesher might have it:

- the profile: a convex polygon of 4-7 corners whose turns lie in 10°-120° (rejection sampling), maybe a
  rectangular notch cut into its longest side (concave corners of 90°), then each corner kept sharp, chamfered (a
  straight cut: two turns of half the angle) or filleted (a tangent circular arc of random radius);
- maybe one or two circular through-holes;
- the mesh: a random target edge length (coarse to fine, 1.2%-6% of the profile's diagonal), either uniform or
  non-uniform (each profile segment sampled at its own spacing, the extrusion's layers at random heights), and
  sometimes "CAD-export-like": caps triangulated from their border samples alone (fans of slivers) and the side
  walls one layer deep (triangles as long as the part).

``expected`` is what a CAD user sees in the B-rep: one planar face per straight profile segment, one cylindrical
face per fillet arc and per hole, two planar caps; ``faces`` is their sum. The caps are meshed by
``heatparam.datasets.mesh_domain`` (Delaunay of the border samples and an interior lattice); the side walls are
built on the caps' border edges, so the result is closed and outward oriented.
"""

from __future__ import annotations

import numpy as np
from shapely.geometry import Point, Polygon

from heatparam.datasets import _arc, _segment, mesh_domain

TURNS = (10.0, 120.0)  # degrees: the range of a sharp corner's turn


def _convex(rng: np.random.Generator) -> np.ndarray:
    """Corners (k,2) of a counter-clockwise convex polygon whose turns all lie in TURNS, about 2 across."""
    while True:
        k = int(rng.integers(4, 8))
        t = np.sort(rng.uniform(0, 2 * np.pi, k))
        aspect = rng.uniform(0.5, 1.0)
        P = np.column_stack([np.cos(t), aspect * np.sin(t)]) * rng.uniform(0.8, 1.2, (k, 1))
        if Polygon(P).convex_hull.area > Polygon(P).area + 1e-12:
            continue
        turns = np.degrees(_turns(P))
        if turns.min() >= TURNS[0] and turns.max() <= TURNS[1]:
            return P


def _turns(P: np.ndarray) -> np.ndarray:
    """The signed turn (radians, left positive) at every corner of the closed polygon P (k,2)."""
    d_in = P - np.roll(P, 1, axis=0)
    d_out = np.roll(P, -1, axis=0) - P
    cross = d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0]
    return np.arctan2(cross, np.einsum("ij,ij->i", d_in, d_out))


def _notched(P: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """P with a rectangular notch cut into the middle of its longest side (4 corners more, two of them concave)."""
    L = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
    i = int(np.argmax(L))
    a, b = P[i], P[(i + 1) % len(P)]
    d = (b - a) / L[i]
    inward = np.array([-d[1], d[0]])
    w = rng.uniform(0.2, 0.4) * L[i]
    depth = rng.uniform(0.15, 0.35) * min(w * 2, Polygon(P).area / L[i])
    c = a + d * (0.5 * L[i] - 0.5 * w)
    notch = [c, c + inward * depth, c + d * w + inward * depth, c + d * w]
    return np.vstack([P[: i + 1], notch, P[i + 1:]])


class _Profile:
    """The profile's closed boundary as segments ("line" or "arc") and their samples, built corner by corner."""

    def __init__(self, corners: np.ndarray, rng: np.random.Generator):
        self.corners, self.rng = corners, rng
        k = len(corners)
        self.turn = _turns(corners)
        L = np.linalg.norm(np.roll(corners, -1, axis=0) - corners, axis=1)
        self.room = 0.4 * np.minimum(L, np.roll(L, 1))  # cut length along each side, at most 0.4 of it
        self.kind = []
        for c in range(k):  # chamfer only where both halves keep a turn of at least TURNS[0]
            r = rng.uniform()
            can_chamfer = abs(np.degrees(self.turn[c])) >= 2 * TURNS[0]
            self.kind.append("chamfer" if r < 0.25 and can_chamfer else "fillet" if r < 0.5 else "sharp")
        self.cut = np.array([0.0 if kd == "sharp" else rng.uniform(0.25, 1.0) * self.room[c]
                             for c, kd in enumerate(self.kind)])

    def segments(self) -> list[tuple]:
        """[(kind, data)] in order: ("line", (p0, p1)) or ("arc", (center, radius, t0, t1))."""
        P, k, out = self.corners, len(self.corners), []
        for c in range(k):
            prev, nxt = P[c - 1], P[(c + 1) % k]
            a = P[c] + (prev - P[c]) / np.linalg.norm(prev - P[c]) * self.cut[c]  # where the corner's cut starts
            b = P[c] + (nxt - P[c]) / np.linalg.norm(nxt - P[c]) * self.cut[c]
            if self.kind[c] == "chamfer":
                out.append(("line", (a, b)))
            elif self.kind[c] == "fillet":
                out.append(("arc", _fillet(a, b, P[c], self.turn[c], self.cut[c])))
            start = b
            end = P[(c + 1) % k] + (P[c] - P[(c + 1) % k]) / np.linalg.norm(P[c] - P[(c + 1) % k]) * self.cut[
                (c + 1) % k]
            out.append(("line", (start, end)))
        return out


def _fillet(a: np.ndarray, b: np.ndarray, corner: np.ndarray, turn: float, t: float) -> tuple:
    """The tangent arc from a to b (both at distance t from the corner along its sides) rounding a turn (radians,
    signed): (center, radius, t0, t1)."""
    r = t / np.tan(0.5 * abs(turn))
    d_in = (corner - a) / np.linalg.norm(corner - a)
    left = np.array([-d_in[1], d_in[0]]) * np.sign(turn)  # the center lies on the side the profile turns to
    center = a + left * r
    t0 = np.arctan2(*(a - center)[::-1])
    t1 = t0 + turn
    return center, r, t0, t1


def _sampled(segments: list[tuple], spacing: np.ndarray) -> np.ndarray:
    """The closed loop (k,2) through the segments, each sampled at its own spacing (its end point excluded)."""
    parts = []
    for (kind, data), h in zip(segments, spacing, strict=True):
        if kind == "line":
            parts.append(_segment(data[0], data[1], h))
        else:
            parts.append(_arc(*data, h))
    return np.vstack(parts)


def _holes(outer: Polygon, rng: np.random.Generator, scale: float) -> list[tuple[np.ndarray, float]]:
    """0-2 circular holes (center, radius) at least a radius away from the border and each other."""
    holes = []
    for _ in range(int(rng.choice([0, 0, 1, 2]))):
        for _try in range(50):
            r = rng.uniform(0.05, 0.15) * scale
            lo, hi = np.array(outer.bounds[:2]), np.array(outer.bounds[2:])
            c = rng.uniform(lo, hi)
            free = outer.exterior.distance(Point(c)) > 2 * r and outer.contains(Point(c))
            if free and all(np.linalg.norm(c - c2) > 2.5 * (r + r2) for c2, r2 in holes):
                holes.append((c, r))
                break
    return holes


def extruded(loops: list[np.ndarray], depth: float, h: float, layers: np.ndarray,
             interior: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """A closed, outward oriented prism: the profile ``loops`` (outer first, then holes; (k,2) in (x, z)) extruded
    along y to the heights ``layers`` (sorted, 0 first, ``depth`` last), capped by ``mesh_domain``
    triangulations (with an interior lattice at spacing h, or without one: ``interior`` False). (n,3), (m,3)."""
    uv, Fc = mesh_domain(loops, h, min_boundary_distance=0.55 if interior else 1e9)
    E = np.concatenate([Fc[:, [0, 1]], Fc[:, [1, 2]], Fc[:, [2, 0]]])
    key = E[:, 0] * len(uv) + E[:, 1]
    border = E[~np.isin(E[:, 1] * len(uv) + E[:, 0], key)]  # half-edges i -> j of the front cap without a twin
    n, ny = len(uv), len(layers) - 1
    V = np.vstack([np.column_stack([uv[:, 0], np.full(n, y), uv[:, 1]]) for y in layers])
    i, j = border[:, 0], border[:, 1]
    side = []
    for lay in range(ny):  # the side wall runs along each cap edge reversed: j -> i on the front's side
        lo, hi = lay * n, (lay + 1) * n
        side += [np.column_stack([j + lo, i + lo, i + hi]), np.column_stack([j + lo, i + hi, j + hi])]
    F = np.vstack([Fc, Fc[:, ::-1] + ny * n, *side])  # front (y = 0) faces -y as meshed counter-clockwise
    used, F = np.unique(F, return_inverse=True)
    return V[used], F.reshape(-1, 3).astype(np.int64)


def _count(segs: list[tuple], outline: Polygon, scale: float, h: float) -> float:
    """About how many triangles a uniform mesh at spacing h has: both caps and the side walls (depth <= 0.8
    scale), two triangles per h x h square."""
    return 2 * (2 * outline.area + outline.length * 0.55 * scale) / (h * h)


def draw(seed: int, faces: int | None = None) -> tuple[np.ndarray, np.ndarray, str, dict]:
    """The part of ``seed``: (V (n,3), F (m,3), a one-line description, expected B-rep faces (dict: ``faces``,
    ``planar``, ``cylindrical``, ``caps``, ``holes``, ``fillets``)). ``faces``: the same shape meshed uniformly to
    about that many triangles instead of the drawn mesh."""
    rng = np.random.default_rng(seed)
    corners = _convex(rng)
    notch = rng.uniform() < 0.3
    if notch:
        corners = _notched(corners, rng)
    prof = _Profile(corners, rng)
    segs = prof.segments()
    scale = float(np.linalg.norm(corners.max(0) - corners.min(0)))
    h = scale * float(np.exp(rng.uniform(np.log(0.012), np.log(0.06))))
    style = str(rng.choice(["uniform", "uniform", "non-uniform", "cad-export"]))
    if faces:  # triangles ~ area / h^2: scale h from the count at the drawn h
        style = "uniform"
        h *= float(np.sqrt(_count(segs, Polygon(_sampled(segs, np.full(len(segs), h))), scale, h) / faces))
    spacing = h * (rng.uniform(0.35, 1.0, len(segs)) if style != "uniform" else np.ones(len(segs)))
    outer = _sampled(segs, spacing)
    holes = _holes(Polygon(outer), rng, scale)
    loops = [outer] + [_arc(c, r, 2 * np.pi, 0.0, h, min_n=8) for c, r in holes]
    depth = scale * rng.uniform(0.3, 0.8)
    if style == "uniform":
        layers = np.linspace(0.0, depth, max(1, int(np.ceil(depth / h))) + 1)
    elif style == "non-uniform":
        ny = max(1, int(np.ceil(depth / h)))
        layers = np.concatenate([[0.0], np.sort(rng.uniform(0.0, depth, ny - 1)), [depth]])
        layers = layers[np.concatenate([[True], np.diff(layers) > 0.05 * h])]
    else:
        layers = np.array([0.0, depth])
    V, F = extruded(loops, depth, h, layers, interior=style != "cad-export")
    lines = sum(kind == "line" for kind, _ in segs)
    arcs = len(segs) - lines
    expected = {"faces": len(segs) + len(holes) + 2, "planar": lines + 2, "cylindrical": arcs + len(holes),
                "caps": 2, "holes": len(holes), "fillets": arcs}
    chamfers = prof.kind.count("chamfer")
    turns = np.degrees(np.abs(_turns(corners)))
    desc = (f"{len(corners)} corners{' (notch)' if notch else ''}, turns {turns.min():.0f}-{turns.max():.0f}°, "
            f"{chamfers} chamfers, {arcs} fillets, {len(holes)} holes, h {h / scale:.3f} diag, {style}")
    return V, F, desc, expected
