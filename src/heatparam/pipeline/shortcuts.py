"""When the heat stage cannot change the map, skip it (``Options.mds_start = "auto"``).

The refinement starts from the lower-energy bijective layout of MDS and the conformal layout (spectral, no pins).
Cases where the MDS layout cannot win are recognised before it is computed:

(a) the conformal layout is bijective and within ``ISOMETRIC_START_EXCESS`` of an isometry (developable parts);
(b) on meshes of at least ``FOLD_CHECK_MIN_VERTICES``, the MDS layout of a coarse mesh (``FOLD_CHECK_VERTICES``,
    ~8k, triangulated in the conformal layout) folds beyond what the refinement repairs (curved scans): the full one
    folds too;
(c) the surface is the seams stage's cut-open mesh: it is not filled (a fill would close the seams), geodesics run
    around the slits, and MDS lost to LSCM or Tutte on every seamed map measured (beetle: 4106 flipped faces;
    halftunnel: energy 1.435 vs LSCM 1.218; a 200k mask scan: not bijective).

All three leave the map bit for bit the same (tests compare with ``mds_start="always"``).
"""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np

from heatparam import metrics
from heatparam.errors import HeatparamError
from heatparam.layout.tutte import build_disk
from heatparam.mesh.validate import validate_mesh
from heatparam.options import FOLD_CHECK_MIN_VERTICES, FOLD_CHECK_VERTICES, ISOMETRIC_START_EXCESS
from heatparam.pipeline.heat_stage import decide_fill, mds_map
from heatparam.pipeline.surface import Surface
from heatparam.progress import Progress
from heatparam.refine.multilevel import coarse_mesh, coarse_vertices
from heatparam.refine.start import MDS_REPAIR_MAX_FRACTION, LscmStart, lscm_start


class StartCheck(NamedTuple):
    """The start checks' value: the conformal start judged (or None when not checked), why the heat stage is skipped
    (None: it runs), and the fold check's report (None when it did not run)."""

    lscm: LscmStart | None
    skipped: str | None
    fold_check: dict | None


def heat_stage_optional(opts) -> bool:
    """Whether ``mds_start auto`` may skip the fill, geodesics and MDS: not when any of them was asked for."""
    return opts.fill == "auto" and opts.geodesics == "auto" and opts.stress == "none" and opts.landmarks == 0


def start_checks(surface: Surface, opts, prog: Progress, seamed: bool = False) -> StartCheck:
    """Whether the fill, geodesics and MDS can be skipped (cases (a), (b) and (c) of the module docstring;
    ``seamed``: the surface is the seams stage's cut-open mesh)."""
    if opts.refine == "none" or opts.mds_start == "always" or not heat_stage_optional(opts):
        return StartCheck(None, None, None)
    with prog.stage("start check"):
        lscm = lscm_start(surface.V, surface.F, surface.conformal, surface.gradients())
    if opts.mds_start == "never":
        return StartCheck(lscm, "skipped: mds_start='never' (the refinement starts from the conformal layout, or Tutte "
                                "when it is "
                                "not bijective)", None)
    if lscm.near_isometric:
        return StartCheck(lscm, (f"skipped: the conformal layout is bijective and within {ISOMETRIC_START_EXCESS:g} of "
                                 f"an isometry (energy {lscm.energy:.7f}), so it starts the refinement "
                                 "(mds_start='always' computes them)"), None)
    if seamed:
        return StartCheck(lscm, ("skipped: the surface is cut open along seams and not filled, so geodesics run "
                                 "around the slits and the MDS layout folds across them (mds_start='always' "
                                 "computes them)"), None)
    if lscm.energy is None or len(surface.V) < FOLD_CHECK_MIN_VERTICES:
        return StartCheck(lscm, None, None)
    with prog.stage("fold check"):
        fc = fold_check(surface, lscm.uv, opts)
    if fc.get("usable", True):
        return StartCheck(lscm, None, fc)
    return StartCheck(lscm, (f"skipped: the MDS layout of a {fc['vertices']}-vertex coarse mesh folds ({fc['flips']} "
                             f"of {fc['faces']} triangles flipped, more than a repair handles), so the full one would "
                             "not be a start for the refinement either; it starts from the conformal layout "
                             "(mds_start='always' "
                             "computes them)"), fc)


def fold_check(surface: Surface, uv: np.ndarray, opts) -> dict:
    """The heat stage on a coarse mesh of the surface triangulated in its bijective layout ``uv`` (n,2): flips and
    boundary crossings of the coarse MDS layout (the same options otherwise), or why it could not be done."""
    t0 = time.perf_counter()
    V, F = surface.V, surface.F
    try:
        disk = build_disk(V, F)
        loops = disk.loops
        ids = coarse_vertices(V, F, loops, FOLD_CHECK_VERTICES)
        T = coarse_mesh(uv, loops, ids)
        coarse = Surface(V[ids], T, validate_mesh(V[ids], T))
        quiet = Progress(False)
        used, reason = decide_fill(opts, coarse, seamed=False)
        m = mds_map(coarse, opts, quiet, used, reason)
        summary = metrics.summary(coarse.V, coarse.F, m.uv)
        flips, crossings = int(summary["flips"]), int(summary["boundary_crossings"])
        out = {"vertices": len(ids), "faces": len(T), "flips": flips, "crossings": crossings,
               "fill": m.fill["used"], "seconds": round(time.perf_counter() - t0, 3)}
        # the refinement repairs an MDS start with a few flips, so only more than that counts as folded; anything
        # less (1 flip of 20k at a boundary corner of a noisy scan's coarse mesh, 3 repairable ones in the full
        # layout) proves nothing about the full layout
        out["usable"] = flips <= max(1, MDS_REPAIR_MAX_FRACTION * len(T))
    except (HeatparamError, ValueError, RuntimeError, np.linalg.LinAlgError) as exc:  # only a shortcut
        return {"failed": str(exc)}
    return out
