"""Tutte's embedding: a bijective layout of any disk (holes closed by fans), the refinement's last-resort start."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from heatparam.mesh.topology import boundary_loops, loop_length, unique_edges
from heatparam.solvers import Factor


class Disk(NamedTuple):
    """The mesh's boundary loops, and its faces with every hole closed by a fan (for the Tutte start)."""

    F: np.ndarray  # (m + f, 3) surface faces then fan faces
    m: int  # number of surface faces
    n: int  # number of surface vertices (fan centres are n, n+1, ...)
    outer: np.ndarray  # outer boundary loop (vertex ids)
    holes: list  # hole loops

    @property
    def loops(self) -> list[np.ndarray]:
        """The boundary loops, outer first (the holes in walker order)."""
        return [self.outer, *self.holes]

def build_disk(V: np.ndarray, F: np.ndarray) -> Disk:
    """Close every hole of the disk-like mesh (V, F) with a fan around a virtual centre vertex.

    The outer loop is the longest boundary loop in 3D.
    """
    loops = boundary_loops(F)
    if not loops:
        raise ValueError("refine needs a mesh with a boundary")
    lens = [loop_length(V, lp) for lp in loops]
    io = int(np.argmax(lens))
    holes = [lp for i, lp in enumerate(loops) if i != io]
    fans = [np.column_stack([np.roll(lp, -1), lp, np.full(len(lp), len(V) + h)]) for h, lp in enumerate(holes)]
    return Disk(np.vstack([F, *fans]).astype(np.int64), len(F), len(V), loops[io], holes)

def tutte(V: np.ndarray, disk: Disk, backend: str = "auto") -> np.ndarray:
    """Uniform-weight Tutte embedding of the disk (surface + fans), outer loop on a circle of its 3D perimeter."""
    N = disk.n + len(disk.holes)
    F = disk.F
    E = unique_edges(F)
    A = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(N, N))
    A = (A + A.T).tocsr()
    L = (sp.diags(np.asarray(A.sum(axis=1)).ravel()) - A).tocsr()
    b = disk.outer
    seg = np.linalg.norm(V[b] - V[np.roll(b, -1)], axis=1)
    per = seg.sum()
    ang = 2 * np.pi * np.concatenate([[0.0], np.cumsum(seg)[:-1]]) / per
    R = per / (2 * np.pi)
    bc = R * np.column_stack([np.cos(ang), np.sin(ang)])
    free = np.setdiff1d(np.arange(N), b)
    uv = np.zeros((N, 2))
    uv[b] = bc
    if len(free):  # a strip whose every vertex is on the border has none: the circle alone is the embedding
        Lff = L[free][:, free].tocsc()
        rhs = -(L[free][:, b] @ bc)
        uv[free] = Factor(Lff, backend).solve(rhs)
    return uv
