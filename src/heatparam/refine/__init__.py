"""Bijective, near-isometric polish of a layout at true scale (Eq. 1 beyond the paper).

Classical MDS minimizes strain (Eq. 13), not the stress of Eq. 1, and folds on strongly curved disks. This stage
turns a layout into a bijective map at true scale:

1. **Start** (``start``): of the MDS layout and the conformal layout (spectral, no pins) scaled to the 3D area, the
   bijective one (no flipped triangle, no boundary crossing, no hole turned inside out) with the lower energy; if
   neither is bijective, Tutte's embedding (mean value weights) of the mesh with every hole closed by a fan
   (``layout.tutte``), bijective by Tutte's theorem.
2. **Polish** (``newton``): symmetric Dirichlet energy Σ A_f (|J|² + |J⁻¹|²) (``energy``), minimized by projected
   Newton with the closed-form Hessian eigensystem of Smith et al. 2019, coarse-to-fine on large meshes
   (``multilevel``).
3. **Global bijectivity by a scaffold** (``scaffold``, Jiang et al. 2017): the rest of a box around the layout,
   re-triangulated at every iteration, joins the energy; the line search never lets a triangle flip.

:func:`refine` ``(V, F, uv, params)`` → (uv, report). Plain arrays in and out; ``report`` is JSON-able.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from threadpoolctl import ThreadpoolController

from heatparam import metrics
from heatparam.layout.conformal import smoothed_conformal_layout
from heatparam.layout.tutte import build_disk
from heatparam.options import MULTILEVEL_MIN_VERTICES
from heatparam.refine.energy import det, jacobians, surface_gradients
from heatparam.refine.multilevel import LevelSettings, multilevel_polish, run_polish
from heatparam.refine.start import LscmStart, SmoothedStart, choose_start

#: Peak memory of the refinement per surface face, above the rest of the pipeline: the peak RSS of the default run
#: minus that of ``refine none`` measured 2.4 / 1.9 / 2.35 KB per face on camelhead↑45k / 182k / 727k
#: (BENCHMARKS.md §4: PARDISO's factor of the Hessian, the 6×6 blocks and the pattern's index arrays)
POLISH_BYTES_PER_FACE = 2600


def polish_bytes(faces: int) -> float:
    """Memory the refinement of a mesh with ``faces`` triangles needs at its peak (estimate), bytes."""
    return float(POLISH_BYTES_PER_FACE) * faces


class RefineParams(NamedTuple):
    """The refinement's own parameters (``Options`` fields of the same meaning).

    solver : factorization backend (``solvers.Factor``). max_iters : the polish's iteration cap. tol : stop when
    an iteration lowers the energy by less than this fraction. multilevel : meshes of at least this many vertices
    are polished coarse-to-fine (0 = never).
    """

    solver: str = "auto"
    max_iters: int = 200
    tol: float = 1e-6
    multilevel: int = MULTILEVEL_MIN_VERTICES

    @classmethod
    def from_options(cls, opts) -> RefineParams:
        return cls(opts.solver, int(opts.refine_iters), float(opts.refine_tol), int(opts.refine_multilevel))


class Pausing(NamedTuple):
    """How a :class:`Refinement` may pause, so that the seams stage can compare maps before finishing one.

    excess : > 0: the polish pauses once an iteration lowers the energy by less than this fraction of its excess
    over an isometry (0: never). coarse : > 0: its coarse levels may pause too while their map's iso mean exceeds
    this (``multilevel.Levels``). park : a paused fine polish frees its factorization (False: it keeps it, for a
    trial that is usually finished next). fine_start : the polish also pauses before the fine level's first
    iteration when a coarse level gave its start (the seams stage compares the two maps' coarse levels first).
    raw_start : the fine level starts from its coarse level's prolongation as it is, not smoothed
    (``multilevel.LevelSettings.smooth``: the seams stage's cut trial, ``pipeline.seams.seams_stage``).
    """

    excess: float = 0.0
    coarse: float = 0.0
    park: bool = True
    fine_start: bool = False
    raw_start: bool = False


NO_PAUSE = Pausing()


def refine(V: np.ndarray, F: np.ndarray, uv: np.ndarray | None, params: RefineParams | None = None,
           progress=None, conformal: Callable[[], np.ndarray] | None = None, lscm: LscmStart | None = None,
           surface: tuple[np.ndarray, np.ndarray] | None = None, extra_starts: dict[str, np.ndarray] | None = None,
           fallback: SmoothedStart | None = None) -> tuple[np.ndarray, dict]:
    """Make the layout ``uv`` (n,2) of (V (n,3), F (m,3)) bijective and near-isometric (true scale).

    Parameters
    ----------
    V : (n,3) float64. F : (m,3) int64, a disk (possibly with holes).
    uv : (n,2) the MDS layout, or None when none was computed (the pipeline found it could not win).
    params : :class:`RefineParams`.
    progress : a ``progress.Progress`` (bars), or None.
    conformal : returns the conformal layout if already computed (the fill decision computes it).
    lscm : the conformal start already judged (``start.lscm_start``), if any.
    surface : ``energy.surface_gradients(V, F)`` if already computed.
    extra_starts : further named start candidates (n,2), judged with the others (``start.choose_start``).
    fallback : the start tried before Tutte's when no candidate is bijective (``start.SmoothedStart``; default: the
        conformal layout of (V, F) smoothed, repaired as the others are).

    Returns
    -------
    The refined layout (n,2) and a JSON-able report of what was done (start, polish, multilevel, bijectivity).
    :class:`Refinement` does the same work and can pause the polish.

    Examples
    --------
    >>> from heatparam import datasets
    >>> s = datasets.cylinder_patch(h=0.1)
    >>> uv, rep = refine(s.V, s.F, None)
    >>> rep["bijective"], rep["start"]["layout"]
    (True, 'conformal')
    """
    r = Refinement(V, F, uv, params, progress=progress, conformal=conformal, lscm=lscm, surface=surface,
                   extra_starts=extra_starts, fallback=fallback)
    r.run()
    return r.x, r.report()


class Refinement:
    """:func:`refine` in steps: the start and the polish until it stops or pauses (``pausing``: :class:`Pausing`)
    at construction, then ``run()`` goes on to the very layout of an uninterrupted refine. ``x`` (n,2) is the
    current layout (bijective at every pause), ``report()`` the report so far (``polish.stop`` "paused" while
    paused), ``done`` whether the polish stopped. The other arguments are :func:`refine`'s."""

    def __init__(self, V: np.ndarray, F: np.ndarray, uv: np.ndarray | None, params: RefineParams | None = None, *,
                 progress=None, conformal: Callable[[], np.ndarray] | None = None, lscm: LscmStart | None = None,
                 surface: tuple[np.ndarray, np.ndarray] | None = None,
                 extra_starts: dict[str, np.ndarray] | None = None, pausing: Pausing = NO_PAUSE,
                 fallback: SmoothedStart | None = None):
        t0 = time.perf_counter()
        params = RefineParams() if params is None else params
        self.F, self.progress = F, progress
        disk = build_disk(V, F)
        g, area = surface if surface is not None else surface_gradients(V, F)
        self.g = g
        if fallback is None:
            fallback = SmoothedStart(functools.partial(smoothed_conformal_layout, V, F), F, g, area, disk.loops)
        x, start = choose_start(V, F, uv, disk, g, area, lscm, conformal, params.solver, extra_starts, fallback)
        fallback.release()  # the polish needs the memory more
        self._report: dict = {"method": "sd", "holes": len(disk.holes), "start": start}
        self.x_start = x
        with _one_openblas_thread():
            settings = LevelSettings(min_vertices=params.multilevel, max_iters=params.max_iters, tol=params.tol,
                                     backend=params.solver, pause_excess=pausing.excess, pause_coarse=pausing.coarse,
                                     park=pausing.park, pause_fine_start=pausing.fine_start,
                                     smooth=not pausing.raw_start)
            # a start whose coarse level stalls is tried again from the fallback's, unless it is that or Tutte
            restart = None if start["layout"] in ("conformal_smoothed", "tutte") else fallback.start
            self.polish, self._report["multilevel"] = multilevel_polish(V, F, x, disk.loops, g, area, settings,
                                                                        progress=progress, restart=restart)
        self.seconds = time.perf_counter() - t0

    @property
    def done(self) -> bool:
        return self.polish.done

    @property
    def x(self) -> np.ndarray:
        # the start is bijective and finite: keep it rather than hand NaN on
        return self.polish.x if np.isfinite(self.polish.x).all() else self.x_start

    def run(self, pause_excess: float = 0.0) -> bool:
        """Go on with the fine polish (see the class); True once it has stopped."""
        t0 = time.perf_counter()
        with _one_openblas_thread():
            done = self.polish.done or run_polish(self.polish, self.progress, pause_excess=pause_excess)
        self.seconds += time.perf_counter() - t0
        return done

    def report(self, measured: dict | None = None) -> dict:
        """The JSON-able report (start, polish, multilevel, bijectivity of ``x``, seconds). ``measured``: the
        ``boundary_crossings`` and ``inverted_loops`` of ``x`` where the caller has them (``metrics.summary``: the
        same counts, 0.14 s at 235k faces)."""
        t0 = time.perf_counter()
        report = dict(self._report)
        pinfo = self.polish.report()
        if not np.isfinite(self.polish.x).all():
            pinfo["fallback"] = "the polish produced non-finite coordinates: the start layout is kept"
        pinfo["method"] = "projected-newton + scaffold"
        report["polish"] = pinfo
        x = self.x
        report["flips"] = int((det(jacobians(x, self.F, self.g)) <= 0).sum())
        if measured is None:
            measured = {"boundary_crossings": metrics.boundary_crossings(x, self.F),
                        "inverted_loops": metrics.inverted_loops(x, self.F)}
        report["boundary_crossings"] = int(measured["boundary_crossings"])
        report["inverted_loops"] = measured["inverted_loops"]
        report["bijective"] = (report["flips"] == 0 and report["boundary_crossings"] == 0
                               and report["inverted_loops"] == 0)
        report["seconds"] = round(self.seconds + time.perf_counter() - t0, 3)
        return report


def _one_openblas_thread():
    """One OpenBLAS thread: the polish's vector work is small, and OpenBLAS threads on it cost 10-60% on 2 cores
    (2.2 s vs 2.5 s on camelhead alone, 6.2 s with another process busy). MKL (PARDISO) keeps its threads."""
    return ThreadpoolController().select(internal_api="openblas").limit(limits=1)


__all__ = ["NO_PAUSE", "POLISH_BYTES_PER_FACE", "LscmStart", "Pausing", "RefineParams", "Refinement", "polish_bytes",
           "refine"]
