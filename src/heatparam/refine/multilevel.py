"""Coarse-to-fine polish: polish a coarse mesh, prolongate, repair the few flips, polish the fine mesh from there.

A mesh of at least ``LevelSettings.min_vertices`` vertices whose start is not already near an isometry gets a
:class:`CoarseLevel`: about an eighth of its vertices (every boundary vertex kept) triangulated in the bijective
start layout, polished (itself coarse-to-fine while large), prolongated piecewise-affinely to every fine vertex and
repaired where the prolongation flips a needle triangle. The fine polish then starts there with the scaffold its
coarse level ended with, a loosened tolerance and fewer stalls allowed (:meth:`Multilevel.fine_settings`). While
the seams stage compares maps, a coarse level may pause; its prolongation is then the provisional map
(:class:`Levels`), and finishing gives the very map of a polish that never paused.

At the finest level of a mesh large enough for levels the polish also stops once an iteration gains less than
``newton.EXCESS_TOL`` of the energy's excess over its coarse level's final energy (over an isometry where no coarse
level gave the start): what the fine level adds to it is mostly a scan's noise, and the last iterations refine a map
already within a few percent of that excess of its minimum; a smooth surface's fine minimum lies near its coarse
level's, so there the rule is hardly looser than the tolerance (camelhead↑45k, energy 1.857: over an isometry it
stopped after 1 of 5 fine iterations, iso mean +0.2%). On gains made only: a prolongated start's first gains are the
flip barrier's (held-out 1013: 1e6 in its first fine iteration), and a next gain predicted from them stopped that
polish 0.0035 above its minimum, iso mean +1%.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from heatparam import metrics
from heatparam.layout.tutte import mean_value_laplacian
from heatparam.mesh.planar import make_ccw, triangulate
from heatparam.mesh.topology import face_areas, unique_inverse
from heatparam.refine.energy import det, jacobians, normalized_energy, surface_gradients
from heatparam.refine.newton import (
    EXCESS_TOL,
    STALL_ITERS,
    Polish,
    PolishSettings,
    ScaffoldUse,
    Stop,
    prepare_hessian,
)
from heatparam.refine.scaffold import loop_edges, loop_ranges
from heatparam.refine.smoother import Smoother
from heatparam.refine.untangle import untangle

#: Each coarser level has about this fraction of the vertices, but at least ``COARSE_MIN`` (at 1/27 the repair of
#: camelhead↑727k's prolongation failed, at 1/6.5 it needed 7 rounds)
COARSE_FRACTION = 1 / 8
COARSE_MIN = 8_000

#: A coarse level of at least this many vertices gets a coarser level of its own (camelhead↑182k's 27.6k level:
#: 15 → 5 Newton iterations; docs/history.md §24)
LEVEL_MULTILEVEL_MIN = 20_000

REPAIR_RINGS = 8  # each repair round re-solves the flipped faces' 8-ring neighbourhoods ...
REPAIR_ROUNDS = 12  # ... at most this many rounds

MULTILEVEL_MIN_EXCESS = 1e-2  # coarse-to-fine only when the start's energy exceeds 1 (isometry) by more than this

#: A coarse level that stops without converging and keeps more than this fraction of its start's energy excess is
#: dropped: its prolongation would be a poorer start than the one it was given (beetle↑78k cut open, from Tutte)
COARSE_MIN_GAIN = 0.5

#: After a converged or stalled coarse level the fine polish stops at this multiple of ``tol``: its start is within
#: ~0.5% of the minimum, and the last iterations at 1e-6 changed no metric to 4 digits (docs/refine.md). So does the
#: polish of a start within ``MULTILEVEL_MIN_EXCESS`` of an isometry, hence of its minimum (a range image's
#: projection at energy 1.0001: 8 fine iterations of 1.7 s where its Tutte start's levels needed 2)
MULTILEVEL_FINE_TOL_FACTOR = 100.0

#: Barrier-limited iterations in a row (gaining < tol) before a coarse level, or a fine level polished from one,
#: gives up (``newton.STALL_ITERS`` for a single level): there the crawl is slit sides pressing against the
#: barrier; a coarse level keeps one more, its end being prolongated (beetle↑311k; BENCHMARKS.md §22)
COARSE_STALL_ITERS = 3
FINE_STALL_ITERS = 1


@dataclass(frozen=True)
class LevelSettings:
    """How :func:`multilevel_polish` polishes one mesh.

    min_vertices : coarse-to-fine from this many vertices (0: never). max_iters, tol, backend : the polish's
    (:class:`newton.PolishSettings`). pause_excess : > 0: the fine polish pauses once an iteration gains less than
    this fraction of the energy's excess over an isometry (the seams stage decides on paused maps). pause_coarse :
    > 0 (with ``pause_excess``): the coarse levels may pause too while their map's iso mean exceeds it. park :
    ``PolishSettings.park`` of the fine polish. coarse : this mesh is a coarse level of another (its own stop rules).
    pause_fine_start : pause before the fine polish's first iteration when a coarse level gave its start.
    smooth : the finest level's start from a prolongation is smoothed first (``refine.smoother``).
    """

    min_vertices: int
    max_iters: int = 200
    tol: float = 1e-6
    backend: str = "auto"
    pause_excess: float = 0.0
    pause_coarse: float = 0.0
    park: bool = True
    coarse: bool = False
    pause_fine_start: bool = False
    smooth: bool = True

    def for_coarse_level(self) -> LevelSettings:
        """The settings of this mesh's coarse level."""
        return replace(self, min_vertices=min(self.min_vertices, LEVEL_MULTILEVEL_MIN), park=True, coarse=True,
                       pause_excess=self.pause_excess if self.pause_coarse > 0 else 0.0, pause_fine_start=False)


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
    repeat the last solve exactly: the repair stops there, failed.
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


def ears(F: np.ndarray, boundary: np.ndarray) -> np.ndarray:
    """The rows (k,) of F (m,3) whose three corners are all boundary vertices (``boundary`` (n,) bool)."""
    return np.flatnonzero(boundary[F].all(axis=1))


class CoarseLevel:
    """The coarse level of a mesh (V (n,3), F (m,3)) laid out bijectively at ``x`` (n,2): :meth:`build` it,
    :meth:`polish` it, :meth:`prolongate` its map to every vertex of the mesh, :meth:`finish` it after a pause;
    :meth:`start` does all four as the fine polish needs.

    Every level keeps all boundary vertices, which the repair never moves; so a fine triangle whose three corners
    are boundary vertices (an ear: a border sliver, a seam's turn) is carried by no coarse triangle and could come
    out of the coarse polish flipped beyond repair, or squeezed to nothing. Such ears join the coarse mesh's energy
    with their own rest shape and area (:meth:`polish`), so the coarse polish keeps them positive as it keeps its
    own triangles, and a coarser level of its own takes them, and its own ears, along.
    ``report`` is this level's part of the report."""

    def __init__(self, V: np.ndarray, F: np.ndarray, x: np.ndarray, loops: list[np.ndarray], g: np.ndarray,
                 area: np.ndarray, settings: LevelSettings, *, progress=None):
        self.t0 = time.perf_counter()
        self.V, self.F, self.x, self.loops, self.g, self.area = V, F, x, loops, g, area
        self.settings, self.progress = settings, progress
        self.report: dict = {}
        self.run: Polish | Levels | None = None
        self.paused_at: float | None = None

    @property
    def paused(self) -> bool:
        """Whether the coarse polish was left paused (its prolongation the provisional start)."""
        return self.paused_at is not None

    def build(self) -> str | None:
        """The coarse vertices (:func:`coarse_vertices`) and their triangulation in ``x`` (:func:`coarse_mesh`);
        why there is no coarse level, or None."""
        n, loops = len(self.V), self.loops
        target = int(max(COARSE_FRACTION * n, COARSE_MIN))
        self.ids = coarse_vertices(self.V, self.F, loops, target)
        nb = sum(len(lp) for lp in loops)
        self.report.update(coarse_vertices=int(len(self.ids)), boundary_vertices=int(nb))
        if nb > target // 2:
            return "the boundary alone has more than half the coarse vertices"
        if len(self.ids) >= n:
            return "the coarse mesh would not be coarser"
        try:
            self.T = coarse_mesh(self.x, loops, self.ids)
        except ValueError as exc:
            return str(exc)
        self.locked = np.zeros(n, dtype=bool)
        self.locked[self.ids[:nb]] = True  # the boundary is the coarse one: polished, bijective, kept as is
        return None

    def polish(self) -> None:
        """Polish the coarse mesh from ``x`` (coarse-to-fine itself when large; it may pause as the settings say).

        Its energy is that of the coarse triangles and of the ears (class docstring), each ear with the mesh's own
        hat gradients and area, so that it is as positive as in ``x`` (a zero-area ear that a projection keeps
        flat: its det J is positive by round-off only). Ears without energy, only kept positive by the line search,
        stalled the coarse level of a cut mesh: a Newton direction that does not see an ear pushes it to collapse
        at every iteration and the barrier cuts each step to a tenth of the last (tuning seed 16 of
        ``bench/large_family.py``: stalled at iso mean 1.1746 where it reaches 1.0127)."""
        ids = self.ids
        local = np.full(len(self.V), -1, dtype=np.int64)
        local[ids] = np.arange(len(ids))
        rows = ears(self.F, self.locked)
        T = np.vstack([self.T, local[self.F[rows]]])
        gc, ac = surface_gradients(self.V[ids], self.T)
        gc, ac = np.concatenate([gc, self.g[rows]]), np.concatenate([ac, self.area[rows]])
        self.e0 = normalized_energy(self.x[ids], T, gc, ac)  # this level's start, before a coarser level of its own
        self.run, self.multilevel = multilevel_polish(
            self.V[ids], T, self.x[ids], loop_ranges(self.loops), gc, ac, self.settings.for_coarse_level(),
            progress=self.progress, label=self.label)
        self.report["ears"] = int(len(rows))

    @property
    def label(self) -> str:
        return f"coarse, {len(self.ids)} vertices"

    def iso_mean(self) -> float:
        """The coarse map's iso mean (paused: where it paused), which the seams stage's noise bound reads."""
        return float(metrics.distortion(self.V[self.ids], self.T, self.run.x)["iso_mean"])

    def start(self) -> tuple[np.ndarray | None, dict]:
        """Build, polish and prolongate: (the fine polish's start (n,2) or None when no bijective one came out,
        the report). With ``pause_coarse`` the coarse polish may be left paused while its iso mean exceeds it:
        the start is then its prolongation, provisional (:attr:`paused`; :meth:`finish` completes it)."""
        reason = self.build()
        if reason is not None:
            return None, self.report | {"used": False, "reason": reason}
        self.polish()
        if self.run.done:
            return self.prolongate(paused=False)
        iso = self.iso_mean()
        if not iso > self.settings.pause_coarse:
            return self.finish()
        y, rep = self.prolongate(paused=True, iso=iso)
        if y is None:  # no provisional start from the paused level: finish it now, as without pausing
            return self.finish()
        self.paused_at = time.perf_counter()
        return y, rep

    def finish(self) -> tuple[np.ndarray | None, dict]:
        """Finish the coarse polish (paused or not) and prolongate its end; its time paused is left out."""
        idle = 0.0 if self.paused_at is None else time.perf_counter() - self.paused_at
        self.paused_at = None
        run_polish(self.run, self.progress, self.label)
        return self.prolongate(paused=False, idle=idle)

    def prolongate(self, *, paused: bool, idle: float = 0.0, iso: float | None = None) -> tuple[np.ndarray | None,
                                                                                              dict]:
        """The coarse map carried to every vertex (:func:`prolongate`) and repaired (:meth:`repaired`), or None
        when the coarse level is not worth it; with the report. ``idle``: seconds the level waited paused;
        ``iso``: the coarse map's iso mean when already measured."""
        seconds = round(time.perf_counter() - self.t0 - idle, 3)
        xc, cinfo = self.run.x, self.run.report()
        out = self.report | {"coarse_polish": cinfo, "coarse_multilevel": self.multilevel,
                             "coarse_iso_mean": self.iso_mean() if iso is None else iso}
        e1 = cinfo["energy_end"]
        if self.run.done and self.run.stop is Stop.SCAFFOLD_FAILED:
            # its boundaries touch: the prolongation would fold between them
            return None, out | {"used": False, "seconds": seconds,
                                "reason": ("the coarse polish stopped where its boundaries touch (its scaffold "
                                           "failed): its prolongation would fold between them")}
        if not paused and not cinfo["converged"] and e1 - 1.0 > COARSE_MIN_GAIN * (self.e0 - 1.0):
            return None, out | {"used": False, "seconds": seconds, "stalled": True,
                                "reason": (f"the coarse polish stopped ({cinfo['stop']}) at energy {e1:.4g} from "
                                           f"{self.e0:.4g}: its prolongation would be a poor start")}
        y = prolongate(self.x, self.x[self.ids], self.T, xc)
        y[self.ids] = xc
        y = self.repaired(y, out)
        out["seconds"] = round(time.perf_counter() - self.t0 - idle, 3)
        if y is None:
            return None, out | {"used": False,
                                "reason": f"{out['prolongation_flips']} prolongated faces still flipped after repair"}
        if metrics.boundary_crossings(y, self.F):  # cannot happen with the coarse boundary kept; checked, not assumed
            return None, out | {"used": False, "reason": "the prolongated boundary crosses itself"}
        return y, out | {"used": True}

    def repaired(self, y: np.ndarray, out: dict) -> np.ndarray | None:
        """The prolongation ``y`` (n,2) without flips (:func:`repair_flips`, else :func:`untangle_flips`), or None;
        what was done goes into ``out``.

        The start's weights fail where the start is far from an affine image of the result (LSCM's scale varies a
        lot across a repair region); the prolongated layout's own weights keep it wherever its stars are valid and
        unfold the rest. The finest level tries the start's first, a coarse level the prolongated layout's
        (camelhead↑182k's 27.6k level: 12 failed rounds → 1; docs/history.md §25)."""
        weights = [("start layout", self.x), ("prolongated layout", y)]
        if self.settings.coarse:
            weights.reverse()
        z, flipped, rounds = None, 0, 0
        for k, (name, ref) in enumerate(weights):
            z, f, rounds = repair_flips(y, ref, self.F, self.g, self.locked)
            flipped = f if k == 0 else flipped  # the prolongation's flips: what the first repair found
            out["repair_weights"] = name
            if z is not None:
                break
        if z is None:
            # flips beside a locked non-convex boundary, where mean value interpolation cannot help: untangle them
            z, rounds = untangle_flips(y, self.V, self.F, self.g, self.locked)
            out["repair_weights"] = "untangled (Garanzha et al. 2021)"
        out.update(prolongation_flips=flipped, repair_rounds=rounds)
        return z


class Multilevel:
    """:func:`multilevel_polish` of (V (n,3), F (m,3)) from the bijective layout ``x`` (n,2): :meth:`coarse_start`
    (a :class:`CoarseLevel`, when it can help), :meth:`fine_polish` from there, and :meth:`refined` to finish a
    coarse level that paused. ``report`` is the report's ``multilevel`` part, updated in place.

    restart : () -> (another bijective start (n,2) or None, its report), asked for once, when the coarse level
        stalled far from its minimum (``COARSE_MIN_GAIN``): such a start is squeezed where a repair made its
        flipped faces barely positive, and the fine polish from it crawls too (a noisy CAD part's repaired
        conformal layout: 28 fine iterations). The levels then start again from the other start if its energy is
        lower."""

    def __init__(self, V: np.ndarray, F: np.ndarray, x: np.ndarray, loops: list[np.ndarray], g: np.ndarray,
                 area: np.ndarray, settings: LevelSettings, *, progress=None,
                 restart: Callable[[], tuple[np.ndarray | None, dict]] | None = None):
        self.V, self.F, self.x, self.loops, self.g, self.area = V, F, x, loops, g, area
        self.settings, self.progress, self.restart = settings, progress, restart
        self.coarse: CoarseLevel | None = None
        self.near_isometric = False  # the start is within MULTILEVEL_MIN_EXCESS of an isometry
        self.prepared = None
        self.report: dict = {}

    @property
    def large(self) -> bool:
        """Whether the mesh is large enough for coarse levels (``LevelSettings.min_vertices``)."""
        return 0 < self.settings.min_vertices <= len(self.V)

    def coarse_start(self) -> np.ndarray | None:
        """The fine polish's start from a coarse level, or None (the report says why)."""
        s = self.settings
        if not self.large:
            self.report.update(used=False, reason="small mesh")
            return None
        if not normalized_energy(self.x, self.F, self.g, self.area) > 1.0 + MULTILEVEL_MIN_EXCESS:
            self.report.update(used=False, reason="the start is already within 1% of an isometry")
            self.near_isometric = True
            return None
        if not s.coarse and s.pause_excess == 0:  # the fine level's Hessian analysed meanwhile, on a thread
            self.prepared = prepare_hessian(self.F, len(self.V), s.backend)
        y = self._level(s)
        return self._restarted(s) if y is None else y

    def _level(self, settings: LevelSettings) -> np.ndarray | None:
        """A coarse level of ``x`` started (:meth:`CoarseLevel.start`): the fine start, or None; reported."""
        self.coarse = CoarseLevel(self.V, self.F, self.x, self.loops, self.g, self.area, settings,
                                  progress=self.progress)
        try:
            y, rep = self.coarse.start()
        except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:  # only a faster start: never fatal
            self.coarse, y, rep = None, None, {"used": False, "reason": f"coarse level failed: {exc}"}
        self.report.update(rep)
        return y

    def _restarted(self, settings: LevelSettings) -> np.ndarray | None:
        """After a coarse level that stalled far from its minimum: the levels from ``restart``'s start, once (the
        fine start or None; ``x`` becomes that start when there is one). The report keeps the dropped level's
        reason and seconds under ``restart``."""
        if self.restart is None or not self.report.get("stalled"):
            return None
        x, rep = self.restart()
        self.restart = None
        rep = {"dropped": self.report["reason"], "dropped_seconds": self.report.get("seconds")} | rep
        if x is not None:
            rep["energy"] = normalized_energy(x, self.F, self.g, self.area)
            rep["start_energy"] = normalized_energy(self.x, self.F, self.g, self.area)
        if x is None or not rep["energy"] < rep["start_energy"]:  # a start as good as this one stalls as well
            self.report["restart"] = rep | {"used": False}
            return None
        self.x = x
        kept = {k: self.report[k] for k in ("provisional",) if k in self.report}  # iterations before a pause
        self.report.clear()
        y = self._level(settings)
        self.report.update(kept, restart=rep | {"used": True})
        return y

    def fine_settings(self, y: np.ndarray | None) -> PolishSettings:
        """The fine polish's settings. From a coarse level that converged, the boundary is where that level left
        it: the scaffold starts at the weight it ended with, is kept while it holds, and is taken only once a step
        would make boundaries cross (docs/history.md §20); after one that stalled at the barrier the scaffold starts
        stiff (boundaries there still push) but is kept while it holds. Either way the tolerance is loosened
        (``MULTILEVEL_FINE_TOL_FACTOR``) and the first small uncut step stops the polish; so it is for a start within
        ``MULTILEVEL_MIN_EXCESS`` of an isometry, which needs no coarse level."""
        s = self.settings
        tol, weight, keep, use, excess, base = s.tol, 1.0, False, ScaffoldUse.ALWAYS, 0.0, 1.0
        if y is None and self.near_isometric and not s.coarse:  # within 1% of an isometry, hence of the minimum
            tol *= MULTILEVEL_FINE_TOL_FACTOR
            self.report["fine_tol"] = tol
        if self.large and not s.coarse:  # a large mesh's finest level: module docstring
            excess = EXCESS_TOL
        if y is not None:
            run, cp = self.coarse.run, self.report["coarse_polish"]
            base = cp["energy_end"]
            converged, stalled = cp["converged"], run.done and run.stop is Stop.STALLED
            if converged or stalled:
                tol *= MULTILEVEL_FINE_TOL_FACTOR
            if converged:
                weight, keep, use = cp["scaffold_weight"], True, ScaffoldUse.UNTIL_CROSSING
            elif stalled:
                keep = True
            self.report["fine_tol"] = tol
        stall = COARSE_STALL_ITERS if s.coarse else FINE_STALL_ITERS if y is not None else STALL_ITERS
        return PolishSettings(max_iters=s.max_iters, tol=tol, backend=s.backend, excess_tol=excess, excess_base=base,
                              excess_predict=False, stall_iters=stall,
                              confirm_light=s.coarse or tol == s.tol, park=s.park, scaffold=use,
                              scaffold_weight=weight, keep_scaffold=keep)

    def fine_polish(self, y: np.ndarray | None) -> Polish:
        """The fine polish from ``y`` (None: from ``x``), not yet run; the prepared Hessian serves it only. A coarse
        level's prolongation ``y`` is smoothed first at the finest level (``refine.smoother``: the local error of
        the fine detail), where a Newton iteration is dear (1-3 s at 200k vertices; a coarse level's, 0.1 s); not
        the provisional one of a paused coarse level, which the fine polish never starts from (:class:`Levels`)."""
        prepared, self.prepared, s = self.prepared, None, self.settings
        if y is not None and s.smooth and not s.coarse and not (self.coarse is not None and self.coarse.paused):
            y, self.report["smoothing"] = Smoother(self.F, self.g, self.area, len(self.V),
                                                   np.concatenate(self.loops)).smooth(y)
        return Polish(self.x if y is None else y, self.F, self.g, self.area, self.loops, self.fine_settings(y),
                      prepared=prepared)

    def refined(self, provisional: Polish) -> Polish:
        """The fine polish after the paused coarse level finished and prolongated again (the report updated in
        place; ``provisional`` counts the iterations made from the provisional start)."""
        counts = {"coarse_iterations": self.report["coarse_polish"]["iterations"], "fine_iterations": provisional.it}
        y, again = self.coarse.finish()
        self.report.clear()
        self.report.update(again, provisional=counts)
        if y is None:  # no more pauses: the levels of another start are finished at once
            y = self._restarted(replace(self.settings, pause_excess=0.0, pause_coarse=0.0))
        return self.fine_polish(y)


def multilevel_polish(V: np.ndarray, F: np.ndarray, x: np.ndarray, loops: list[np.ndarray], g: np.ndarray,
                      area: np.ndarray, settings: LevelSettings, *, progress=None, label: str = "Newton",
                      restart: Callable[[], tuple[np.ndarray | None, dict]] | None = None
                      ) -> tuple[Polish | Levels, dict]:
    """Polish (V (n,3), F (m,3)) from the bijective layout ``x`` (n,2), coarse-to-fine when the mesh has at least
    ``settings.min_vertices`` vertices and ``x`` is more than ``MULTILEVEL_MIN_EXCESS`` above an isometry
    (:class:`Multilevel`), until the polish stops or pauses (``settings.pause_excess``; ``pause_fine_start``: before
    the fine level's first iteration, when a coarse level gave its start). g (m,3,2), area (m,): the rest
    triangles' hat gradients and areas; loops: boundary loops, outer first; restart: another start for the levels
    when the coarse level stalls (:class:`Multilevel`). Returns (the fine level's :class:`newton.Polish`, or
    :class:`Levels` when its coarse level paused, with its layout ``x`` and ``report()``; the coarse-to-fine report,
    updated in place when a paused coarse level is finished)."""
    ml = Multilevel(V, F, x, loops, g, area, settings, progress=progress, restart=restart)
    run: Polish | Levels = ml.fine_polish(ml.coarse_start())
    if ml.coarse is not None and ml.coarse.paused:
        run = Levels(run, ml)
    if not (settings.pause_fine_start and ml.report.get("used")):
        run_polish(run, progress, label, settings.pause_excess)
    return run, ml.report


class Levels:
    """A fine polish started from a coarse level that paused, with :class:`newton.Polish`'s interface (``x``,
    ``done``, ``stop``, ``converged``, ``run``, ``report``, ``bar``).

    While pauses are asked for, the provisional map is the paused coarse level's prolongation, which the seams stage
    reads; the fine level waits there unpolished. Finishing (``run()`` without a pause) first finishes the coarse
    level, prolongates its end again and polishes the fine level from there: the very layout of a multilevel polish
    that never paused (the report's ``multilevel.provisional`` counts the iterations made before). ``fine`` is the
    current fine :class:`newton.Polish`."""

    def __init__(self, fine: Polish, multilevel: Multilevel):
        self.fine, self._multilevel, self.bar = fine, multilevel, None

    @property
    def x(self) -> np.ndarray:
        return self.fine.x

    @property
    def done(self) -> bool:
        return self._multilevel is None and self.fine.done

    @property
    def stop(self) -> Stop:
        return self.fine.stop

    @property
    def converged(self) -> bool:
        return self.fine.converged

    def run(self, pause_excess: float = 0.0) -> bool:
        if self._multilevel is not None:
            if pause_excess > 0.0:
                return False
            self.fine, self._multilevel = self._multilevel.refined(self.fine), None
        self.fine.bar = self.bar
        try:
            self.fine.run(pause_excess)
        finally:
            self.fine.bar = None
        return self.done

    def report(self) -> dict:
        rep = self.fine.report()
        if self._multilevel is not None:
            rep["stop"] = "paused"
        return rep


def run_polish(run: Polish | Levels, progress=None, label: str = "Newton", pause_excess: float = 0.0) -> bool:
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
