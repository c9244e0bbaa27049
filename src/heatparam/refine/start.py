"""The refinement's start: the bijective one of the MDS, conformal and mean-plane projection layouts with the lowest
energy, else the conformal layout of the smoothed surface, else Tutte.

Every candidate is judged once, here: flipped faces, boundary crossings and holes turned inside out, energy (1 =
isometry). A layout with a few flipped faces is repaired first (:func:`repaired_layout`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from heatparam import metrics
from heatparam.errors import HeatparamError
from heatparam.layout.conformal import conformal_layout
from heatparam.layout.projection import NO_MEAN_PLANE, projection_layout
from heatparam.layout.tutte import Disk, tutte
from heatparam.mesh.topology import boundary_edges, boundary_loops
from heatparam.options import ISOMETRIC_START_EXCESS
from heatparam.refine.energy import det, jacobians, normalized_energy, surface_gradients
from heatparam.refine.multilevel import grow_rings, repair_flips
from heatparam.refine.reopen_slits import push_apart
from heatparam.refine.untangle import BARRIER_EPS, untangle


def bijectivity(uv: np.ndarray, F: np.ndarray, g: np.ndarray) -> tuple[int, int]:
    """(flipped faces, crossings) of a layout: crossings are the boundary crossings plus the holes turned inside out
    (``metrics.inverted_loops``: halftunnel's conformal layout, its 2 flipped faces untangled, covers one hole
    twice), only counted when nothing is flipped (else -1). Bijective when both are 0."""
    flips = int((det(jacobians(uv, F, g)) <= 0).sum())
    if flips:
        return flips, -1
    return 0, int(metrics.boundary_crossings(uv, F)) + metrics.inverted_loops(uv, F)

#: A layout with a few flipped faces (at most this fraction, and at least 1) is repaired before it competes as a
#: start (:func:`unflipped`), accepted only when the result is bijective (a noisy 49k-vertex patch's MDS layout: 3
#: flips repaired, then half the Newton iterations for the same map quality).
MDS_REPAIR_MAX_FRACTION = 1e-3

#: A border ear (a face whose three corners are boundary vertices) that a layout folds or flattens is untangled in
#: this many rings around it (:func:`unflipped`)
EAR_RINGS = 2


def unflipped(x: np.ndarray, F: np.ndarray, g: np.ndarray, area: np.ndarray, loops: list[np.ndarray],
              ears_only: bool = False) -> tuple[np.ndarray | None, dict]:
    """``x`` (n,2) without flipped faces, if only a few are (≤ ``MDS_REPAIR_MAX_FRACTION``).

    Where the only faces flipped or flattened to round-off (det J ≤ ``BARRIER_EPS``) are border ears (faces whose
    three corners are boundary vertices: a projection folds a scan's border sliver under its neighbour, a zero-area
    ear stays flat), which the repair below never moves: ``untangle`` of their ``EAR_RINGS``-ring neighbourhood,
    their own corners free. Else (unless ``ears_only``: None) the flipped faces go to ``repair_flips``, the boundary
    loops locked. A layout that also folds elsewhere was a poor start with its ears untangled (a held-out mask's
    projection, 126 folds and 3 ears: iso 1.0198 → 1.0360 against Tutte's start), and untangling every fold lost
    too (docs/refine.md §10). Boundary crossings are not checked here.
    g (m,3,2), area (m,): the rest triangles' hat gradients and areas. Returns (layout or None, report)."""
    D = det(jacobians(x, F, g))
    locked = np.zeros(len(x), dtype=bool)
    locked[np.concatenate(loops)] = True
    flipped, ears = D <= 0, (D <= BARRIER_EPS) & locked[F].all(axis=1)
    bad = int((flipped | ears).sum())
    report: dict = {"flips": int(flipped.sum())}
    if bad == 0:
        return None, report | {"repaired": False, "reason": "nothing flipped"}
    if bad > max(1, MDS_REPAIR_MAX_FRACTION * len(F)):
        return None, report | {"repaired": False, "reason": "too many flips to repair"}
    z = x
    if ears.any():
        report["ears"] = int(ears.sum())
    folds = bool((flipped & ~ears).any())
    if folds and ears_only:
        return None, report | {"repaired": False, "reason": "faces other than border ears are flipped"}
    if ears.any() and not folds:
        z = _untangled_ears(x, F, g, area, locked, ears)
        if z is None:
            return None, report | {"repaired": False, "reason": "a border ear could not be untangled"}
    z, _, rounds = repair_flips(z, z, F, g, locked)
    if z is None:
        return None, report | {"repaired": False, "reason": f"flips remain after {rounds} rounds"}
    return z, report | {"repaired": True, "rounds": rounds}


def _untangled_ears(x: np.ndarray, F: np.ndarray, g: np.ndarray, area: np.ndarray, locked: np.ndarray,
                    ears: np.ndarray) -> np.ndarray | None:
    """``x`` with the ``ears`` (m,) bool faces untangled (:func:`unflipped`), or None."""
    import igl

    corners = np.zeros(len(x), dtype=bool)
    corners[F[ears].ravel()] = True
    free = (grow_rings(corners, igl.adjacency_matrix(F), EAR_RINGS) & ~locked) | corners
    near = free[F].any(axis=1)  # only these faces move: the flips elsewhere are the mean value repair's
    z, _ = untangle(x, F[near], g[near], area[near], free, floor=BARRIER_EPS)
    return z


def repaired_layout(x: np.ndarray, F: np.ndarray, g: np.ndarray, area: np.ndarray, loops: list[np.ndarray]
                    ) -> tuple[np.ndarray | None, dict]:
    """``x`` (n,2) made bijective by :func:`unflipped`, or None when it is not bijective then (its boundary
    crosses, or a hole is turned inside out); (layout or None, report)."""
    z, report = unflipped(x, F, g, area, loops)
    if z is None:
        return None, report
    if metrics.boundary_crossings(z, F):
        return None, report | {"repaired": False, "reason": "the boundary crosses itself"}
    if metrics.inverted_loops(z, F):
        return None, report | {"repaired": False, "reason": "a hole is turned inside out (the layout covers it twice)"}
    return z, report

class LscmStart(NamedTuple):
    """The conformal layout as a start candidate: the layout (None if it failed; repaired when ``repair`` says so),
    flips and crossings of the layout as computed (crossings -1 when not counted), its energy per area / 4 (1 =
    isometry; None unless it, or its repair, is bijective), why it failed, and the repair's report (None: nothing was
    flipped)."""

    uv: np.ndarray | None
    flips: int
    crossings: int
    energy: float | None
    failed: str | None = None
    repair: dict | None = None

    @property
    def near_isometric(self) -> bool:
        return self.energy is not None and self.energy - 1.0 <= ISOMETRIC_START_EXCESS

def lscm_start(V: np.ndarray, F: np.ndarray, conformal: Callable[[], np.ndarray] | None = None,
               surface: tuple[np.ndarray, np.ndarray] | None = None) -> LscmStart:
    """The conformal layout of (V, F) (``conformal()`` if given, else computed) judged as a start for the polish; a
    few flipped faces are repaired as MDS's are (:func:`repaired_layout`; strong scanner noise leaves a few, e.g.
    7 of a 182k-vertex noisy cylinder patch's faces).

    surface : ``surface_gradients(V, F)`` if already computed.
    """
    g, area = surface if surface is not None else surface_gradients(V, F)
    try:
        xl = np.array(conformal() if conformal is not None else conformal_layout(V, F))
    except HeatparamError as exc:  # a degenerate mesh, or not computed: only a candidate, MDS or Tutte serve
        return LscmStart(None, -1, -1, None, str(exc))
    if not np.isfinite(xl).all():  # never hand NaN on: the candidate is dropped, MDS or Tutte still serve
        return LscmStart(None, -1, -1, None, "the conformal layout has non-finite coordinates")
    flips, cross = bijectivity(xl, F, g)
    repair = None
    if flips:
        z, repair = repaired_layout(xl, F, g, area, boundary_loops(F))
        if z is not None:
            return LscmStart(z, flips, cross, normalized_energy(z, F, g, area), None, repair)
    e = normalized_energy(xl, F, g, area) if flips == 0 and cross == 0 else None
    return LscmStart(xl, flips, cross, e, None, repair)


#: Start energies within this fraction of the lowest are a tie, which the first candidate (MDS, conformal,
#: projection, extras) wins: a mean of 1e4-1e6 terms has round-off far below it, and a flat part's conformal layout
#: and projection are both isometries (woody.obj: 0.9999999999999999 against 1.0, which the Jacobians' summation
#: order flipped)
ENERGY_TIE = 1e-12


def _lowest(energies: dict[str, float]) -> str:
    """The candidate of lowest energy; of energies within ``ENERGY_TIE`` of it, the first one's."""
    low = min(energies.values())
    return next(k for k, e in energies.items() if e <= low * (1 + ENERGY_TIE))


def choose_start(V: np.ndarray, F: np.ndarray, uv: np.ndarray | None, disk: Disk, g: np.ndarray, area: np.ndarray,
                 lscm: LscmStart | None, conformal: Callable[[], np.ndarray] | None, backend: str,
                 extra: dict[str, np.ndarray] | None = None, fallback: SmoothedStart | None = None
                 ) -> tuple[np.ndarray, dict]:
    """The polish's start: of the MDS layout ``uv`` (n,2) (a few flipped faces repaired: :func:`repaired_layout`;
    None = not computed), the conformal layout (``lscm`` if given, else :func:`lscm_start`), the projection onto
    the mean plane (``layout.projection``, repaired likewise) and the ``extra`` named layouts (n,2) (e.g.
    ``"conformal_reopened"``: the cut mesh's conformal layout, its crossing slits reopened), the bijective one (no
    flipped face, no crossing of any boundary loop) with the lowest energy; if none is, the ``fallback``
    (:class:`SmoothedStart`) when bijective, else Tutte's embedding. Returns (layout (n,2), the report's ``start``)."""
    if lscm is None:
        lscm = lscm_start(V, F, conformal, (g, area))
    cands: dict[str, np.ndarray] = {}
    energies: dict[str, float] = {}
    if uv is None:
        report: dict = {"mds": "not computed (the pipeline's method.geodesics says why)"}
    else:
        x = np.asarray(uv, dtype=np.float64)
        finite = bool(np.isfinite(x).all())
        flips, cross = bijectivity(x, F, g) if finite else (-1, -1)
        report = {"flips": flips, "crossings": cross}
        if not finite:  # degenerate faces can make the heat geodesics, hence MDS, non-finite: not a candidate
            report["mds_rejected"] = "non-finite coordinates"
            x = None
        elif flips:  # crossings are only counted when nothing is flipped; a repaired layout has none
            x, report["repair"] = repaired_layout(x, F, g, area, disk.loops)
            cross = 0
        if x is not None and not cross:
            cands["mds"], energies["mds"] = x, normalized_energy(x, F, g, area)
    if lscm.failed is not None:
        report["conformal_failed"] = lscm.failed
    report.update(conformal_flips=lscm.flips, conformal_crossings=lscm.crossings)
    if lscm.repair is not None:
        report["conformal_repair"] = lscm.repair
    if lscm.energy is not None:
        cands["conformal"], energies["conformal"] = lscm.uv, lscm.energy
    xp, report["projection"] = _projection(V, F, g, area, disk)
    if xp is not None:
        cands["projection"], energies["projection"] = xp, normalized_energy(xp, F, g, area)
    for name, xe in (extra or {}).items():
        xe = np.asarray(xe, dtype=np.float64)
        flips, cross = bijectivity(xe, F, g)
        report[f"{name}_flips"], report[f"{name}_crossings"] = flips, cross
        if flips == 0 and cross == 0:
            cands[name], energies[name] = xe, normalized_energy(xe, F, g, area)
    # of the bijective candidates, start from the one with the lower energy: on developable parts LSCM (already
    # computed by the fill decision) is an isometry up to round-off, where MDS needs 5-7 Newton iterations
    if cands:
        start = _lowest(energies)
        x = np.array(cands[start], dtype=np.float64)
        report["energy"] = energies
    else:
        x, start = _last_resort(V, F, g, area, disk, backend, fallback, report)
    if not np.isfinite(x).all():
        x, start = tutte(V, disk, backend)[: len(V)], "tutte"
    if not np.isfinite(x).all():
        raise HeatparamError("the refinement's start layouts (MDS, conformal, Tutte) all have non-finite coordinates: "
                             "is the mesh degenerate?")
    report["layout"] = start
    return x, report


#: :class:`SmoothedStart` smooths the surface by this many umbrella steps: spikes a few edges wide fold the
#: conformal layout (2 steps left a noisy 114k-vertex part's cut mesh with 14 crossings; 16 steps rescued no part
#: that 4 did not, on 40 drawn parts)
SMOOTHING_STEPS = 4


class SmoothedStart:
    """The start tried when no candidate of :func:`choose_start` is bijective, before Tutte's embedding: the
    conformal layout of the surface smoothed by ``SMOOTHING_STEPS`` umbrella steps
    (``layout.conformal.smoothed_conformal_layout``), if it is bijective as it is or once ``repair``ed.

    layout : steps -> (n,2) layout (``pipeline.Surface.smoothed_conformal``), computed only when asked.
    F (m,3), g (m,3,2), area (m,), loops : the faces, their rest triangles' hat gradients and areas, the boundary
        loops (outer first): to judge bijectivity and to repair.
    repair : layout -> (bijective layout or None, report); None: :func:`repaired_layout`, as for the other
        candidates (the seams stage passes its reopening of crossing slits for a mesh cut open).
    release : frees what ``layout`` keeps to make it sooner (``pipeline.Surface.release_layouts``: the conformal
        layout's factorization), called by :meth:`release` once the start is chosen.
    """

    def __init__(self, layout: Callable[[int], np.ndarray], F: np.ndarray, g: np.ndarray, area: np.ndarray,
                 loops: list[np.ndarray],
                 repair: Callable[[np.ndarray], tuple[np.ndarray | None, dict]] | None = None,
                 release: Callable[[], None] | None = None):
        self.layout, self.F, self.g = layout, F, g
        self.repair = repair or functools.partial(repaired_layout, F=F, g=g, area=area, loops=loops)
        self._release = release

    def release(self) -> None:
        """The start is chosen: free what the layout keeps (``release``); a later :meth:`start` (a coarse level's
        restart) makes its layout without it."""
        if self._release is not None:
            self._release()

    def start(self) -> tuple[np.ndarray | None, dict]:
        """(bijective layout (n,2) or None, the report's ``start.conformal_smoothed`` part)."""
        try:
            x = np.array(self.layout(SMOOTHING_STEPS), dtype=np.float64)
        except HeatparamError as exc:
            return None, {"steps": SMOOTHING_STEPS, "reason": str(exc)}
        flips, cross = bijectivity(x, self.F, self.g)
        report: dict = {"steps": SMOOTHING_STEPS, "flips": flips, "crossings": cross}
        if flips or cross:
            x, report["repair"] = self.repair(x)
        return x, report


def _last_resort(V: np.ndarray, F: np.ndarray, g: np.ndarray, area: np.ndarray, disk: Disk, backend: str,
                 fallback: SmoothedStart | None, report: dict) -> tuple[np.ndarray, str]:
    """No candidate of :func:`choose_start` is bijective: (the ``fallback``'s layout when it is, else Tutte's
    embedding, its name); the fallback's part and energy go into ``report``."""
    if fallback is not None:
        x, report["conformal_smoothed"] = fallback.start()
        if x is not None:
            report["energy"] = {"conformal_smoothed": normalized_energy(x, F, g, area)}
            return x, "conformal_smoothed"
    return tutte(V, disk, backend)[: len(V)], "tutte"


def _projection(V: np.ndarray, F: np.ndarray, g: np.ndarray, area: np.ndarray, disk: Disk
                ) -> tuple[np.ndarray | None, dict]:
    """The projection onto the mean plane (``layout.projection``) as a start candidate: (the layout when it is
    bijective, a few flipped faces repaired as MDS's are, else None; the report's ``start.projection``). Boundary
    vertices that a bijective projection puts on one point (the copies of a vertex that the atlas's repair split,
    at one 3D position) are then pushed into their own sides (``reopen_slits.push_apart``): the scaffold needs
    distinct boundary points."""
    x = projection_layout(V, F)
    if x is None:
        return None, {"reason": NO_MEAN_PLANE}
    flips, cross = bijectivity(x, F, g)
    report: dict = {"flips": flips, "crossings": cross}
    if flips:
        x, report["repair"] = repaired_layout(x, F, g, area, disk.loops)
        if x is None:
            return None, report
        report["crossings"] = cross = 0
    if cross:
        return None, report
    x, separated = separated_boundary(x, F, disk.loops)
    return x, report | separated


def separated_boundary(x: np.ndarray, F: np.ndarray, loops: list[np.ndarray]) -> tuple[np.ndarray | None, dict]:
    """The bijective layout ``x`` (n,2) with boundary vertices that share a point (the copies of a vertex that the
    atlas's repair split, at one 3D position, projected) pushed into their own sides (``reopen_slits.push_apart``):
    the scaffold needs distinct boundary points. (layout or None, the report's ``separated`` part: {} when none
    shared a point)."""
    bnd = np.concatenate(loops)
    _, at, count = np.unique(x[bnd], axis=0, return_inverse=True, return_counts=True)
    shared = bnd[count[at.ravel()] > 1]
    if not len(shared):
        return x, {}
    z, pushed = push_apart(x, F, boundary_edges(F), shared)
    report = {"separated": int(len(shared))}
    return z, report if z is not None else report | {"reason": pushed["reason"]}
