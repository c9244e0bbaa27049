"""The seams stage: flatten the surface cut open from every hole to the border when that is asked for or, with
``seams auto``, clearly better (``SEAM_TRY_EXCESS``, ``SEAM_MIN_GAIN``).

A map must keep each hole a hole; where the surface's curvature pushes a hole's side over another boundary (the
crossings of libigl's SLIM maps on halftunnel and beetle) a bijective map has to squeeze the band between them.
Cutting the holes open to the border (``mesh.seams.hole_seams``: a minimum spanning tree of shortest paths) removes
the constraint instead of fighting it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from heatparam.errors import HeatparamError
from heatparam.mesh.seams import cut_open, hole_seams
from heatparam.mesh.validate import validate_mesh
from heatparam.options import SEAM_MIN_GAIN, SEAM_TRY_EXCESS
from heatparam.pipeline.report import Flat
from heatparam.pipeline.surface import Surface
from heatparam.progress import Progress
from heatparam.refine.seam_start import open_slits


class Cut(NamedTuple):
    """A mesh cut open along seams: the cut surface (its F is the input's, row for row), ``source`` (n_s,) the
    vertex of the uncut surface each of its vertices copies, ``paths`` the seams' vertex paths (uncut ids)."""

    surface: Surface
    source: np.ndarray
    paths: list[np.ndarray]


class SeamResult(NamedTuple):
    """The seams stage's value: the flattening to keep (``flat`` itself when not cut), the cut (None when not
    cut), the report's ``seams`` part, and warnings."""

    flat: Flat
    cut: Cut | None
    report: dict
    warnings: list[str]


def seams_stage(surface: Surface, opts, prog: Progress, flat: Flat,
                flatten: Callable[..., Flat], uncut_start: bool = False) -> SeamResult:
    """``Options.seams``: the flattening (``flatten(cut surface, opts, prog, seamed=True, starts)``) of the surface
    cut open from every hole to the border when it is asked for or (``auto``) clearly better than ``flat``.

    ``uncut_start``: offer the refinement ``flat``'s map with the slits opened (``refine.seam_start.open_slits``)
    as the start candidate ``"uncut"``. Off by default: on beetle that start wins on energy (1.0106 vs Tutte's 37.6)
    but its polish ends in a worse minimum (energy 1.0039 vs 1.0007, iso mean 1.041 vs 1.019) after more Newton
    iterations (67 vs 44), on halftunnel LSCM's start is lower (1.218 vs 1.300); ``bench/bench_seams.py``.
    """
    rep: dict = {"mode": opts.seams, "used": False}
    reason = _no_cut_reason(surface, opts, flat)
    if reason is not None:
        return SeamResult(flat, None, rep | {"reason": reason}, [])
    with prog.stage("seams"):
        paths = hole_seams(surface.V, surface.F, surface.info.boundary_loops)
        Vs, Fs, src = cut_open(surface.V, surface.F, paths)
        try:
            cut_surface = Surface(Vs, Fs, validate_mesh(Vs, Fs))
        except HeatparamError as exc:  # a seam set that does not leave a disk (never seen): keep the map
            return SeamResult(flat, None, rep | {"reason": f"the cut-open mesh is not a disk ({exc})"}, [])
    iso = flat.summary["iso_mean"]
    lengths = [float(np.linalg.norm(np.diff(surface.V[p], axis=0), axis=1).sum()) for p in paths]
    rep.update(seams=len(paths), length=round(sum(lengths), 9), longest=round(max(lengths), 9),
               split_vertices=int(len(Vs) - len(surface.V)), iso_mean_without=iso)
    starts = None
    if uncut_start and opts.refine != "none":
        with prog.stage("seams"):
            x, rep["uncut_start"] = open_slits(flat.uv[src], Fs, src)
        starts = None if x is None else {"uncut": x}
    cut = flatten(cut_surface, opts, prog, True, starts)
    iso_s = cut.summary["iso_mean"]
    rep.update(iso_mean_with=iso_s, bijective_with=cut.summary["bijective"])
    if opts.seams == "auto":
        better = cut.summary["bijective"] and (not flat.summary["bijective"] or iso_s <= iso * (1 - SEAM_MIN_GAIN))
        if not better:
            rep["reason"] = (f"the cut-open map is not {SEAM_MIN_GAIN:.0%} better (iso mean {iso_s:.4f} vs "
                             f"{iso:.4f}{'' if cut.summary['bijective'] else ', not bijective'}); kept without seams")
            return SeamResult(flat, None, rep, [])
        rep["reason"] = (f"the holes cost distortion: iso mean {iso:.4f} without seams, {iso_s:.4f} with "
                         f"{len(paths)} (seams='none' keeps one uncut piece)")
    else:
        rep["reason"] = "requested (seams='holes')"
    rep["used"] = True
    warning = (f"the map has seams: {len(paths)} cut(s), {sum(lengths):.6g} long in all, join the holes to the border "
               f"(iso mean {iso:.4f} → {iso_s:.4f}); the OBJ's vt rows split along them (seams='none': one uncut "
               "piece)")
    return SeamResult(cut, Cut(cut_surface, src, paths), rep, [*cut.warnings, warning])


def _no_cut_reason(surface: Surface, opts, flat: Flat) -> str | None:
    """Why the surface is not cut (None: try cutting it)."""
    if opts.seams == "none":
        return "disabled (seams='none')"
    if surface.info.n_holes == 0:
        return "no holes"
    if opts.seams == "auto":
        if opts.refine == "none":
            return "the raw map (refine='none') is not cut (seams='holes' cuts it)"
        iso = flat.summary["iso_mean"]
        if flat.summary["bijective"] and iso <= 1 + SEAM_TRY_EXCESS:
            return f"the map without seams is bijective and near-isometric (iso mean {iso:.4f})"
    return None
