"""Coarse-to-fine polish: polish a coarse mesh, prolongate, repair the few flips, polish the fine mesh from there."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from heatparam import metrics
from heatparam.layout.tutte import mean_value_laplacian
from heatparam.mesh.planar import make_ccw, triangulate
from heatparam.mesh.topology import face_areas, unique_inverse
from heatparam.refine.energy import det, jacobians, normalized_energy, surface_gradients
from heatparam.refine.newton import STALL_ITERS, Polish, prepare_hessian
from heatparam.refine.scaffold import loop_edges, loop_ranges
from heatparam.refine.untangle import untangle

COARSE_FRACTION = 1 / 8  # each coarser level has about this fraction of the vertices (camelhead↑727k: at 1/27 the
#                          repair of the prolongation's flips failed, at 1/6.5 it needed 7 rounds) ...
COARSE_MIN = 8_000  # ... but at least this many; levels of >= refine_multilevel vertices get a coarser level too

#: A coarse level of at least this many vertices gets a coarser level of its own even below ``refine_multilevel``
#: (0: only from ``refine_multilevel``): camelhead upsampled to 182k, its 27.6k level polished from the conformal
#: layout (energy 128) took 15 Newton iterations (2.4-2.6 s); from its own 8k level, 5 (0.8 s) after 14 cheap ones,
#: the same fine iterations and iso mean (2.05883), refine 9.9-10.1 → 9.5-9.6 s (BENCHMARKS §24)
LEVEL_MULTILEVEL_MIN = 20_000

REPAIR_RINGS = 8  # each repair round re-solves the flipped faces' 8-ring neighbourhoods ...

REPAIR_ROUNDS = 12  # ... at most this many rounds

#: A coarse level's prolongation (to a level that is itself coarse) is repaired with the prolongated layout's own
#: weights first, the start's second (the finest level: the other way round, ``repair_flips``): camelhead upsampled
#: to 182k, its 27.6k level's start-weight repair failed after 12 rounds (0.88 s; 2 flipped faces, up to 8110 as
#: its region grew) before these succeeded in one (0.02 s); its coarse levels 1.54 → 0.71 s, the same map
#: (BENCHMARKS.md §25)
PROLONGATED_FIRST = True

MULTILEVEL_MIN_EXCESS = 1e-2  # coarse-to-fine only when the start's energy exceeds 1 (isometry) by more than this

#: A coarse level that stops without converging and keeps more than this fraction of its start's energy excess over
#: an isometry is dropped (the fine level polishes from the start): beetle upsampled (78k) cut open along its
#: seams, from Tutte, stalled at the barrier at 25.7 from 26.0 (probably because its coarse triangles, made in the
#: Tutte disk, where the two sides of a seam lie far apart, join points that coincide in 3D), and its prolongation
#: took 92 fine Newton iterations (118 s; 159 s end to end); dropped: 40 from Tutte (57 s; 101 s), to a lower
#: energy (1.000714 vs 1.000723). The start is the layout this level was given (the coarse mesh's energy there),
#: not where its polish began after a coarser level of its own: halftunnel upsampled to 201k from Tutte's layout
#: (energy 23.7 on the 33k level) had its 11k level converge to 1.278 and the 33k level stall at 1.276 from 1.281
#: — a far better start than 23.6, dropped when the gain was measured from 1.281 (stop 20)
COARSE_MIN_GAIN = 0.5
#: A coarse level whose polish stopped because its scaffold could not be built (two boundaries touch after the
#: last step, within round-off) is dropped whatever its energy: halftunnel upsampled to 201k, its map without seams
#: from Tutte, the 10.7k level stopped so at energy 1.357 (from 1275); its prolongation to the 33k level had 197
#: flipped faces that 36 rounds of repair did not fix, 72 s spent before the level was dropped (stop 19).

#: After a converged coarse level the fine polish stops at this multiple of ``refine_tol``: its start is already
#: within ~0.5% of the minimum, and at 1e-6 its last 2 of 7 Newton iterations (camelhead↑182k, ~2.5 s each) gained
#: < 1e-5 of the energy together and no metric to 4 digits (iso mean 2.05884 at 1e-4 and 1e-6; docs/refine.md)
MULTILEVEL_FINE_TOL_FACTOR = 100.0
#: After a coarse level that converged (not one that stalled at the barrier: beetle↑311k's cut map took 8 → 10
#: fine iterations) the fine polish also starts with the scaffold weight that level ended with (``newton.Polish``'s
#: ``scaffold_weight``: the lightest), not the stiffest, which is for boundaries that still move a lot: a converged
#: polish must end at the lightest, so a fine level started stiff spent one more Newton iteration only to lighten
#: it; and it keeps its scaffold while that holds (``newton.Polish``'s ``keep_scaffold``: the Hessian's pattern
#: stays, PARDISO refactorizes without a new analysis; BENCHMARKS.md §19). False: start stiff and re-triangulate at
#: every iteration, as before stop 24.
FINE_SCAFFOLD = True

#: Such a fine level (after a converged coarse level) starts without a scaffold, and builds one only once a step
#: would make boundaries cross (``newton.Polish(scaffold="until crossing")``): no scaffold triangulation, chain of
#: scaffolds or new PARDISO analysis per iteration. Fine polish (2026-12-03, in process, the same iterations and
#: iso mean to 5 digits): demo up 8.7 -> 5.9 s, cylinder_noisy 7.9 -> 6.6 s, cylinder_noisy02 11.0-11.9 ->
#: 8.5-8.7 s (its noisy border never let a scaffold be kept), halftunnel up 9.8 -> 9.0 s, camelhead up 9.9-10.9 vs
#: 10.3-11.1 s (its kept scaffold already held); halftunnel's uncut map (400-vertex threshold) switched at once
#: and ended where the scaffolded polish did (BENCHMARKS §20)
FINE_BARE = True

#: After a coarse level that stalled at the barrier the fine polish starts stiff (``FINE_SCAFFOLD``'s note) but also
#: keeps its scaffold while that holds: beetle upsampled to 311k, its cut map's fine level, the same 5 iterations to
#: 7 digits of energy (1.0025490 → 1.0006873) in 19.5 s instead of ~25 s, each iteration's PARDISO refactorization
#: in place instead of a new analysis for each re-triangulated scaffold (BENCHMARKS §22)
FINE_KEEP_AFTER_STALL = True

#: The levels of a coarse-to-fine polish give up after fewer barrier-limited iterations in a row that gain < tol
#: than a single-level polish (``newton.Polish``'s ``stall_iters``; ``newton.STALL_ITERS`` = 5): a coarse level after
#: ``COARSE_STALL_ITERS``, the fine level polished from one after ``FINE_STALL_ITERS``. There the crawl is slit
#: sides or a boundary pressing against the scaffold's barrier: beetle upsampled to 311k, its cut map's 52k coarse
#: level made 6 such iterations (1.0006576 → 1.0006565) and its fine level 5 after the first cut short (4.6-10 s
#: each, 1.0007033 → 1.0006733; 109 → 66 s end to end with ``PROVISIONAL_FINE``, BENCHMARKS §22). A coarse level
#: keeps one more: its end is prolongated, and stopped right after a cut-short step (2) it gave a fine start of
#: energy 1.00507 instead of 1.00255 (3)
COARSE_STALL_ITERS = 3
FINE_STALL_ITERS = 1

#: A fine level polished from a coarse level that stopped (converged or stalled), its tolerance loosened by
#: ``MULTILEVEL_FINE_TOL_FACTOR``, stops at the first uncut step that gains less than that tolerance, whatever its
#: scaffold's weight (``newton.Polish``'s ``confirm_light`` False), instead of one more iteration at the lightest
#: weight to confirm it. Only a fine level after a stall starts stiff (``FINE_KEEP_AFTER_STALL``) and meets that
#: case: beetle upsampled to 311k, its cut map's fine level, the 4th iteration (uncut, gain 7.5e-5 < 1e-4, weight
#: 0.125) was followed by a 5th at the lightest (~3 s) that gained 1.7e-6, its step cut to 0.06 by the barrier; iso
#: mean 1.018396 after the 4th, 1.018394 after the 5th (BENCHMARKS §24). True: confirm, as before stop 29.
FINE_CONFIRM_LIGHT = False

#: The finest level's Hessian pattern and its symbolic analysis are made on a thread of their own while the coarse
#: levels are polished (``newton.prepare_hessian``; not while the seams stage may pause the polish, which would hold
#: them meanwhile): camelhead upsampled to 182k, BENCHMARKS.md §25
PREPARE_FINE = True

#: While the seams stage decides on paused maps, a coarse level that paused is prolongated and the fine level waits
#: there, unpolished (the provisional map is the prolongation; :class:`Levels`). True: the fine level is polished
#: from it until its own pause, as before stop 27 (beetle upsampled to 311k: 2 fine iterations, 15 s, for a map the
#: seams stage dropped; BENCHMARKS §22)
PROVISIONAL_FINE = False


def coarse_vertices(V: np.ndarray, F: np.ndarray, loops: list[np.ndarray], target: int) -> np.ndarray:
    """About ``target`` surface vertices spread evenly in 3D: every boundary vertex (loop order), then per cell of
    a uniform grid (cell side √(area/target)) the interior vertex nearest the cell centre, skipping cells that hold
    boundary vertices. Deterministic. Returns vertex ids (k,), boundary loops first."""
    bnd = np.concatenate(loops)
    h = float(np.sqrt(face_areas(V, F).sum() / target))
    lo = V.min(axis=0)
    key = np.floor((V - lo) / h).astype(np.int64)
    dims = key.max(axis=0) + 1
    if float(np.prod(dims.astype(np.float64))) < 2.0**62:
        # the cells' lexicographic ranks, as np.unique(key, axis=0)'s inverse, by one int64 key per vertex and a
        # sort (np.unique's row path: 0.44 s at 182k vertices)
        cell = unique_inverse((key[:, 0] * dims[1] + key[:, 1]) * dims[2] + key[:, 2])[2]
    else:
        cell = np.unique(key, axis=0, return_inverse=True)[1].ravel()
    dist = np.linalg.norm(V - (lo + (key + 0.5) * h), axis=1)
    order = np.lexsort((dist, cell))
    first = order[np.r_[True, cell[order][1:] != cell[order][:-1]]]  # nearest the centre, per cell
    blocked = np.zeros(int(cell.max()) + 1, dtype=bool)
    blocked[cell[bnd]] = True
    return np.concatenate([bnd, np.sort(first[~blocked[cell[first]]])]).astype(np.int64)

def coarse_mesh(uv: np.ndarray, loops: list[np.ndarray], ids: np.ndarray) -> np.ndarray:
    """Triangles (c,3) over ``ids`` (boundary loops first, as :func:`coarse_vertices`): the constrained Delaunay
    triangulation of ``uv[ids]`` inside the outer loop and outside the holes (gpytoolbox, no Steiner points),
    counter-clockwise. ``uv`` (n,2) must be bijective, so the coarse faces tile the same region of the plane."""
    P = uv[ids]
    P2, T = triangulate(P, loop_edges(loop_ranges(loops)))
    if len(P2) != len(ids):
        raise ValueError("the coarse triangulation added vertices")
    return make_ccw(P, T)

def prolongate(uv: np.ndarray, uvc0: np.ndarray, T: np.ndarray, uvc: np.ndarray) -> np.ndarray:
    """Carry the coarse result to every fine vertex: locate each point of ``uv`` (n,2) in the coarse triangles T
    laid out at ``uvc0`` (their start positions, the same region) and apply the barycentric combination of the
    polished coarse positions ``uvc``. A piecewise-affine map of a bijective layout, (n,2)."""
    import igl

    _, face, C = igl.point_mesh_squared_distance(uv, uvc0, T)
    a, b, c = (uvc0[T[face, i]] for i in range(3))
    e1, e2, p = b - a, c - a, C - a
    den = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    l1 = (p[:, 0] * e2[:, 1] - p[:, 1] * e2[:, 0]) / den
    l2 = (e1[:, 0] * p[:, 1] - e1[:, 1] * p[:, 0]) / den
    l0 = 1.0 - l1 - l2
    return l0[:, None] * uvc[T[face, 0]] + l1[:, None] * uvc[T[face, 1]] + l2[:, None] * uvc[T[face, 2]]

def repair_flips(x: np.ndarray, ref: np.ndarray, F: np.ndarray, g: np.ndarray, locked: np.ndarray,
                 max_rounds: int = REPAIR_ROUNDS) -> tuple[np.ndarray | None, int, int]:
    """Unflip the few faces a prolongation flips (needle triangles straddling a coarse edge): re-solve the union of
    the flipped faces' ``REPAIR_RINGS``-ring neighbourhoods as mean value (Floater) interpolants with the weights
    of the layout ``ref`` (n,2) (the bijective start: locally an affine image of it is flip-free; weights of the
    3D surface measured worse, camelhead↑45k start energy 1.891 vs 1.877; or ``x`` itself, which those weights
    reproduce wherever its vertex stars are valid: the fallback, start energy 2.88 vs 1.87 at 182k) and the rest
    of ``x`` (n,2) as boundary values; grow the union around what is still flipped, at most ``max_rounds`` times.
    A round whose union did not grow (what is still flipped lies within it, walled in by locked vertices) would
    repeat the last solve exactly: the repair stops there, failed (cylinder_noisy02's start-weight repairs ran 11
    such rounds after the first, twice: 0.41-0.45 → 0.13 s each, the same result; ``BENCHMARKS.md`` §25).
    ``locked`` (n,) bool: vertices never moved.
    Returns (layout or None when flips remain, faces flipped at first, rounds)."""
    n = len(x)
    flipped = det(jacobians(x, F, g)) <= 0
    bad = np.flatnonzero(flipped)
    first = len(bad)
    if first == 0:
        return x, 0, 0
    import igl

    adj = igl.adjacency_matrix(F)  # the mesh's edges, as untangle_flips walks them
    if adj.shape[0] < n:  # vertices past the last one F uses: no neighbours
        adj.resize((n, n))
    y, region, size = x.copy(), np.zeros(n, dtype=bool), -1
    for r in range(1, max_rounds + 1):
        grow = np.zeros(n, dtype=bool)
        grow[F[bad].ravel()] = True
        region |= grow_rings(grow, adj, REPAIR_RINGS)
        free = region & ~locked
        if (k := int(free.sum())) == size:  # the same free vertices as the last round: the same solve and flips
            return None, first, r - 1
        size = k
        fi, fx = np.flatnonzero(free), np.flatnonzero(~free)
        # only the faces at a free vertex: their rows of the mean value Laplacian are whole (a free vertex's faces
        # are all among them), and only their Jacobians change (the region only grows, so every vertex moved so
        # far is free); the full mesh's, at every round, were 2.9 of cylinder_noisy02's 3.3 s of repair
        near = free[F].any(axis=1)
        Lf = mean_value_laplacian(ref, F[near])[fi]
        y[fi] = spla.splu(Lf[:, fi].tocsc()).solve(-(Lf[:, fx] @ x[fx]))
        now = flipped.copy()
        now[near] = det(jacobians(y, F[near], g[near])) <= 0
        bad = np.flatnonzero(now)
        if len(bad) == 0:
            return y, first, r
    return None, first, max_rounds


def grow_rings(mask: np.ndarray, adj: sp.spmatrix, rings: int) -> np.ndarray:
    """``mask`` (n,) bool grown by ``rings`` rings of the vertex adjacency ``adj`` (n,n), a new array."""
    for _ in range(rings):
        mask = mask | (adj @ mask.astype(np.int32) > 0)
    return mask

def untangle_flips(y: np.ndarray, V: np.ndarray, F: np.ndarray, g: np.ndarray, locked: np.ndarray
                   ) -> tuple[np.ndarray | None, int]:
    """:func:`heatparam.refine.untangle.untangle` of the flipped faces' ``REPAIR_RINGS``-ring neighbourhood of the
    layout ``y`` (n,2) (``locked`` (n,) bool vertices held), grown by ``REPAIR_RINGS`` rings while flips remain,
    at most 3 times. Returns (layout or None, minimizations run)."""
    import igl

    area = face_areas(V, F)
    bad = det(jacobians(y, F, g)) <= 0
    adj = igl.adjacency_matrix(F)
    region = np.zeros(len(y), dtype=bool)
    region[F[bad].ravel()] = True
    total = 0
    for _ in range(3):
        region = grow_rings(region, adj, REPAIR_RINGS)
        z, r = untangle(y, F, g, area, region & ~locked)
        total += r
        if z is not None:
            return z, total
    return None, total

def boundary_faces(F: np.ndarray, boundary: np.ndarray) -> np.ndarray:
    """The triangles of F (m,3) whose three corners are all boundary vertices (``boundary`` (n,) bool), (k,3)."""
    return F[boundary[F].all(axis=1)]

def coarse_to_fine(V: np.ndarray, F: np.ndarray, x: np.ndarray, loops: list[np.ndarray], g: np.ndarray,
                   *, min_vertices: int, max_iters: int, tol: float, backend: str, progress=None,
                   guards: np.ndarray | None = None, pause_excess: float = 0.0, pause_coarse: float = 0.0,
                   level: bool = False
                   ) -> tuple[np.ndarray | None, dict, Callable[[], tuple[np.ndarray | None, dict]] | None]:
    """A start for the fine polish from a coarse one: :func:`coarse_vertices` and :func:`coarse_mesh` in the
    bijective layout ``x`` (n,2), :func:`multilevel_polish` of the coarse mesh from ``x`` (itself coarse-to-fine
    while a level has >= ``min_vertices`` vertices), :func:`prolongate`, :func:`repair_flips`.

    Every level keeps all boundary vertices, which the repair never moves; so a triangle whose three corners are
    boundary vertices (a corner "ear" of the scan; plenty in the coarse levels' own triangulations) could come out
    of the coarse polish flipped, beyond repair, unless the coarse polish keeps it positive: such triangles of this
    level (and its own ``guards`` (k,3)) are passed down as guards, triangles without energy that the line search
    keeps positive.

    ``pause_excess`` > 0 and ``pause_coarse`` > 0: the coarse polish may pause as :class:`newton.Polish` does, and
    while its map's iso mean (``metrics.distortion``) exceeds ``pause_coarse`` its layout is prolongated there (a
    provisional start; otherwise it is finished at once); the third value then finishes the coarse polish and
    prolongates again, giving what an unpaused call returns. Returns (layout (n,2) or None when no bijective one
    came out, report, that finisher or None when no coarse polish is left paused).
    """
    t0 = time.perf_counter()
    n = len(V)
    target = int(max(COARSE_FRACTION * n, COARSE_MIN))
    ids = coarse_vertices(V, F, loops, target)
    nb = sum(len(lp) for lp in loops)
    info: dict = {"coarse_vertices": int(len(ids)), "boundary_vertices": int(nb)}
    if nb > target // 2:
        return None, info | {"used": False, "reason": "the boundary alone has more than half the coarse vertices"}, None
    if len(ids) >= n:
        return None, info | {"used": False, "reason": "the coarse mesh would not be coarser"}, None
    try:
        T = coarse_mesh(x, loops, ids)
    except ValueError as exc:
        return None, info | {"used": False, "reason": str(exc)}, None
    gc, ac = surface_gradients(V[ids], T)
    e0 = normalized_energy(x[ids], T, gc, ac)  # this level's start, before any coarser level of its own
    cloops = loop_ranges(loops)  # the coarse mesh's boundary loops: its first vertices, in loop order
    locked = np.zeros(n, dtype=bool)
    locked[ids[:nb]] = True  # the boundary is the coarse one: polished, bijective, kept as is
    local = np.full(n, -1, dtype=np.int64)
    local[ids] = np.arange(len(ids))
    ears = boundary_faces(F if guards is None else np.vstack([F, guards]), locked)
    level_min = min(min_vertices, LEVEL_MULTILEVEL_MIN) if LEVEL_MULTILEVEL_MIN else min_vertices
    crun, cml = multilevel_polish(V[ids], T, x[ids], cloops, gc, ac, min_vertices=level_min,
                                  max_iters=max_iters, tol=tol, backend=backend, progress=progress,
                                  guards=local[ears], label=f"coarse, {len(ids)} vertices",
                                  pause_excess=pause_excess if pause_coarse > 0 else 0.0, pause_coarse=pause_coarse,
                                  level=True)
    info["guards"] = int(len(ears))

    def coarse_iso() -> float:
        """This level's map's iso mean (paused: where it paused), which the seams stage's noise bound reads."""
        return float(metrics.distortion(V[ids], T, crun.x)["iso_mean"])

    def prolongated(paused: bool, idle: float = 0.0, iso: float | None = None) -> tuple[np.ndarray | None, dict]:
        """``idle``: seconds this level waited paused (other work), left out of its ``seconds``; ``iso``: the
        coarse map's iso mean when already measured."""
        seconds = round(time.perf_counter() - t0 - idle, 3)
        xc, cinfo = crun.x, crun.report()
        out = info | {"coarse_polish": cinfo, "coarse_multilevel": cml,
                      "coarse_iso_mean": coarse_iso() if iso is None else iso}
        e1 = cinfo["energy_end"]
        if cinfo["stop"].startswith("scaffold failed"):  # module constant COARSE_MIN_GAIN's note
            return None, out | {"used": False, "seconds": seconds,
                                "reason": ("the coarse polish stopped where its boundaries touch (its scaffold "
                                           "failed): its prolongation would fold between them")}
        if not paused and not cinfo["converged"] and e1 - 1.0 > COARSE_MIN_GAIN * (e0 - 1.0):
            return None, out | {"used": False, "seconds": seconds,
                                "reason": (f"the coarse polish stopped ({cinfo['stop']}) at energy {e1:.4g} from "
                                           f"{e0:.4g}: its prolongation would be a poor start")}
        y = prolongate(x, x[ids], T, xc)
        y[ids] = xc
        # the start's weights fail where the start is far from an affine image of the result (LSCM's scale varies a
        # lot across a repair region: camelhead↑727k's 111k-vertex level, 4 flips grew to 443); weights of the
        # prolongated layout itself keep it wherever its stars are valid, and unfold the rest (1 round). A coarse
        # level tries those first (PROLONGATED_FIRST)
        weights = [("start layout", x), ("prolongated layout", y)]
        if level and PROLONGATED_FIRST:
            weights.reverse()
        z, flipped, rounds = None, 0, 0
        for k, (name, ref) in enumerate(weights):
            z, f, rounds = repair_flips(y, ref, F, g, locked)
            flipped = f if k == 0 else flipped  # the prolongation's flips: what the first repair found
            out["repair_weights"] = name
            if z is not None:
                break
        if z is None:
            # flips beside a locked non-convex boundary, where mean value interpolation cannot help (a 50k-vertex
            # halftunnel from Tutte: 18 left after 12 rounds of both): untangle their neighbourhoods
            z, rounds = untangle_flips(y, V, F, g, locked)
            out["repair_weights"] = "untangled (Garanzha et al. 2021)"
        y = z
        out.update(prolongation_flips=flipped, repair_rounds=rounds,
                   seconds=round(time.perf_counter() - t0 - idle, 3))
        if y is None:
            return None, out | {"used": False, "reason": f"{flipped} prolongated faces still flipped after repair"}
        if metrics.boundary_crossings(y, F):  # cannot happen with the coarse boundary kept; checked, not assumed
            return None, out | {"used": False, "reason": "the prolongated boundary crosses itself"}
        return y, out | {"used": True}

    def finish(paused_at: float | None = None) -> tuple[np.ndarray | None, dict]:
        idle = 0.0 if paused_at is None else time.perf_counter() - paused_at
        run_polish(crun, progress, f"coarse, {len(ids)} vertices")
        return prolongated(False, idle)

    if crun.done:
        return *prolongated(False), None
    iso = coarse_iso()
    if not iso > pause_coarse:
        return *finish(), None
    y, ml = prolongated(True, iso=iso)
    if y is None:  # no provisional start from the paused level: finish it now, as without pausing
        return *finish(), None
    paused_at = time.perf_counter()
    return y, ml, lambda: finish(paused_at)


def multilevel_polish(V: np.ndarray, F: np.ndarray, x: np.ndarray, loops: list[np.ndarray], g: np.ndarray,
                      area: np.ndarray, *, min_vertices: int, max_iters: int, tol: float, backend: str,
                      progress=None, guards: np.ndarray | None = None, label: str = "Newton",
                      pause_excess: float = 0.0, pause_coarse: float = 0.0, level: bool = False, park: bool = True
                      ) -> tuple[Polish | Levels, dict]:
    """:func:`polish` of (V (n,3), F (m,3)) from the bijective layout ``x`` (n,2); coarse-to-fine
    (:func:`coarse_to_fine`) when the mesh has >= ``min_vertices`` (> 0) vertices and ``x`` is more than
    ``MULTILEVEL_MIN_EXCESS`` above an isometry. After a converged coarse level the polish stops at
    ``MULTILEVEL_FINE_TOL_FACTOR`` × ``tol``. ``pause_excess`` > 0: the fine polish pauses once an iteration gains
    less than that fraction of the energy's excess (:class:`newton.Polish`; :func:`run_polish` goes on), and with
    ``pause_coarse`` > 0 so may the coarse levels while their maps' iso mean exceeds it (:func:`coarse_to_fine`,
    :class:`Levels`). ``level``: this mesh is a coarse level of another (its polish stops after
    ``COARSE_STALL_ITERS`` barrier-limited iterations, a fine level polished from a coarse one after
    ``FINE_STALL_ITERS``); ``park``:
    :class:`newton.Polish`'s (False: a pause keeps the factorization).
    Returns (the fine level's :class:`newton.Polish` or :class:`Levels`: its layout ``x`` (n,2) and ``report()``,
    coarse-to-fine report; the report is updated in place when a paused coarse level is finished)."""
    y, finish, prepared = None, None, None
    if not 0 < min_vertices <= len(V):
        ml: dict = {"used": False, "reason": "small mesh"}
    elif not normalized_energy(x, F, g, area) > 1.0 + MULTILEVEL_MIN_EXCESS:
        ml = {"used": False, "reason": "the start is already within 1% of an isometry"}
    else:
        if PREPARE_FINE and not level and pause_excess == 0:  # the fine level's Hessian analysed meanwhile
            prepared = prepare_hessian(F, len(V), backend)
        try:
            y, ml, finish = coarse_to_fine(V, F, x, loops, g, min_vertices=min_vertices, max_iters=max_iters,
                                           tol=tol, backend=backend, progress=progress, guards=guards,
                                           pause_excess=pause_excess, pause_coarse=pause_coarse, level=level)
        except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:  # only a faster start: never fatal
            ml = {"used": False, "reason": f"coarse level failed: {exc}"}

    def fine(y: np.ndarray | None) -> Polish:
        nonlocal prepared
        ready, prepared = prepared, None  # for one polish only
        ftol, weight, keep, bare = tol, 1.0, False, False
        if y is not None:
            cp = ml["coarse_polish"]
            converged, stalled = cp["converged"], cp["stop"] == "stalled at the barrier"
            if converged or stalled:
                ftol *= MULTILEVEL_FINE_TOL_FACTOR
            if converged and FINE_SCAFFOLD:
                # the boundary is where the coarse polish left it: no stiff scaffold to relax first, and little
                # for a new scaffold to follow (not after a stall at the barrier: boundaries there still push)
                weight, keep, bare = ml["coarse_polish"]["scaffold_weight"], True, FINE_BARE
            elif stalled and FINE_KEEP_AFTER_STALL:
                keep = True  # stiff, but the scaffold is kept while it holds
            ml["fine_tol"] = ftol
        # open-ended: Newton stops when converged (5-50 iterations measured), far below the cap
        return Polish(x if y is None else y, F, g, area, loops, max_iters=max_iters, tol=ftol, backend=backend,
                      guards=guards, scaffold_weight=weight, keep_scaffold=keep,
                      scaffold="until crossing" if bare else True,
                      stall_iters=COARSE_STALL_ITERS if level else FINE_STALL_ITERS if y is not None else STALL_ITERS,
                      park=park, confirm_light=FINE_CONFIRM_LIGHT or level or ftol == tol, prepared=ready)

    run: Polish | Levels = fine(y)
    if finish is not None:
        def finished(provisional: Polish) -> Polish:
            """The fine polish after the coarse level finished and prolongated again; the report updated in place."""
            y, again = finish()
            counts = {"coarse_iterations": ml["coarse_polish"]["iterations"], "fine_iterations": provisional.it}
            ml.clear()
            ml.update(again, provisional=counts)
            return fine(y)

        run = Levels(run, finished)
    run_polish(run, progress, label, pause_excess)
    return run, ml


class Levels:
    """A fine polish started from a coarse level that paused (:func:`multilevel_polish` with ``pause_excess`` and
    ``pause_coarse``), with :class:`newton.Polish`'s interface (``x``, ``done``, ``run``, ``report``, ``bar``).

    While pauses are asked for, the provisional map is the paused coarse level's prolongation, which the seams stage
    reads (``PROVISIONAL_FINE`` True: the fine polish goes on from there until its own pause). Finishing (``run()``
    without a pause) first finishes the coarse level, prolongates its end again and polishes the fine level from
    there: the very layout of a multilevel polish that never paused (any provisional fine iterations are dropped;
    the report's ``multilevel.provisional`` counts them). ``fine`` is the current fine :class:`newton.Polish`."""

    def __init__(self, fine: Polish, finished: Callable[[Polish], Polish]):
        self.fine, self._finished, self.bar = fine, finished, None

    @property
    def x(self) -> np.ndarray:
        return self.fine.x

    @property
    def done(self) -> bool:
        return self._finished is None and self.fine.done

    def run(self, pause_excess: float = 0.0) -> bool:
        if self._finished is not None:
            if pause_excess <= 0.0:
                self.fine, self._finished = self._finished(self.fine), None
            elif self.fine.done or not PROVISIONAL_FINE:  # the provisional polish has stopped, or waits
                return False
        self.fine.bar = self.bar
        try:
            self.fine.run(pause_excess)
        finally:
            self.fine.bar = None
        return self.done

    def report(self) -> dict:
        rep = self.fine.report()
        if self._finished is not None:
            rep["stop"] = "paused"
        return rep


def run_polish(run: Polish, progress=None, label: str = "Newton", pause_excess: float = 0.0) -> bool:
    """``run.run(pause_excess)`` under a progress bar (``progress``: a ``progress.Progress`` or None); True when
    the polish has stopped, False when it paused."""
    bar = progress.bar(None, f"polish ({label})") if progress is not None else None
    run.bar = bar
    try:
        return run.run(pause_excess)
    finally:
        run.bar = None
        if bar is not None:
            bar.close()
