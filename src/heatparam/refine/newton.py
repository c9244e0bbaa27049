"""Projected Newton on the symmetric Dirichlet energy plus the scaffold's, from a bijective layout.

The scaffold (``scaffold.build_scaffold``) is rebuilt around the current layout at every iteration (or kept while
it holds: ``PolishSettings.keep_scaffold``) and measured against its own shape at the
iteration's start (Jiang et al. 2017); each scaffold triangle weighs up to ``SCAFFOLD_WEIGHT`` ×
the mean surface face, relaxed by ``SCAFFOLD_ADAPT`` after every uncut step: it shapes the Newton direction. The
line search (:func:`_line_search`, on the surface energy) starts at the largest step that stays bijective: 0.9 ×
the largest for which no surface triangle flips (Smith & Schaefer 2015), and no farther than the scaffold,
re-triangulated where it would flip, allows (``scaffold.feasible_step``). Converged
when an uncut step (≥ half the Newton step) lowers the surface energy by less than ``tol`` of it; the polish gives
up after ``STALL_ITERS`` barrier-limited steps in a row that gain less.

Stopping. The Newton decrement (the quadratic model's predicted decrease) far below ``tol`` means the start is
already the minimum (e.g. the LSCM start of a developable surface, an isometry to round-off, where line searches
find no descent); the threshold is far below tol so that a stiff scaffold holding boundary vertices back cannot
fake it. A tiny decrease means convergence only if the Newton step was not cut short by the flip barrier and the
scaffold was already at its lightest (a stiff scaffold slows boundary vertices down); cut-short steps usually
recover once the scaffold is re-triangulated, so only a run of them stops. With ``excess_tol`` (the atlas's joint
polish) ``EXCESS_STALL_ITERS`` iterations in a row that each gain less than that fraction of the energy's excess
over an isometry stop it too, cut short or not.

Scaffold weight. A stiff scaffold keeps boundaries apart while they move a lot, but it acts like a proximal term on
boundary vertices (thin scaffold triangles): it is relaxed while Newton steps go through uncut and stiffened again
after a cut step.

The Hessian's sparsity pattern is built once (:class:`HessianPattern`); directions are solved with a reused
factorization (:func:`newton_direction`); the line search is bounded by the flip barrier (``energy.max_step``,
``scaffold.feasible_step``).

Without a scaffold (:class:`ScaffoldUse` ``NEVER``: the atlas's charts, ``refine.charts``; ``UNTIL_CROSSING``: a
fine level after a converged coarse one) the Hessian is the surface's alone, its pattern fixed, and each step is
checked instead of barred: halved until no two boundary edges cross (:func:`_chart_steps`, one step per chart), or,
until crossing, redone with the stiffest scaffold at the first crossing.
"""

from __future__ import annotations

import time
from concurrent.futures import Future
from dataclasses import dataclass
from enum import Enum
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from heatparam.mesh.topology import unique_inverse
from heatparam.refine.energy import (
    BLOCK_ENTRIES,
    ENTRY_CHUNK,
    face_step_limits,
    hat_gradients,
    jacobians,
    max_step,
    scatter,
    sd_newton_blocks,
    sd_newton_entries,
    symmetric_dirichlet,
)
from heatparam.refine.scaffold import (
    SCAFFOLD_ADAPT,
    SCAFFOLD_WEIGHT,
    SCAFFOLD_WEIGHT_MIN,
    Scaffold,
    build_scaffold,
    feasible_step,
    loop_edges,
    loop_ranges,
    scaffold_holds,
    scaffold_matrix,
)
from heatparam.solvers import Factor, large_system_backend

DECREMENT_TOL = 1e-3  # converged at once when the Newton decrement predicts less than this × tol relative decrease

LINE_SEARCH_MAX = 2.0  # the line search's doubling of a full Newton step goes this far at most

STALL_ITERS = 5  # the polish gives up after this many barrier-limited iterations in a row that gain < tol

#: With ``excess_tol`` (the atlas's joint polish), this many iterations in a row that each gain less than excess_tol
#: of the energy's excess stop the polish, whatever the step length and the scaffold's weight: on cow the 5
#: barrier-limited iterations after the first such one gained 2e-5 of energy 1.00094 together (docs/history.md §18)
EXCESS_STALL_ITERS = 2

#: ``excess_tol`` of the atlas's joint polish (``refine.charts``) and of a large mesh's finest level
#: (``refine.multilevel``): an iteration that gains less than this fraction of the energy's excess (over an isometry;
#: a fine level's over its coarse level's energy, ``PolishSettings.excess_base``) counts as small, and
#: ``EXCESS_STALL_ITERS`` such iterations in a row stop the polish whatever the step and the scaffold; the joint
#: polish also stops when the next gain is predicted below it: on cow half the iterations for an iso mean 2e-4 higher
#: (docs/history.md §18a). The seams stage pauses its trial maps at the same fraction (``options.SEAM_PAUSE_EXCESS``).
EXCESS_TOL = 0.03

#: Without a scaffold (``ScaffoldUse.NEVER``) a step is halved at most this many times until no boundary
#: edges cross
CROSSING_HALVINGS = 20

class HessianPattern:
    """Sparsity pattern of the surface's (2n,2n) Hessian, built once; ``matrix(entries)`` sums the faces' blocks.

    The Hessian is a 2×2 block matrix [[H_uu, H_uv], [H_vu, H_vv]] whose four blocks share the vertex-adjacency
    pattern A (n,n), so only the 9 vertex pairs of each face are located in A (one sort of 9m keys, not of the
    36m entries); column (b, v) of the full CSC matrix holds A's column v twice, rows u then n + u. Each face's
    block is symmetric, so it is summed from its 21 distinct entries (``energy.BLOCK_ENTRIES``, as
    ``energy.sd_newton_entries`` computes them): ``slot`` (21, m) is where each entry goes, and in the full matrix
    ``mirror`` (21, m) where its transpose goes (a discarded slot for the diagonal).

    upper : build only the upper triangle, as sorted CSR, which is what PARDISO reads (``solvers.Factor(...,
        upper=True)``): each entry goes once, to whichever of (p, q), (q, p) lies in the upper triangle, at half the
        full matrix's memory and without its copies and ``triu`` at every iteration (beetle↑78k: peak RSS 1013 →
        932 MB). Faces must have three distinct vertices (validated meshes do).
    """

    def __init__(self, F: np.ndarray, n: int, upper: bool = False):
        R, C = np.repeat(F, 3, axis=1).ravel(), np.tile(F, (1, 3)).ravel()  # (9m,) vertices of corner pair (i, j)
        # A's pattern as sorted row-major keys u*n + v, once each, and the place of each face's pair (i, j) there
        key, _, kidx = unique_inverse(R * n + C)
        rows = key // n
        ptr = np.searchsorted(rows, np.arange(n + 1))
        deg = np.diff(ptr)
        self.shape = (2 * n, 2 * n)
        self.upper = upper
        p, q = BLOCK_ENTRIES.T
        if upper:
            self.slot, self.mirror = self._upper(F, n, kidx, key, rows, ptr, deg), None
            return
        inv = self._full(F, n, C, kidx, key, rows, ptr, deg)
        pa, pi, qa, qj = p // 3, p % 3, q // 3, q % 3
        self.slot = inv[:, pa, pi, qa, qj].T.copy()  # (21, m)
        # the transposed entries' places; the diagonal entries (p == q) once
        self.mirror = np.where((p == q)[:, None], self.nnz, inv[:, qa, qj, pa, pi].T)

    def _full(self, F, n, C, kidx, key, rows, ptr, deg) -> np.ndarray:
        """The full CSC pattern; returns each face's entry (a, i, b, j) place (m,2,3,2,3). ``kidx`` (9m,): the place
        in ``key`` of each face's vertex pair (i, j)."""
        m = len(F)
        # A is symmetric: column v's rows are row v's columns, so key % n lists each column's rows, sorted
        col, rows = rows, key % n
        nnz = len(rows)
        # place of (R, C) = (F[f,i], F[f,j]) in column C: where the key C*n + R, the face's pair (j, i), sits
        local = kidx.reshape(m, 3, 3).transpose(0, 2, 1).ravel() - ptr[C]
        # full CSC layout: column b*n + v starts at b*2nnz + 2 ptr[v]; rows a*n + u sit at a*deg[v] + local
        half = np.empty(2 * nnz, dtype=np.int64)
        at = 2 * ptr[col] + (np.arange(nnz) - ptr[col])
        half[at] = rows
        half[at + deg[col]] = rows + n
        self.indices = np.concatenate([half, half]).astype(np.int32)
        self.indptr = np.concatenate([2 * ptr[:-1], 2 * nnz + 2 * ptr]).astype(np.int32)
        self.nnz = 4 * nnz
        base = (2 * ptr[C] + local).reshape(m, 3, 3)  # (f, i, j): offset of pair (F[f,i], F[f,j]) in a half
        degC = deg[C].reshape(m, 3, 3)
        inv = np.empty((m, 2, 3, 2, 3), dtype=np.int64)  # block entry (a*3+i, b*3+j)
        for a in range(2):
            for b in range(2):
                inv[:, a, :, b, :] = b * 2 * nnz + base + a * degC
        return inv

    def _upper(self, F, n, kidx, key, rows, ptr, deg) -> np.ndarray:
        """The upper triangle's sorted CSR pattern, straight from A's rows: row u (x block) holds the columns v ≥ u
        of A's row u, then n + v for all of them; row n + u the columns n + v, v ≥ u. ``kidx`` (9m,): the place in
        ``key`` of each face's vertex pair (i, j). Returns the places (21, m) of each face's block entries
        (``energy.BLOCK_ENTRIES``)."""
        m = len(F)
        lo = np.searchsorted(key, np.arange(n) * (n + 1)) - ptr[:-1]  # place of the diagonal in each row
        up = deg - lo
        self.indptr = np.concatenate([[0], np.cumsum(np.concatenate([up + deg, up]))]).astype(np.int32)
        self.nnz = nnz = int(self.indptr[-1])
        s0, s1 = self.indptr[:n].astype(np.int64), self.indptr[n:2 * n].astype(np.int64)
        cols = key % n
        pos = np.arange(len(key)) - ptr[rows]  # place of each pair in its row
        isup = pos >= lo[rows]
        ru, off = rows[isup], pos[isup] - lo[rows[isup]]
        indices = np.empty(nnz, dtype=np.int32)
        indices[s0[ru] + off] = cols[isup]
        indices[s0[rows] + up[rows] + pos] = cols + n
        indices[s1[ru] + off] = cols[isup] + n
        self.indices = indices
        # the pair (u, v) at place k of key (row u) sits at s0[u] + (k - ptr[u]) - lo[u] in row u of the x block
        # (v ≥ u), at s1[u] + ... in row n + u, and its (x, y) coupling at s0[u] + up[u] + (k - ptr[u])
        start = ptr[:-1]
        base0, base1, base01 = s0 - start - lo, s1 - start - lo, s0 + up - start
        kidx = kidx.reshape(m, 9).T.copy()  # (9, m): pair (i, j) of every face, row 3i + j
        slot = np.empty((21, m), dtype=np.int64)
        Fc = np.ascontiguousarray(F.T)  # (3, m): corner i of every face
        for k, (i, j) in enumerate(BLOCK_ENTRIES[:6].tolist()):
            # of the (u, u) pairs (i, j), (j, i) the one in the upper triangle: F[f,i] ≤ F[f,j]
            first = Fc[i] <= Fc[j]
            r = np.where(first, Fc[i], Fc[j])
            at = np.where(first, kidx[3 * i + j], kidx[3 * j + i])
            slot[k] = base0[r] + at
            slot[k + 6] = base1[r] + at
        for k, (i, j) in enumerate(BLOCK_ENTRIES[12:].tolist()):  # (u_i, v_j): row F[f,i], column n + F[f,j]
            slot[12 + k] = base01[Fc[i]] + kidx[3 * i + j - 3]
        return slot

    def matrix(self, entries: np.ndarray) -> sp.spmatrix:
        """The (2n,2n) Hessian summed from the faces' block entries (21, m) (``energy.BLOCK_ENTRIES``): full CSC,
        or (``upper``) its upper triangle as sorted CSR."""
        data = np.bincount(self.slot.ravel(), weights=entries.ravel(), minlength=self.nnz + 1)
        if self.mirror is not None:
            data += np.bincount(self.mirror.ravel(), weights=entries.ravel(), minlength=self.nnz + 1)
        data = data[: self.nnz]
        if self.upper:
            return sp.csr_matrix((data, self.indices, self.indptr), shape=self.shape)
        return sp.csc_matrix((data, self.indices, self.indptr), shape=self.shape)

    def assemble(self, J: np.ndarray, g: np.ndarray, w: np.ndarray, chunk: int = ENTRY_CHUNK
                 ) -> tuple[np.ndarray, sp.spmatrix]:
        """dE/dJ (m,2,2) and the Hessian (as :meth:`matrix`) of E = Σ w_f Ψ(J_f), from ``energy.sd_newton_entries``
        (``chunk`` faces per pass)."""
        grad, entries = sd_newton_entries(J, g, w, chunk)
        return grad, self.matrix(entries)


class Prepared(NamedTuple):
    """What :func:`prepare_hessian` makes ahead of time: the Hessian's pattern, and (PARDISO) the symbolic analysis
    of it being made on a thread of its own (``solvers.Factor(..., numeric=False)``; None for other backends)."""

    pat: HessianPattern
    analysis: Future[Factor] | None


def prepare_hessian(F: np.ndarray, n: int, backend: str = "auto") -> Prepared:
    """:class:`HessianPattern` of (F (m,3), n vertices) and, where the polish factorizes with PARDISO, the symbolic
    analysis of that pattern (the fill-reducing ordering: ~0.7 s of the first factorization at 363k unknowns) on a
    thread of its own while the caller goes on: ``multilevel.multilevel_polish`` starts it before the coarse levels.
    The pattern is built here, on the caller's thread: built on the other one it took 0.95 s instead of 0.27 s
    (both threads want the interpreter), and slowed the coarse levels; the analysis is MKL's, which releases it.
    Pass it to :class:`Polish` (``prepared=``): when its first Hessian has no scaffold (a fine level after a
    converged coarse one), and so this pattern, it waits for the analysis and needs a numerical factorization
    only; otherwise the analysis is dropped unused. The same results: the same analysis, made earlier."""
    from concurrent.futures import ThreadPoolExecutor

    backend = large_system_backend(2 * n, backend, POLISH_PARDISO_MIN_UNKNOWNS)
    pat = HessianPattern(F, n, upper=backend == "pardiso")
    if backend != "pardiso":
        return Prepared(pat, None)
    T = pat.matrix(np.zeros((len(BLOCK_ENTRIES), len(F))))  # the values are not read
    pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="heatparam-analysis")
    try:
        return Prepared(pat, pool.submit(Factor, T, backend, upper=True, numeric=False))
    finally:
        pool.shutdown(wait=False)  # the thread ends with its task


#: The polish factorizes with PARDISO whenever it is installed (backend ``auto``): with its analysis reused and no
#: iterative refinement it measured 0.8 vs 1.65 s on camelhead (11k), 6.1-6.5 vs 9.2-9.8 s on beetle (20k), 2.8-3.0
#: vs 7.2 s on camelhead↑45k against CHOLMOD (cholespy) with lagged factors, and even on halftunnel (831 vertices)
POLISH_PARDISO_MIN_UNKNOWNS = 0

#: Newton directions are solved to this relative residual by conjugate gradients preconditioned with the last
#: Cholesky factor; the Hessian is refactorized only when that takes more than PCG_MAX_ITERS iterations.
PCG_RTOL = 1e-3

PCG_MAX_ITERS = 12

#: With PARDISO no stale factor is tried: its refactorizations reuse the symbolic analysis (``Factor.refactor``,
#: ~0.55 s at 363k unknowns), about 4 of its CG steps (a solve + a product, ~0.13 s each), and the stale factor
#: needed 6-30 steps there (camelhead↑180k fine polish 13.1 s with the attempt, 10.5 s without)
PCG_MAX_ITERS_PARDISO = 0

def newton_direction(H: sp.spmatrix, rhs: np.ndarray, fac: Factor | None, backend: str, upper: bool = False
                      ) -> tuple[np.ndarray, Factor, int]:
    """Solve H dx = rhs, reusing a stale factorization as a preconditioner while it still works (lagged Newton).

    Factorizing the (2n,2n) Hessian dominates an iteration; consecutive Hessians differ little, so a few
    preconditioned CG steps with the previous factor usually reach PCG_RTOL for a fraction of the cost.
    ``upper``: H is its upper triangle (sorted CSR, PARDISO only; then no stale factor is tried).
    Returns (dx, the factor used, 1 if it was refactorized else 0).
    """
    cap = PCG_MAX_ITERS_PARDISO if backend == "pardiso" else PCG_MAX_ITERS
    if fac is not None and cap > 0 and not upper:
        prec = spla.LinearOperator(H.shape, matvec=fac.solve, dtype=np.float64)
        dx, info = spla.cg(H, rhs, x0=fac.solve(rhs), rtol=PCG_RTOL, maxiter=cap, M=prec)
        if info == 0:
            return dx, fac, 0
    fac = Factor(H, backend, upper=upper) if fac is None else fac.refactor(H, upper=upper)
    return fac.solve(rhs), fac, 1

class _System(NamedTuple):
    """One Newton iteration's system around the layout: the scaffold, the surface + scaffold energy E0, the
    Hessian H (full CSC, or its upper triangle as sorted CSR when ``upper``: :class:`HessianPattern`) and the
    right-hand side (minus the gradient)."""

    sc: Scaffold
    E0: float
    H: sp.spmatrix
    rhs: np.ndarray
    upper: bool


def _system(x: np.ndarray, J: np.ndarray, Es: float, F: np.ndarray, g: np.ndarray, w_surf: np.ndarray,
            w_scaf: float, loops: list[np.ndarray], pat: HessianPattern, last: Scaffold | None = None,
            scaffold: bool = True) -> _System:
    """Scaffold around ``x`` (``last``, the previous iteration's, while it holds: ``scaffold.scaffold_holds``;
    else :func:`build_scaffold`, ValueError when it cannot be built), PSD-projected Hessian and gradient of
    surface + scaffold energy (each scaffold triangle measured against its shape in ``x``). ``scaffold`` False
    (``ScaffoldUse.NEVER``): the surface energy's alone, ``sc`` None."""
    n = len(x)
    gJ, H = pat.assemble(J, g, w_surf)
    gr = scatter(gJ, F, g, n)
    sc, E0 = None, Es
    if scaffold:
        sc = last if last is not None and scaffold_holds(x, last) else build_scaffold(x, loops)
        xs = np.vstack([x, sc.box])
        gs = hat_gradients(xs[sc.F])
        ws = np.full(len(sc.F), w_scaf)
        Js = jacobians(xs, sc.F, gs)
        E0 = Es + symmetric_dirichlet(Js, ws)[0]
        gJs, blocks_s = sd_newton_blocks(Js, gs, ws)
        Hc = scaffold_matrix(sc.F, blocks_s, n)
        H = H + (sp.triu(Hc, format="csr") if pat.upper else Hc)
        gr = gr + scatter(gJs, sc.F, gs, n + 4)[:n]
    rhs = -np.concatenate([gr[:, 0], gr[:, 1]])
    # the rigid motions (without a scaffold each chart's translations too) span the null space: a tiny shift
    H = H + sp.identity(2 * n, format=H.format) * (1e-9 * float(H.diagonal().mean()))
    return _System(sc, E0, H, rhs, pat.upper)


class _ChartEnergies:
    """The charts' energies along a step: ``(t, which)`` → (k,) the energy of the charts ``which`` (k,) bool (None:
    all) at their step lengths t (k,) (None: 0) along the Jacobian directions D, 0 for the others."""

    def __init__(self, J: np.ndarray, D: np.ndarray, w_surf: np.ndarray, groups: ChartGroups):
        self.J, self.D, self.w, self.fg, self.k = J, D, w_surf, groups.face, groups.k

    def __call__(self, t: np.ndarray | None, which: np.ndarray | None) -> np.ndarray:
        J, D, w, fg, k = self.J, self.D, self.w, self.fg, self.k
        if which is None or which.all():  # every face (no copies of the selection)
            Jt = J if t is None else J + (t[0] if k == 1 else t[fg][:, None, None]) * D
            return np.bincount(fg, weights=w * symmetric_dirichlet(Jt, w)[1], minlength=k)
        sel = which[fg]
        e = symmetric_dirichlet(J[sel] + t[fg[sel]][:, None, None] * D[sel], w[sel])[1]
        return np.bincount(fg[sel], weights=w[sel] * e, minlength=k)


def _chart_steps(x: np.ndarray, d: np.ndarray, J: np.ndarray, D: np.ndarray, w_surf: np.ndarray,
                 tmax: np.ndarray, groups: ChartGroups, halvings: int = CROSSING_HALVINGS
                 ) -> np.ndarray | None:
    """Per-chart step lengths (k,) along ``d`` (n,2) for a polish without a scaffold (``ScaffoldUse.NEVER``).

    The charts (``groups``) share no vertex and the energy is a sum over them, so each takes its own step: from
    min(1, ``tmax`` (k,), its flip barrier), halved until its energy decreases, doubled after a full step while that
    lowers it further (as :func:`_line_search`), then :func:`_uncrossed`. None when no chart moves, or (``halvings``
    0: the caller then takes a scaffold) when any boundary crosses."""
    energies = _ChartEnergies(J, D, w_surf, groups)
    E0 = energies(None, None)
    t = np.minimum(1.0, tmax)
    E1 = energies(t, None)
    for _ in range(40):
        bad = ~(E1 < E0) & (t > 0)
        if not bad.any():
            break
        t[bad] *= 0.5
        E1 = np.where(bad, energies(t, bad), E1)
    t[~(E1 < E0)] = 0.0  # no descent in 40 halvings (a chart already at its minimum): it stays
    grow = (t >= 1.0) & (2 * t <= tmax)
    while grow.any():
        E2 = energies(2 * t, grow)
        grow &= E2 < E1
        t, E1 = np.where(grow, 2 * t, t), np.where(grow, E2, E1)
        grow &= 2 * t <= tmax
    if not _uncrossed(x, d, t, E0, E1, energies, groups, halvings):
        return None
    return t if (t > 0).any() else None


def _uncrossed(x: np.ndarray, d: np.ndarray, t: np.ndarray, E0: np.ndarray, E1: np.ndarray,
               energies: _ChartEnergies, groups: ChartGroups, halvings: int) -> bool:
    """Halve the steps t (k,), in place, of the charts whose boundary edges cross (``metrics.crossing_pairs``; a
    flip-free disk whose boundary does not cross itself is bijective, whatever the path there: only the end point
    is checked), at most ``halvings`` times, after which a chart still crossing stays where it is (t 0); a chart
    whose halved step no longer descends stays too. False when ``halvings`` is 0 and any boundary crosses."""
    from heatparam.metrics import crossing_pairs

    edges, k = groups.edges, groups.k
    check = np.arange(len(edges))  # the edges whose pairs can cross: all, then those near the charts just moved
    P = x + np.append(t, 0.0)[groups.vertex][:, None] * d
    for i in range(halvings + 2):
        pairs = check[crossing_pairs(P, edges[check])]
        if not len(pairs):
            return True
        if halvings == 0:
            return False
        hit = np.zeros(k, dtype=bool)
        hit[groups.edge[pairs.ravel()]] = True
        if i >= halvings:  # still crossing: those charts stay where they are (checked once more)
            t[hit] = 0.0
        else:
            t[hit] *= 0.5
            E1 = np.where(hit, energies(t, hit), E1)
            t[hit & ~(E1 < E0)] = 0.0
        # only pairs with an edge of a chart that moved can cross now: its edges, and the others' in its box
        P = x + np.append(t, 0.0)[groups.vertex][:, None] * d
        A, B = P[edges[:, 0]], P[edges[:, 1]]
        lo_e, hi_e = np.minimum(A, B), np.maximum(A, B)
        near = hit[groups.edge]
        for c in np.flatnonzero(hit):
            own = groups.edge == c
            lo, hi = lo_e[own].min(axis=0), hi_e[own].max(axis=0)
            near |= ((hi_e >= lo) & (lo_e <= hi)).all(axis=1)
        check = np.flatnonzero(near)
    return False


class ChartGroups(NamedTuple):
    """The charts of a polish without a scaffold: face (m,) and vertex (n,) chart ids (k for a row no face uses:
    it never moves), k charts, boundary edges (e,2) and the chart of each (e,), each chart's weight (k,) in the
    energy (the sum of its faces' weights ``w``)."""

    face: np.ndarray
    vertex: np.ndarray
    k: int
    edges: np.ndarray
    edge: np.ndarray
    weight: np.ndarray

    @classmethod
    def of(cls, F: np.ndarray, n: int, loops: list[np.ndarray], face: np.ndarray | None, w: np.ndarray
           ) -> ChartGroups:
        face = np.zeros(len(F), dtype=np.int64) if face is None else np.asarray(face, dtype=np.int64)
        k = int(face.max()) + 1 if len(face) else 0
        vertex = np.full(n, k, dtype=np.int64)
        vertex[F.ravel()] = np.repeat(face, 3)
        edges = (np.concatenate(loops)[loop_edges(loop_ranges(loops))].astype(np.int64) if loops
                 else np.zeros((0, 2), np.int64))
        return cls(face, vertex, k, edges, vertex[edges[:, 0]], np.bincount(face, weights=w, minlength=k))


def _line_search(J: np.ndarray, D: np.ndarray, w_surf: np.ndarray, E0: float, tmax: float
                 ) -> tuple[float, float] | None:
    """Step t and surface energy E1 < E0 along the Jacobian directions D: from min(1, tmax), halved until the
    energy decreases (None: no descent in 40 halvings); after a full step, doubled while that lowers the energy
    further (the 1/σ² terms are steep far from the minimum, so the full Newton step undershoots)."""
    t = min(1.0, tmax)
    for _ in range(40):
        E1 = symmetric_dirichlet(J + t * D, w_surf)[0]
        if E1 < E0:
            break
        t *= 0.5
    else:
        return None
    while t >= 1.0 and 2 * t <= tmax:
        E2 = symmetric_dirichlet(J + 2 * t * D, w_surf)[0]
        if not E2 < E1:
            break
        t, E1 = 2 * t, E2
    return t, E1


def _safe_direction(sy: _System, fac, backend: str):
    """The Newton direction (dx, factor, refactorized?) of the system, or what failed (a string): any
    solver failure (PARDISO -4, CHOLMOD not positive definite) on degenerate faces keeps the last layout."""
    try:
        if not (np.isfinite(sy.H.data).all() and np.isfinite(sy.rhs).all()):
            raise FloatingPointError("non-finite Hessian")
        dx, fac, fresh = newton_direction(sy.H, sy.rhs, fac, backend, sy.upper)
    except Exception as exc:  # noqa: BLE001 - the polish must keep its bijective layout whatever the solver does
        return type(exc).__name__
    if not np.isfinite(dx).all():
        return "non-finite Newton step"
    return dx, fac, fresh


def _barrier_step(x: np.ndarray, J: np.ndarray, Es: float, dx: np.ndarray, F: np.ndarray, g: np.ndarray,
                  w_surf: np.ndarray, sc: Scaffold | None, loops: list[np.ndarray], groups: ChartGroups | None = None,
                  halvings: int = CROSSING_HALVINGS) -> tuple[float, np.ndarray] | None:
    """(step length t, the step t d (n,2)) along the Newton direction ``dx`` (2n,): at most 0.9 × the largest step
    for which no surface triangle flips (:func:`max_step`) and no farther than the chained scaffolds allow
    (``scaffold.feasible_step``, starting from the iteration's scaffold ``sc``), then :func:`_line_search` on the
    surface energy ``Es`` (the scaffold shapes the direction; the step may leave its triangulation behind); None
    when no step lowers the energy. Without a scaffold (``sc`` None) every chart of ``groups`` takes its own step
    (:func:`_chart_steps`; t is then their area-weighted mean, for the stop rules)."""
    n = len(x)
    d = np.column_stack([dx[:n], dx[n:]])
    D = jacobians(d, F, g)
    if sc is None:
        tf = face_step_limits(J, D)
        tmax = np.full(groups.k, LINE_SEARCH_MAX)
        np.minimum.at(tmax, groups.face, 0.9 * tf)
        tc = _chart_steps(x, d, J, D, w_surf, tmax, groups, halvings)
        if tc is None:
            return None
        tv = np.append(tc, 0.0)[groups.vertex]
        return float(np.dot(np.minimum(tc, 1.0), groups.weight) / groups.weight.sum()), tv[:, None] * d
    tbar = 0.9 * max_step(J, D)
    step = _line_search(J, D, w_surf, Es, feasible_step(x, d, loops, sc, min(tbar, LINE_SEARCH_MAX)))
    if step is not None and step[0] >= LINE_SEARCH_MAX:
        step = _farther(x, d, loops, sc, J, D, w_surf, step, tbar)
    return None if step is None else (step[0], step[0] * d)


def _farther(x: np.ndarray, d: np.ndarray, loops: list[np.ndarray], sc: Scaffold, J: np.ndarray, D: np.ndarray,
             w_surf: np.ndarray, step: tuple[float, float], tbar: float) -> tuple[float, float]:
    """A line search that doubled up to ``LINE_SEARCH_MAX`` goes on doubling the step (t, its energy) while that
    lowers the surface energy, within the flip barrier ``tbar`` and as far as the chained scaffolds allow
    (``feasible_step``, asked only when the next doubling lowers the energy). Why: a start with a nearly degenerate
    triangle (a mollified zero-area face that a coarse level flattened almost to nothing) is steep in the 1/det²
    terms, and a Newton step grows that det by only a third, so a capped search spends dozens of iterations on one
    face. Where twice the cap does not lower the energy the step is the capped search's."""
    t, E1 = step
    if not 2 * t <= tbar:
        return step
    E2 = symmetric_dirichlet(J + 2 * t * D, w_surf)[0]
    if not E2 < E1:
        return step
    tfar = feasible_step(x, d, loops, sc, tbar)
    while 2 * t <= tfar and E2 < E1:
        t, E1 = 2 * t, E2
        E2 = symmetric_dirichlet(J + 2 * t * D, w_surf)[0] if 2 * t <= tfar else E1
    return t, E1


class ScaffoldUse(Enum):
    """How a polish keeps boundaries from crossing: a scaffold at every iteration (``ALWAYS``), none, each step
    checked instead (``NEVER``: many charts polished together, ``refine.charts``), or none until a step would make
    boundaries cross and the scaffold from that iteration on (``UNTIL_CROSSING``: a fine level after a converged
    coarse level, whose boundary stays put)."""

    ALWAYS = "always"
    NEVER = "never"
    UNTIL_CROSSING = "until crossing"


class Stop(Enum):
    """Why a polish stopped (:attr:`Polish.stop`); the value is the report's text (``{detail}``: what failed,
    ``{excess_tol}``: the excess rule's tolerance, ``{base}``: what its excess is measured from)."""

    ITERATION_CAP = "iteration cap"
    CONVERGED = "converged"
    START_IS_MINIMUM = "converged (the start is an isometry to within the tolerance)"
    EXCESS_GAINS = "converged (gains below {excess_tol:g} of the excess over {base})"
    EXCESS_PREDICTED = "converged (next gain predicted below {excess_tol:g} of the excess over {base})"
    STALLED = "stalled at the barrier"
    NO_DESCENT = "no descent"
    SCAFFOLD_FAILED = "scaffold failed: {detail}"
    NUMERICAL_FAILURE = "numerical failure ({detail}): the last bijective layout is kept"


@dataclass(frozen=True)
class PolishSettings:
    """How a :class:`Polish` iterates.

    max_iters : iteration cap. tol : converged when an uncut step lowers the energy by less than this fraction.
    backend : factorization backend (``solvers.Factor``). excess_tol : an iteration that lowers the energy by less
    than this fraction of its excess over an isometry (Ψ - 4) also counts as small (0: off; the atlas's joint
    polish, a large mesh's finest level). excess_base : the normalized energy that excess is measured from (1: an
    isometry; a fine level: its coarse level's). excess_predict : with ``excess_tol``, also stop when the next
    gain, predicted from the last two, falls below it (False: on gains made only). stall_iters : barrier-limited
    iterations in a row that gain < ``tol`` before the polish gives up.
    confirm_light : an uncut step that gains < ``tol`` stops the polish only at the scaffold's lightest weight
    (one more iteration there to confirm it); False stops at once (a fine level after a coarse one). park : a pause
    frees the factorization and the Hessian's pattern (False keeps them: a trial usually finished next).
    scaffold : :class:`ScaffoldUse`. scaffold_weight : the scaffold's starting weight, a fraction of its largest
    within [``SCAFFOLD_WEIGHT_MIN``, 1] (a fine level starts where its converged coarse level ended).
    keep_scaffold : keep the last iteration's scaffold while it holds (``scaffold.scaffold_holds``: the Hessian's
    pattern stays and PARDISO refactorizes without a new analysis) instead of re-triangulating at every iteration.
    """

    max_iters: int = 200
    tol: float = 1e-6
    backend: str = "auto"
    excess_tol: float = 0.0
    excess_base: float = 1.0
    excess_predict: bool = True
    stall_iters: int = STALL_ITERS
    confirm_light: bool = True
    park: bool = True
    scaffold: ScaffoldUse = ScaffoldUse.ALWAYS
    scaffold_weight: float = 1.0
    keep_scaffold: bool = False


class _Next(Enum):
    """What follows one iteration of :meth:`Polish._run`."""

    GO_ON = 0
    STOP = 1
    PAUSE = 2


FULL_STEP = 0.5  # a step of at least half the Newton step counts as uncut ("Stopping")


def polish(uv: np.ndarray, F: np.ndarray, g: np.ndarray, area: np.ndarray, loops: list[np.ndarray], *, bar=None,
           groups: np.ndarray | None = None, **settings) -> tuple[np.ndarray, dict]:
    """Minimize the symmetric Dirichlet energy Σ A_f Ψ(J_f) from a bijective layout ``uv`` (n,2), keeping it bijective
    (the scheme: module docstring). g (m,3,2): hat gradients of the rest triangles; area (m,): their areas; loops:
    boundary loops, outer first; groups (m,): the chart of each face, for ``ScaffoldUse.NEVER``;
    ``settings``: :class:`PolishSettings` fields. Returns the layout (n,2) and a JSON-able report. :class:`Polish`
    runs the same iterations in steps.
    """
    run = Polish(uv, F, g, area, loops, PolishSettings(**settings), bar=bar, groups=groups)
    run.run()
    return run.x, run.report()


class Polish:
    """:func:`polish` as an object that can pause and go on: ``run(pause_excess)`` iterates until the polish stops
    or (``pause_excess`` > 0) an iteration lowers the energy by less than that fraction of its excess over an
    isometry; ``run()`` again goes on from there, so a paused and resumed polish makes exactly the iterations (and
    the layout) of one that never paused. ``x`` (n,2) is the current layout, ``done`` whether it has stopped,
    ``stop`` why (:class:`Stop`). ``settings``: :class:`PolishSettings`. ``groups`` (m,): the chart of each face
    (default one) for ``ScaffoldUse.NEVER``: the charts being separate components, each takes its own step, checked
    instead of barred (:func:`_chart_steps`). ``prepared``: the Hessian's pattern and analysis made ahead of time
    (:func:`prepare_hessian`).
    ``report()["scaffold_from_iteration"]`` (``UNTIL_CROSSING``): where the scaffold was taken, None if never."""

    def __init__(self, uv: np.ndarray, F: np.ndarray, g: np.ndarray, area: np.ndarray, loops: list[np.ndarray],
                 settings: PolishSettings | None = None, *, bar=None, groups: np.ndarray | None = None,
                 prepared: Prepared | None = None):
        t0 = time.perf_counter()
        settings = PolishSettings() if settings is None else settings
        self.settings, self._prepared = settings, prepared
        self.F, self.g, self.loops, self.bar = F, g, loops, bar
        n = len(uv)
        self.backend = large_system_backend(2 * n, settings.backend, POLISH_PARDISO_MIN_UNKNOWNS)
        self.w_surf = area / area.sum()
        self.w_max = SCAFFOLD_WEIGHT * float(self.w_surf.mean())
        self.w_min = SCAFFOLD_WEIGHT_MIN * self.w_max
        self.w_scaf = float(np.clip(settings.scaffold_weight, SCAFFOLD_WEIGHT_MIN, 1.0)) * self.w_max
        self.crossing_switch = None
        if settings.scaffold is ScaffoldUse.NEVER:  # nothing to relax: the stop rules see the lightest weight
            self.w_scaf = self.w_min
        self.scaffold = settings.scaffold is ScaffoldUse.ALWAYS
        self.groups = None if self.scaffold else ChartGroups.of(F, n, loops, groups, self.w_surf)
        self.x = uv.copy()
        self.hist: list[float] = []
        self.fac, self.refactorizations, self.it, self.converged = None, 0, 0, False
        self.stop, self.stop_detail = Stop.ITERATION_CAP, ""
        self.small = self.small_excess = 0
        self.max_iters = settings.max_iters
        self.done = False
        self._H_last = self._parked = self.pat = None
        self._ok: tuple | None = None  # (x, J, Es) of the last layout a scaffold was built around
        self._sc: Scaffold | None = None  # that scaffold, kept while it holds (``scaffold.scaffold_holds``)
        # surface Jacobians and energy of the current layout, carried from step to step
        self.J = jacobians(self.x, F, g)
        self.Es = symmetric_dirichlet(self.J, self.w_surf)[0]
        # Ψ ≥ 4 on every face (equality iff isometric), so no step can gain more than Es - 4: below the
        # Newton-decrement threshold the start is the minimum (the LSCM start of a developable part) and nothing is
        # assembled
        if np.isfinite(self.Es) and self.Es - 4.0 <= DECREMENT_TOL * settings.tol * self.Es:
            self.hist.append(self.Es)
            self.max_iters, self.converged, self.stop = 0, True, Stop.START_IS_MINIMUM
        self.seconds = time.perf_counter() - t0

    def run(self, pause_excess: float = 0.0) -> bool:
        """Iterate until the polish stops (returns True) or pauses (False; module docstring of the class)."""
        t0 = time.perf_counter()
        try:
            return self._run(pause_excess)
        finally:
            self.seconds += time.perf_counter() - t0

    def _park(self) -> None:
        """While paused, free the factorization and the Hessian's pattern (a 200k-vertex halftunnel: 2.36 GB peak
        with them held while the seams stage flattened the cut mesh); :meth:`_unpark` rebuilds both exactly."""
        if self.fac is not None:
            kept = self.fac.rebuild_matrix()
            self._parked = (self.fac.backend, self._H_last if kept is None else kept, self.fac.ordering)
            self.fac = None
        self.pat = None

    def _unpark(self) -> None:
        """What the iterations need: the Hessian's pattern (built once, and again after a pause) and, after a
        pause, the factorization :meth:`_park` freed."""
        if self._parked is not None:
            backend, A, ordering = self._parked
            # the same matrix and ordering: the same factor (PARDISO's is the analysed upper triangle)
            self.fac, self._parked = Factor(A, backend, upper=backend == "pardiso", ordering=ordering), None
        if self.pat is None and self._prepared is not None and self._prepared.pat.upper == (self.backend == "pardiso"):
            self.pat = self._prepared.pat  # made ahead of time (prepare_hessian)
        if self.pat is None and self.max_iters > 0:
            self.pat = HessianPattern(self.F, len(self.x), upper=self.backend == "pardiso")

    def _run(self, pause_excess: float) -> bool:
        self._unpark()
        while self.it < self.max_iters:
            self.it += 1
            after = self._iteration(pause_excess)
            if after is _Next.STOP:
                break
            if after is _Next.PAUSE:
                if self.settings.park:
                    self._park()
                return False
        self.done = True
        self.fac = self.pat = self._H_last = self._prepared = None  # stopped: nothing more to solve
        return True

    def _stopped(self, why: Stop, converged: bool = False, detail: str = "") -> _Next:
        self.stop, self.stop_detail, self.converged = why, detail, converged
        return _Next.STOP

    def _iteration(self, pause_excess: float) -> _Next:
        """One Newton iteration: the system, its direction, the bijective step, then the stop rules."""
        sy = self._system()
        if sy is None:
            return _Next.STOP
        self.hist.append(self.Es)
        direction = _safe_direction(sy, self.fac, self.backend)
        if isinstance(direction, str):
            return self._stopped(Stop.NUMERICAL_FAILURE, detail=direction)
        dx, self.fac, fresh = direction
        self.refactorizations += fresh
        if fresh and self.fac.rebuild_matrix() is None:  # what rebuilds this factor after a pause
            self._H_last = sy.H
        # a negligible Newton decrement: the start is already the minimum (module docstring, "Stopping")
        if 0.5 * float(sy.rhs @ dx) <= DECREMENT_TOL * self.settings.tol * sy.E0:
            return self._stopped(Stop.CONVERGED, converged=True)
        step = _barrier_step(self.x, self.J, self.Es, dx, self.F, self.g, self.w_surf, sy.sc, self.loops,
                             self.groups, 0 if self.settings.scaffold is ScaffoldUse.UNTIL_CROSSING
                             else CROSSING_HALVINGS)
        if step is None:
            if self.settings.scaffold is ScaffoldUse.UNTIL_CROSSING and not self.scaffold:
                # boundaries in the way: this iteration again, and the rest, with the scaffold at its stiffest, as
                # after a coarse level that stalled: they press on each other (docs/refine.md 5.6)
                self.scaffold, self.crossing_switch, self.w_scaf = True, self.it, self.w_max
                self.it -= 1
                self.hist.pop()
                return _Next.GO_ON
            return self._stopped(Stop.NO_DESCENT)
        t, move = step
        self.x = self.x + move
        self.J = jacobians(self.x, self.F, self.g)
        self.Es = symmetric_dirichlet(self.J, self.w_surf)[0]
        if self.bar is not None:
            self.bar.set_postfix_str(f"energy {self.Es / 4:.5f} (1 = isometry)", refresh=False)
            self.bar.update(1)
        return self._judge(t, self.Es, pause_excess)

    def _system(self) -> _System | None:
        """The iteration's system (:func:`_system`), or None when its scaffold could not be built (the stop set)."""
        try:
            sy = _system(self.x, self.J, self.Es, self.F, self.g, self.w_surf, self.w_scaf, self.loops, self.pat,
                         self._sc if self.settings.keep_scaffold else None, self.scaffold)
        except ValueError as exc:
            detail = str(exc)
            if self._ok is not None:  # the last step left boundaries touching: keep the layout before it
                (self.x, self.J, self.Es), self.it = self._ok, self.it - 1
                detail += " (after the last step; the layout before it is kept)"
            self._stopped(Stop.SCAFFOLD_FAILED, detail=detail)
            return None
        self._ok = (self.x, self.J, self.Es)  # a valid scaffold around x: no boundaries touch or cross
        self._sc = sy.sc
        if self._prepared is not None:  # the first Hessian: without a scaffold it has the prepared pattern
            analysis, self._prepared = self._prepared.analysis, None
            if analysis is not None and self.fac is None and sy.sc is None:
                try:
                    self.fac = analysis.result()  # its first refactor() is a numerical factorization only
                except Exception:  # noqa: BLE001 - only a head start: the factorization is made here as ever
                    self.fac = None
        return sy

    def _judge(self, t: float, Es1: float, pause_excess: float) -> _Next:
        """The stop rules after a step of length ``t`` to energy ``Es1`` (module docstring, "Stopping"), the
        scaffold's weight relaxed or stiffened ("Scaffold weight"), and whether to pause."""
        tol, excess_tol = self.settings.tol, self.settings.excess_tol
        gain = self.hist[-1] - Es1
        excess = Es1 - 4.0 * self.settings.excess_base
        low_excess = excess_tol > 0 and gain < excess_tol * excess
        self.small_excess = self.small_excess + 1 if low_excess else 0
        if low_excess and self.small_excess >= EXCESS_STALL_ITERS:
            self.hist.append(Es1)
            return self._stopped(Stop.EXCESS_GAINS, converged=True)
        # the next gain as this one times its ratio to the last (Newton's gains shrink at least that fast near
        # the minimum): below the excess rule, the iteration is not made
        last = self.hist[-2] - self.hist[-1] if len(self.hist) > 1 else 0.0
        if (excess_tol > 0 and self.settings.excess_predict and 0 < gain < last
                and gain * gain / last < excess_tol * excess):
            self.hist.append(Es1)
            return self._stopped(Stop.EXCESS_PREDICTED, converged=True)
        if gain / self.hist[-1] < tol or low_excess:
            self.small += 1  # converged only after an uncut step with the lightest scaffold ("Stopping")
            if t >= FULL_STEP and self.scaffold and self.w_scaf > self.w_min and self.settings.confirm_light:
                self.w_scaf = self.w_min
                return _Next.GO_ON
            if t >= FULL_STEP or self.small >= self.settings.stall_iters:
                self.hist.append(Es1)
                uncut = t >= FULL_STEP
                return self._stopped(Stop.CONVERGED if uncut else Stop.STALLED, converged=uncut)
        else:
            self.small = 0
        self.w_scaf = (max(self.w_scaf / SCAFFOLD_ADAPT, self.w_min) if t >= FULL_STEP
                       else min(self.w_scaf * SCAFFOLD_ADAPT, self.w_max))
        if pause_excess > 0 and gain < pause_excess * (Es1 - 4.0):
            return _Next.PAUSE
        return _Next.GO_ON

    def stop_text(self) -> str:
        """Why the polish stopped, as the report says it."""
        base = self.settings.excess_base
        return self.stop.value.format(detail=self.stop_detail, excess_tol=self.settings.excess_tol,
                                      base="an isometry" if base == 1.0 else f"the coarse level's energy {base:.6f}")

    def report(self) -> dict:
        """The JSON-able report (``stop`` says "paused" while the polish has not stopped)."""
        hist = self.hist or [self.Es]  # no iteration yet (a fine level waiting paused: ``multilevel.Levels``)
        return {"iterations": self.it, "converged": self.converged, "stop": self.stop_text() if self.done else "paused",
                "energy_start": float(hist[0] / 4),
                "energy_end": float((hist[-1] if self.done else self.Es) / 4),
                "factorizations": self.refactorizations, "backend": self.backend,
                "scaffold_weight": self.w_scaf / self.w_max, "seconds": round(self.seconds, 3),
                **({"scaffold_from_iteration": self.crossing_switch}
                   if self.settings.scaffold is ScaffoldUse.UNTIL_CROSSING else {})}
