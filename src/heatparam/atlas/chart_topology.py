"""A component's adjacency for charting (:class:`Topology`), and a chart's own mesh (:func:`chart_mesh`).

A chart is a set of faces plus the half-edges glued inside it: its mesh welds corners across those half-edges only,
so a chart may keep a seam inside (a cube's net) and several charts can share one solve (one mesh component each).
"""

from __future__ import annotations

from dataclasses import dataclass

import igl
import numpy as np

from heatparam.atlas.repair import half_edge_opposites
from heatparam.mesh.topology import degenerate_faces, vertex_corners

__all__ = ["CONE_DEFECT", "DEFAULT_CREASE", "Topology", "chart_mesh", "glue_inside"]

DEFAULT_CREASE = 60.0  # degrees: dihedral angle above which an edge is a crease (never crossed while growing)
CONE_DEFECT = 0.3  # radians: vertices with a larger |angle defect| end a glued stretch (cube corners: pi/2)


@dataclass
class Topology:
    """Per-component adjacency: V (n,3), F (m,3), opp (3m,) opposite half-edge or -1, normals (m,3),
    areas (m,), crease (3m,) bool, defect (n,) angle defect (2pi - angle sum inside, pi - sum on the border),
    hlen (3m,) half-edge lengths, degenerate (m,) bool zero-area faces (``mesh.topology.degenerate_faces``)."""

    V: np.ndarray
    F: np.ndarray
    opp: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    crease: np.ndarray
    defect: np.ndarray
    hlen: np.ndarray
    degenerate: np.ndarray

    def ends(self) -> tuple[np.ndarray, np.ndarray]:
        """(3m,) start and end vertex of every half-edge ``3 f + j`` (F[f, j] → F[f, (j+1) % 3]), made once."""
        if not hasattr(self, "_ends"):
            self._ends = (self.F.ravel(), self.F[:, [1, 2, 0]].ravel())
        return self._ends

    def cones(self) -> list[bool]:
        """Per vertex: a cone point (|angle defect| > CONE_DEFECT), as a list, made once."""
        if not hasattr(self, "_cones"):
            self._cones = (np.abs(self.defect) > CONE_DEFECT).tolist()
        return self._cones

    def centroids(self) -> np.ndarray:
        """(m,3) face centroids, made once."""
        if not hasattr(self, "_centroids"):
            self._centroids = self.V[self.F].mean(axis=1)
        return self._centroids

    def double_neighbours(self) -> bool:
        """Whether two faces are neighbours across two of their edges (a two-faced pocket), found once."""
        if not hasattr(self, "_double"):
            nb = np.where(self.opp >= 0, self.opp // 3, -1).reshape(-1, 3)
            p, q = nb[:, [0, 0, 1]], nb[:, [1, 2, 2]]  # each face's three pairs of neighbours
            self._double = bool(((p == q) & (p >= 0)).any())
        return self._double

    def neighbours(self) -> tuple[np.ndarray, np.ndarray]:
        """(m,3) int64 each face's neighbours across its edges (m where there is none: a sentinel row) and the same
        with m across the creases too, for the region growing, made once."""
        if not hasattr(self, "_neighbours"):
            m = len(self.F)
            nb = np.where(self.opp >= 0, self.opp // 3, m)
            cross = np.where(self.crease, m, nb)
            self._neighbours = (nb.reshape(m, 3), cross.reshape(m, 3))
        return self._neighbours

    def vertex_faces(self) -> tuple[np.ndarray, np.ndarray]:
        """The faces around each vertex, made once: (faces, starts), vertex w's are ``faces[starts[w]:starts[w+1]]``."""
        if not hasattr(self, "_vf"):
            corners, starts = vertex_corners(self.F, len(self.V))
            self._vf = (corners // 3, starts)
        return self._vf

    @classmethod
    def build(cls, V: np.ndarray, F: np.ndarray, crease_deg: float = DEFAULT_CREASE) -> Topology:
        opp = half_edge_opposites(F)
        N = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
        area2 = np.linalg.norm(N, axis=1)
        normals = N / np.maximum(area2, 1e-300)[:, None]
        degenerate = degenerate_faces(V, F)
        if degenerate.any():
            normals = _borrowed_normals(normals, degenerate, opp, area2)
        h = np.arange(3 * len(F))
        crease = np.zeros(3 * len(F), dtype=bool)
        ok = opp >= 0
        cosang = np.einsum("ij,ij->i", normals[h[ok] // 3], normals[opp[ok] // 3])
        crease[ok] = cosang < np.cos(np.radians(crease_deg))
        a, b = F.ravel(), F[:, [1, 2, 0]].ravel()
        hlen = np.linalg.norm(V[b] - V[a], axis=1)
        ang = np.asarray(igl.internal_angles(V, F)).ravel()
        asum = np.bincount(F.ravel(), weights=ang, minlength=len(V))
        onb = np.zeros(len(V), dtype=bool)
        onb[a[~ok]] = True
        defect = np.where(onb, np.pi, 2 * np.pi) - asum
        return cls(V, F, opp, normals, 0.5 * area2, crease, defect, hlen, degenerate)


def _borrowed_normals(normals: np.ndarray, degenerate: np.ndarray, opp: np.ndarray, area2: np.ndarray
                      ) -> np.ndarray:
    """(m,3) ``normals`` where each zero-area face has its largest neighbour's normal (a cluster of them from the
    outside in). A zero-area face has no normal of its own: with a zero or arbitrary one every edge of it was a crease
    and no cone took it in, so it seeded a chart of one face that no layout flattens; with a neighbour's it grows
    into that neighbour's chart, which lays it out with its neighbours. A component of zero-area faces only keeps
    what it had."""
    normals = normals.copy()
    has = ~degenerate
    nb = np.where(opp >= 0, opp // 3, -1).reshape(-1, 3)
    while True:
        todo = np.flatnonzero(~has)
        cand = nb[todo]
        w = np.where((cand >= 0) & has[np.maximum(cand, 0)], area2[np.maximum(cand, 0)], -1.0)
        pick = w.argmax(axis=1)
        found = w[np.arange(len(todo)), pick] >= 0
        if not found.any():
            return normals
        normals[todo[found]] = normals[cand[np.arange(len(todo)), pick][found]]
        has[todo[found]] = True


def chart_mesh(topo: Topology, faces: np.ndarray, glued: np.ndarray, group: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The chart's own mesh: corners welded across its glued half-edges only.

    group : (len(faces),) optional chart of each face: several charts at once, never welded to each other (the mesh
    has one component per chart); a face may then appear in several charts (once in each).

    Returns Vl (nl,3), Fl (k,3) local triangles (row i = faces[i]), vert (nl,) component vertex of each row.
    """
    F = topo.F
    k = len(faces)
    h = (3 * faces[:, None] + np.arange(3)).ravel()
    o = topo.opp[h]
    ok = (o >= 0) & glued[h]
    a = np.repeat(np.arange(k), 3)  # the row of each half-edge
    group = np.zeros(k, dtype=np.int64) if group is None else group
    row = np.full(len(F), -1, dtype=np.int64)
    row[faces] = np.arange(k)
    if (row[faces] == np.arange(k)).all():  # each face once: its twin's row by table, kept within its group
        b = row[np.maximum(o, 0) // 3]
        ok &= b >= 0
        ok[ok] = group[b[ok]] == group[a[ok]]
        b = np.where(ok, b, -1)
    else:  # rows found by (group, face): a face sits in several groups
        key = group * len(F) + faces
        order = np.argsort(key, kind="stable")
        q = np.repeat(group, 3) * len(F) + np.maximum(o, 0) // 3
        pos = np.minimum(np.searchsorted(key[order], q), k - 1)
        b = np.where(ok & (key[order][pos] == q), order[pos], -1)
        ok &= b >= 0
    j, kk = h[ok] % 3, o[ok] % 3
    a, b = a[ok], b[ok]
    # corners welded across a glued half-edge: corner j of row a is corner kk+1 of row b, corner j+1 is corner kk.
    # Around a vertex the welds form paths and cycles (each corner has one outgoing and one incoming half-edge:
    # at most one successor and one predecessor), labelled here by their smallest corner with pointer jumping
    # (2^t ≥ the longest fan), numbered by that corner: scipy's connected_components' labels, 3x faster here
    src = np.concatenate([3 * a + j, 3 * b + kk])
    dst = np.concatenate([3 * b + (kk + 1) % 3, 3 * a + (j + 1) % 3])
    lab = np.arange(3 * k)
    nf, nb = lab.copy(), lab.copy()
    nf[src] = dst
    nb[dst] = src
    fan = int(np.bincount(F[faces].ravel()).max()) if k else 1
    for _ in range(max(1, (fan - 1).bit_length())):
        lab = np.minimum(lab, np.minimum(lab[nf], lab[nb]))
        nf, nb = nf[nf], nb[nb]
    root = lab == np.arange(3 * k)
    first = np.flatnonzero(root)  # the first corner of each component
    lab = (np.cumsum(root) - 1)[lab]
    Fl = lab.reshape(k, 3).astype(np.int64)
    vert = F[faces].ravel()[first]
    return topo.V[vert], Fl, vert


def glue_inside(topo: Topology, faces: np.ndarray) -> np.ndarray:
    """(3m,) bool: the half-edges between two of ``faces`` (a region welded inside, nothing else)."""
    m = len(topo.F)
    inside = np.zeros(m, dtype=bool)
    inside[faces] = True
    g = np.zeros(3 * m, dtype=bool)
    h = (3 * faces[:, None] + np.arange(3)).ravel()
    o = topo.opp[h]
    ok = o >= 0
    ok[ok] = inside[o[ok] // 3]
    g[h[ok]] = True
    return g
