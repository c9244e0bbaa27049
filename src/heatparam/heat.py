"""Heat kernels (paper Eq. 2-4, 7) and heat-method geodesic distances (Eq. 8-10), many sources per solve.

Precompute once: factor (Δt·L + B) for Eq. 4 and the Poisson matrix L for Eq. 10; then every batch of sources
is two multi-column back-substitutions plus sparse × dense products (Eq. 8 gradient/normalization, Eq. 10
divergence). No Python loop runs per vertex.
"""

from __future__ import annotations

import operator
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

from heatparam.memory import require
from heatparam.mesh.topology import edge_graph
from heatparam.operators import Operators
from heatparam.options import TIME_STEPS
from heatparam.solvers import Factor, large_system_backend

#: Bytes of scratch per source column per vertex in :meth:`HeatGeodesics.distances` (heat solution, gradient
#: and unit field on ~2n faces × 2 components, right-hand side, distance): ~12 float64 per vertex.
_BYTES_PER_COLUMN_VERTEX = 12 * 8
#: Most columns per batch: time per source on beetle.off (20k vertices) is lowest at 8-16 columns and higher at
#: 32-64 (the (2m,k) gradient block no longer stays in cache); ``bench/bench_solvers.py`` (second table)
#: measures it. On ~180k vertices the batch width hardly matters (memory bound either way).
MAX_BLOCK = 16
#: Meshes of at least this many vertices factorize with PARDISO when it is installed (backend ``auto``): its faster
#: factorization pays for the pipeline's ~100 landmark sources there (camelhead↑180k: 1.2 vs 3.0 s); below it
#: CHOLMOD's faster solves win.
PARDISO_MIN_VERTICES = 100_000
#: Batches of sources run in this many threads on meshes of fewer than THREADS_MAX_VERTICES vertices. A
#: factorization is not safe to use from two threads at once, so the solves take turns (``HeatGeodesics._lock``);
#: what overlaps is one batch's gradient, normalization and divergence products (numpy/scipy release the GIL) with
#: the other's solves (beetle: 1.07 vs 1.29 ms per source). Large meshes are memory-bound: threads only cost there.
THREADS = 2
THREADS_MAX_VERTICES = 100_000


#: The heat kernel of one implicit step, u = (t·L + B)⁻¹ B δ, decays like exp(−d/√t) with the distance d from its
#: source (measured: 0.95-1.0 per √t on flat disks and strips). Below ~1e-300 doubles lose it (denormals, then 0):
#: ∇u vanishes and the distances there are garbage. The default t keeps d/√t ≤ DECAY_RANGE over the whole surface.
DECAY_RANGE = 600.0
#: An explicit time step whose diffusion length √t exceeds this many diameter bounds is refused: the heat then
#: spreads over the whole surface in one step and its gradient carries no direction.
TIME_MAX_SPAN = 100.0


def diameter_bound(op: Operators) -> float:
    """An upper bound on the geodesic distance between any two vertices: 2 × the eccentricity of a central vertex
    in the edge graph (edge paths are curves on the surface, so graph distances bound geodesic ones; the triangle
    inequality gives d(a,b) ≤ d(a,c) + d(c,b)). c: the vertex nearest both ends of a double sweep. Four Dijkstra
    runs on the (intrinsic) edge graph: ~0.05 s each at 200k vertices; ~1.07 × the diameter on a flat disk."""
    from scipy.sparse.csgraph import dijkstra

    graph = edge_graph(op.F, op.lengths, op.L.shape[0])

    def sweep(i: int) -> np.ndarray:
        d = dijkstra(graph, directed=False, indices=i)
        return np.where(np.isfinite(d), d, -1.0)  # vertices of no face (none after validation) are ignored

    da = sweep(int(np.argmax(sweep(0))))
    db = sweep(int(np.argmax(da)))
    return 2.0 * float(sweep(int(np.argmin(np.maximum(da, db)))).max())


def time_step(op: Operators, mode: str | float = "default", coef: float = 1.0, unit: float = 1.0) -> float:
    """Heat diffusion time t for Eq. 4, in the operators' length units (``unit``: their length in model units,
    ``mesh.frame.UnitFrame.unit``; the number and Eq. 7 are taken in model units).

    ``default``: t = coef·h², h the mean edge length (Crane et al. 2013). It has units of length², so the
    distances scale with the mesh and the map is scale-invariant. On surfaces more than ~600 edges across (long
    strips, scans of ~200k vertices and more) t is raised to (:func:`diameter_bound` / ``DECAY_RANGE``)², so the
    kernel never underflows (at t = h² a 20 × 0.3 strip of 5k vertices had 3.4% mean and 23% max distance error).
    ``paper``: Eq. 7 exactly, Δt = T = the longest edge length (a single implicit step). It has units of
    length, not length², so it is **not** scale-invariant: scaling the mesh by s changes the relative diffusion
    by 1/s and so changes the map's shape, not only its size.
    A float is taken as t itself.
    """
    if isinstance(mode, (int, float)) and not isinstance(mode, bool):
        if not mode > 0:
            raise ValueError(f"time step must be positive, got {mode}")
        return float(mode) / unit**2  # a time has units of length²
    if mode == "default":
        return max(coef * op.mean_edge**2, min_time_step(op))
    if mode == "paper":
        return op.max_edge / unit  # Eq. 7: Δt = the longest edge's length in model units, taken as a time
    raise ValueError(f"time step must be one of {TIME_STEPS} or a positive number, got {mode!r}")


def check_time_step(mode: str | float, diameter: float) -> None:
    """Refuse an explicit time step (model units²) that spreads the heat over more than ``TIME_MAX_SPAN`` × the
    surface's ``diameter`` (bounding-box diagonal, model units) in one step: its distances carry no information.
    Checked up front, before any work (a shortcut may skip the heat stage, which would hide the mistake)."""
    if not isinstance(mode, str) and mode > (TIME_MAX_SPAN * diameter) ** 2:
        from heatparam.errors import HeatparamError

        raise HeatparamError(f"time_step={mode:g} is far too large for this surface (its heat spreads over more than "
                             f"{TIME_MAX_SPAN:g} × the surface's size in one step, so the distances carry no "
                             "information) — use time_step='default'")


def min_time_step(op: Operators) -> float:
    """The smallest t at which the heat kernel stays representable across the surface: (bound / DECAY_RANGE)²."""
    return (diameter_bound(op) / DECAY_RANGE) ** 2


def underflow_warning(op: Operators, t: float) -> str | None:
    """A warning when t (given explicitly) is too small for the surface's size: far distances are then wrong."""
    t_min = min_time_step(op)
    if t >= t_min:
        return None
    span = DECAY_RANGE * np.sqrt(t_min / t)  # the diameter bound in units of √t
    return (f"time step {t:.3g} is too small for this surface (it spans {span:.0f} √t, "
            f"the heat kernel underflows beyond ~{DECAY_RANGE:.0f} √t): far distances will be wrong; use "
            f"time_step='default' or at least {t_min:.3g}")


class HeatGeodesics:
    """Heat-method geodesic distances on one mesh (precompute in the constructor, then solve many).

    Parameters
    ----------
    op : the mesh's :class:`Operators` (L, B, G, div).
    t : diffusion time Δt = T (see :func:`time_step`).
    backend : sparse factorization backend (see :mod:`heatparam.solvers`).
    block_bytes : scratch memory budget per batch of sources; sets how many columns are solved at once.
    """

    def __init__(self, op: Operators, t: float, backend: str = "auto", block_bytes: float = 256 * 2**20):
        self.op = op
        self.t = float(t)
        self.n = op.L.shape[0]
        backend = large_system_backend(self.n, backend, PARDISO_MIN_VERTICES)
        try:
            self.heat = Factor((self.t * op.L + op.B).tocsc(), backend)  # Eq. 4
            # Eq. 10: L is singular (constants); its right-hand side sums to zero, so pinning vertex 0 and
            # solving the reduced SPD system gives the exact solution up to the constant fixed afterwards.
            self.poisson = Factor(op.L[1:, 1:].tocsc(), self.heat.backend)
        except (ValueError, RuntimeError, ArithmeticError, np.linalg.LinAlgError) as exc:
            from heatparam.errors import HeatparamError

            raise HeatparamError(f"the heat method's systems could not be factorized ({str(exc).splitlines()[0]}): "
                                 "is the mesh degenerate, or the time step extreme? (time_step='default')") from None
        self.backend = self.heat.backend
        self._lock = threading.Lock()
        self.block = int(max(1, min(MAX_BLOCK, block_bytes // (_BYTES_PER_COLUMN_VERTEX * self.n))))
        self._lumped = np.asarray(op.B.sum(axis=1)).ravel()  # ∫ of each hat function
        self._m = len(op.areas)
        # One (2m,n) gradient product per batch and one (n,2m) product for the right-hand side of Eq. 10:
        # −div H = Gᵀ·diag(A,A)·H = op.D·(∇u/|∇u|), the minus sign of H = −∇u/|∇u| folded into op.D.
        self._G = sp.csr_matrix(op.G, copy=True)
        self._G.eliminate_zeros()  # the local frames put exact zeros in G (one per face): skip them
        self._G.sort_indices()
        self._D = sp.csr_matrix(op.D)
        self._D.sort_indices()

    def _weights(self, sources) -> sp.csc_matrix:
        """Sources as an (n,k) sparse weight matrix: vertex indices → unit columns; a matrix is taken as is."""
        if sp.issparse(sources):
            return sp.csc_matrix(sources)
        src = np.asarray(sources, dtype=np.int64)
        return sp.csc_matrix((np.ones(len(src)), (src, np.arange(len(src)))), shape=(self.n, len(src)))

    def kernels(self, sources) -> np.ndarray:
        """Heat kernels u_i(·, T) (Eq. 4 with one step Δt = T) for the given sources, (n,k).

        sources : vertex indices (k,), or an (n,k) sparse matrix of barycentric weights (point sources).
        The initial condition is the discrete Dirac δ_i of Eq. 3 (∫δ_i = 1): δ_i = Σ_v w_v e_v / ∫φ_v.
        """
        W = self._weights(sources)
        delta = sp.diags(1.0 / self._lumped) @ W
        rhs = (self.op.B @ delta).toarray()
        with self._lock:
            return self.heat.solve(rhs)

    def _distances_block(self, W: sp.csc_matrix) -> np.ndarray:
        u = self.kernels(W)
        k, m = W.shape[1], self._m
        g = self._G @ u  # per-face ∇u in local frames, (2m,k): rows [0,m) x, rows [m,2m) y
        del u
        normalize_gradient(g[:m], g[m:])  # Eq. 8: H = −∇u/|∇u|; the sign is folded into op.D below
        rhs = self._D @ g  # −div H (Eq. 9-10 right-hand side, B·K in the paper)
        del g
        phi = np.empty((self.n, k))
        phi[0] = 0.0
        with self._lock:
            self.poisson.solve(rhs[1:], out=phi[1:])
        del rhs
        cols = np.repeat(np.arange(k), np.diff(W.indptr))
        phi -= np.bincount(cols, weights=W.data * phi[W.indices, cols], minlength=k)  # source at distance 0
        np.maximum(phi, 0.0, out=phi)  # tiny negative values near the source are discretization noise
        return phi

    def distances(
        self,
        sources,
        out: np.ndarray | None = None,
        progress: Callable[[int], None] | None = None,
    ) -> np.ndarray:
        """Geodesic distances from each source to every vertex, (n,k); column j belongs to ``sources[j]``.

        sources : vertex indices (k,), or an (n,k) sparse matrix whose column j holds the barycentric weights
            of a source point inside a face (see :func:`point_sources`).

        ``out`` may be a preallocated (n,k) array (any float dtype). ``progress(c)`` is called after each
        batch with the number of columns done.
        """
        W = self._weights(sources)
        k = W.shape[1]
        if out is None:
            require(8.0 * self.n * k, f"distance matrix {self.n} x {k}", "use fewer sources (landmarks)")
            out = np.empty((self.n, k))
        starts = range(0, k, self.block)
        threads = THREADS if self.n < THREADS_MAX_VERTICES else 1

        def block(s: int) -> int:
            out[:, s : s + self.block] = self._distances_block(W[:, s : s + self.block])
            return min(self.block, k - s)

        # batches in threads, their solves one at a time (see THREADS)
        pool = ThreadPoolExecutor(threads) if threads > 1 and len(starts) > 1 else None
        try:
            for c in (pool.map if pool else map)(block, starts):
                if progress is not None:
                    progress(c)
        finally:
            if pool:
                pool.shutdown()
        return out


#: :func:`normalize_gradient` works on row chunks of about this many bytes per component (they stay in cache).
_CHUNK_BYTES = 256 * 2**10


#: Below this norm x² + y² is subnormal or zero (~1e-308), so :func:`normalize_gradient` takes np.hypot (5× slower)
#: there.
_TINY_NORM = 1e-150


def normalize_gradient(gx: np.ndarray, gy: np.ndarray) -> None:
    """Scale the 2D vectors (gx[i,j], gy[i,j]) to unit length in place; zero vectors stay zero.

    Done on row chunks that fit in cache: on large meshes the (m,k) arrays do not, and the five passes of the
    normalization would otherwise each stream them through memory.
    """
    rows = max(1, _CHUNK_BYTES // (8 * max(gx.shape[1], 1)))
    buf = np.empty((min(rows, len(gx)), gx.shape[1]))
    for a in range(0, len(gx), rows):
        x, y = gx[a : a + rows], gy[a : a + rows]
        norm = buf[: len(x)]
        np.multiply(x, x, out=norm)
        norm += y * y
        np.sqrt(norm, out=norm)
        tiny = norm < _TINY_NORM  # x² + y² lost precision or underflowed far from the source: recompute safely
        if tiny.any():
            norm[tiny] = np.hypot(x[tiny], y[tiny])
        norm[norm == 0] = 1.0  # flat regions: no direction, zero field
        x /= norm
        y /= norm


def euclidean_from(VT: np.ndarray, i: int) -> np.ndarray:
    """|V[j] − V[i]| for all j, from VT = Vᵀ (3,n): the same sums in the same order as
    ``np.linalg.norm(V - V[i], axis=1)`` (so bit-identical), ~8× faster on large meshes (no (n,3) strided reduce).
    """
    d = VT - VT[:, i : i + 1]
    d *= d
    s = d[0] + d[1]
    s += d[2]
    return np.sqrt(s, out=s)


def point_sources(F: np.ndarray, face: np.ndarray, bary: np.ndarray, n: int) -> sp.csc_matrix:
    """Sparse (n,p) weights of p points inside faces: column j = bary[j] on the corners of F[face[j]]."""
    p = len(face)
    return sp.csc_matrix((bary.ravel(), (F[face].ravel(), np.repeat(np.arange(p), 3))), shape=(n, p))


def all_pairs_bytes(n: int) -> float:
    """Peak bytes of the all-pairs path (the n×n distance matrix plus MDS work vectors)."""
    return 8.0 * n * n * 1.05


def all_pairs(solver: HeatGeodesics, progress: Callable[[int], None] | None = None) -> np.ndarray:
    """The symmetrized all-pairs geodesic matrix G (n,n), Eq. 10 for every vertex, G = (G + Gᵀ)/2."""
    n = solver.n
    require(all_pairs_bytes(n), f"all-pairs distance matrix {n} x {n}", "use geodesics='landmarks'")
    D = solver.distances(np.arange(n), progress=progress)
    D += D.T  # in place and symmetric: numpy buffers the transposed operand when they overlap
    D *= 0.5
    return D


def farthest_point_landmarks(
    solver: HeatGeodesics,
    V: np.ndarray,
    k: int,
    seed: int = 0,
    progress: Callable[[int], None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """k landmarks by geodesic farthest-point sampling, and their distance columns (n,k).

    The samples are drawn in doubling batches (1, 1, 2, 4, ...) so that each batch is one multi-column solve:
    within a batch, each next point is the farthest from the landmarks so far by geodesic distance and from
    the batch's earlier picks by straight-line distance (a lower bound of the geodesic one). The distance
    columns are the ones landmark MDS needs, so sampling costs no extra solves.
    """
    n = solver.n
    k = int(min(k, n))
    rng = np.random.default_rng(seed)
    D = np.empty((n, k))
    chosen = np.empty(k, dtype=np.int64)
    # Start from the vertex farthest from a random one (lands on the border, independent of the seed's luck).
    start = int(rng.integers(n))
    d0 = solver.distances([start])[:, 0]
    chosen[0] = int(np.argmax(d0))
    D[:, :1] = solver.distances(chosen[:1], progress=progress)
    mind = D[:, 0].copy()
    done = 1
    VT = np.ascontiguousarray(np.asarray(V).T)  # (3,n): the straight-line distances below, column by column
    while done < k:
        b = min(done, k - done)
        cur = mind.copy()
        for j in range(b):
            i = int(np.argmax(cur))
            chosen[done + j] = i
            np.minimum(cur, euclidean_from(VT, i), out=cur)
        solver.distances(chosen[done : done + b], out=D[:, done : done + b], progress=progress)
        np.minimum(mind, D[:, done : done + b].min(axis=1), out=mind)
        done += b
    return chosen, D


def geodesic_distances(V: np.ndarray, F: np.ndarray, sources, time_step_mode: str | float = "default",
                       t_coef: float = 1.0, solver: str = "auto") -> tuple[np.ndarray, str | None]:
    """One-shot heat-method geodesic distances (Eq. 4, 8-10) from source vertices, on any manifold mesh (closed
    surfaces too): the operators, :func:`time_step` and :class:`HeatGeodesics` in one call.

    Parameters
    ----------
    V : (n,3) float64. F : (m,3) int64. sources : (k,) int vertex ids (each referenced by a face).
    time_step_mode, t_coef, solver : as ``Options.time_step``, ``Options.t_coef``, ``Options.solver``.

    Returns
    -------
    D : (n,k) float64, column j the distances from ``sources[j]``; vertices no face uses are unreachable (inf).
    warning : an explicit time step too small for the surface (:func:`underflow_warning`), or None.

    Examples
    --------
    >>> from heatparam import datasets
    >>> s = datasets.flat_square(h=0.1)
    >>> D, _ = geodesic_distances(s.V, s.F, [0])
    >>> D.shape[1]
    1
    """
    from heatparam.errors import HeatparamError
    from heatparam.mesh.frame import frame_of
    from heatparam.mesh.topology import compact
    from heatparam.mesh.validate import check_arrays, validate_mesh
    from heatparam.operators import build_operators

    V, F = check_arrays(V, F)
    try:
        ids = [operator.index(s) for s in np.atleast_1d(sources).tolist()]  # Python ints: any size, no overflow
    except TypeError:
        ids = []
    if not ids:
        raise HeatparamError("sources must be a non-empty list of vertex indices")
    bad = [s for s in ids if not 0 <= s < len(V)]
    if bad:
        raise HeatparamError(f"source vertex {bad[0]} is out of range (the mesh has {len(V)} vertices)")
    frame = frame_of(V, F)  # extreme sizes are computed near the unit box (exactly), then scaled back
    V = frame.to_unit(V)
    info = validate_mesh(V, F, flatten=False)  # distances need no boundary: closed scans are fine here
    check_time_step(time_step_mode, info.diameter * frame.unit)
    src = np.asarray(ids, dtype=np.int64)
    if not info.referenced[src].all():
        raise HeatparamError(f"source vertex {int(src[~info.referenced[src]][0])} is not used by any face")
    comp = compact(info.referenced)
    op = build_operators(V[comp.keep], comp.faces(F))
    t = time_step(op, time_step_mode, t_coef, frame.unit)
    warning = underflow_warning(op, t) if time_step_mode != "default" else None
    D = np.full((len(V), len(src)), np.inf)
    D[comp.keep] = frame.lengths_to_model(HeatGeodesics(op, t, backend=solver).distances(comp.remap[src]))
    if not np.isfinite(D[comp.keep]).all():
        raise HeatparamError("the heat-method distances are not finite (the time step is far too large or too "
                             "small for this surface) — use time_step='default'")
    return D, warning
