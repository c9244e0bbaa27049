"""The seams stage's cut mesh: its heat stage is skipped (same maps), its conformal layout with crossing slits
reopened (``refine.seam_start.reopen_crossing_slits``: local, bijective, the start of beetle's cut mesh), and the
uncut map as a start candidate (``refine.seam_start.open_slits``): bijective, judged with the others, and where it
helps and where it does not."""

from __future__ import annotations

import numpy as np
import pytest

from heatparam import datasets, metrics, parameterize
from heatparam.formats import load_mesh
from heatparam.layout.conformal import conformal_layout
from heatparam.mesh.seams import cut_open, hole_seams
from heatparam.options import make_options
from heatparam.pipeline import flatten
from heatparam.pipeline.surface import Surface
from heatparam.progress import Progress
from heatparam.refine import LscmStart, refine
from heatparam.refine.energy import normalized_energy, surface_gradients
from heatparam.refine.scaffold import build_scaffold
from heatparam.refine.seam_start import SLIT_MIN_AREA_FRACTION, open_slits, reopen_crossing_slits

from conftest import shared_mesh

NO_LSCM = LscmStart(None, -1, -1, None, "left out by the test")


def _cap():
    """A strongly curved cap (sphere radius 1.5) with two eye holes and a mouth slot, ~1.2k vertices."""
    s = datasets.curved_cap_with_holes(sphere_radius=1.5, h=0.05)
    return s.V, s.F


def _halftunnel():
    return load_mesh(shared_mesh("halftunnel.off"))


def _cut_case(V, F):
    """(cut V, cut F, source, the uncut map laid on the cut mesh, the opened start, its report)."""
    surface = Surface.validated(V, F)[0]
    flat = flatten(surface, make_options(None), Progress(False))
    paths = hole_seams(surface.V, surface.F, surface.info.boundary_loops)
    Vs, Fs, src = cut_open(surface.V, surface.F, paths)
    closed = flat.uv[src]
    x, rep = open_slits(closed, Fs, src)
    return Vs, Fs, src, closed, x, rep


def _signed(uv, F):
    a, b, c = uv[F[:, 0]], uv[F[:, 1]], uv[F[:, 2]]
    return 0.5 * ((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])


@pytest.mark.parametrize("case", [_cap, _halftunnel], ids=["curved cap", "halftunnel"])
def test_opened_slits_are_bijective(case):
    Vs, Fs, src, closed, x, rep = _cut_case(*case())
    assert x is not None, rep
    assert rep["moved"] == int((np.bincount(src)[src] > 1).sum())
    # closed slits: the boundary touches itself, so the scaffold cannot be built around it
    loops = [np.asarray(lp) for lp in Surface.validated(Vs, Fs)[2].boundary_loops]
    with pytest.raises(ValueError):
        build_scaffold(closed, loops)
    s = metrics.summary(Vs, Fs, x)
    assert s["flips"] == 0 and s["boundary_crossings"] == 0
    assert (_signed(x, Fs) >= SLIT_MIN_AREA_FRACTION * _signed(closed, Fs) - 1e-15).all()
    # every copy of a seam vertex now has its own position
    order = np.argsort(src, kind="stable")
    same = src[order][1:] == src[order][:-1]
    gap = np.linalg.norm(x[order][1:][same] - x[order][:-1][same], axis=1)
    assert len(gap) and gap.min() > 0
    build_scaffold(x, loops)


def test_uncut_start_on_a_cap_saves_iterations():
    """Where the seams need not open far (a cap whose cut map is near-isometric), the uncut start is close to the
    cut map's minimum: fewer Newton iterations than Tutte's embedding, measured in this run, the same energy."""
    Vs, Fs, _, _, x, _ = _cut_case(*_cap())
    y_u, r_u = refine(Vs, Fs, None, lscm=NO_LSCM, extra_starts={"uncut": x})
    y_t, r_t = refine(Vs, Fs, None, lscm=NO_LSCM)
    assert r_u["start"]["layout"] == "uncut" and r_t["start"]["layout"] == "tutte"
    assert r_u["start"]["energy"]["uncut"] < r_t["polish"]["energy_start"]
    assert r_u["polish"]["iterations"] < r_t["polish"]["iterations"]
    assert r_u["bijective"] and r_t["bijective"]
    assert r_u["polish"]["energy_end"] <= r_t["polish"]["energy_end"] * (1 + 1e-6)
    iso_u, iso_t = (metrics.summary(Vs, Fs, y)["iso_mean"] for y in (y_u, y_t))
    assert iso_u <= iso_t * (1 + 1e-5)


def test_uncut_start_on_halftunnel_loses():
    """Why it is not the default: on halftunnel the slits must open far, and the polish from the uncut start ends
    in a worse minimum than from Tutte's embedding; offered beside LSCM, the lower-energy LSCM start wins."""
    Vs, Fs, _, _, x, _ = _cut_case(*_halftunnel())
    _, r_u = refine(Vs, Fs, None, lscm=NO_LSCM, extra_starts={"uncut": x})
    _, r_t = refine(Vs, Fs, None, lscm=NO_LSCM)
    assert r_u["bijective"] and r_t["bijective"]
    assert r_u["polish"]["energy_end"] > r_t["polish"]["energy_end"] * 1.01
    _, r = refine(Vs, Fs, None, extra_starts={"uncut": x})
    e = r["start"]["energy"]
    assert r["start"]["layout"] == "conformal" and e["conformal"] < e["uncut"]


@pytest.mark.parametrize("case,kw,why", [(_halftunnel, {}, "the surface is cut open along seams"),
                                         (_cap, {"seams": "holes"}, "the conformal layout is bijective and within")],
                         ids=["halftunnel", "cap"])
def test_cut_mesh_skips_the_heat_stage_with_the_same_map(case, kw, why):
    V, F = case()
    a = parameterize(V, F, **kw)
    b = parameterize(V, F, mds_start="always", **kw)
    assert a.seamed and b.seamed
    assert a.report["method"]["geodesics"].startswith(f"skipped: {why}")
    assert not b.report["method"]["geodesics"].startswith("skipped")
    assert np.array_equal(a.uv, b.uv) and np.array_equal(a.Fuv, b.Fuv)


def _cut_cylinder():
    """cylinder_with_holes (h 0.1) cut open from its two holes: (cut V, F, source, the seams' paths, the exact flat
    layout on the cut mesh: every slit of zero width)."""
    s = datasets.cylinder_with_holes(h=0.1)
    surface = Surface.validated(s.V, s.F)[0]
    paths = hole_seams(surface.V, surface.F, surface.info.boundary_loops)
    Vs, Fs, src = cut_open(surface.V, surface.F, paths)
    return Vs, Fs, src, paths, s.uv_true[src]


def _bijective(x, F):
    return (_signed(x, F) > 0).all() and metrics.boundary_crossings(x, F) == 0


def test_reopen_closes_a_crossed_slit_locally():
    """A slit whose sides cross at one seam vertex (its two copies swapped: no face flips, the seam's edges there
    cross) is closed and reopened there only: the swapped vertex and its two seam neighbours, nothing else moves."""
    Vs, Fs, src, paths, flat = _cut_cylinder()
    opened, _ = open_slits(flat, Fs, src)
    assert _bijective(opened, Fs)
    for path in paths:
        v = path[1]  # the seam vertex next to the hole
        copies = np.flatnonzero(src == v)
        crossed = opened.copy()
        crossed[copies] = opened[copies[::-1]]
        assert (_signed(crossed, Fs) > 0).all() and metrics.boundary_crossings(crossed, Fs) > 0
        x, rep = reopen_crossing_slits(crossed, Fs, src)
        assert x is not None, rep
        assert _bijective(x, Fs)
        moved = np.flatnonzero((x != crossed).any(axis=1))
        assert set(src[moved]) == {path[0], path[1], path[2]} and rep["closed"] == 3 and rep["widened"] == 0
        loops = [np.asarray(lp) for lp in Surface.validated(Vs, Fs)[2].boundary_loops]
        build_scaffold(x, loops)


def test_reopen_zero_width_slits_and_what_it_refuses():
    """The exact flat layout laid on the cut mesh has zero-width slits (each seam edge overlaps its twin: crossings);
    reopened, it is bijective. A layout without crossings, or with a flipped face, is not touched."""
    Vs, Fs, src, paths, flat = _cut_cylinder()
    x, rep = reopen_crossing_slits(flat, Fs, src)
    assert x is not None and _bijective(x, Fs), rep
    assert set(src[(x != flat).any(axis=1)]) == set(np.concatenate(paths).tolist())
    y, rep = reopen_crossing_slits(x, Fs, src)
    assert y is None and rep["reason"] == "no boundary crossing"
    flipped = flat.copy()
    f = Fs[0]
    flipped[f[0]], flipped[f[1]] = flat[f[1]], flat[f[0]]
    y, rep = reopen_crossing_slits(flipped, Fs, src)
    assert y is None and "flipped" in rep["reason"]


@pytest.mark.slow
def test_beetle_cut_mesh_starts_from_its_reopened_conformal_layout():
    """beetle's cut mesh: its conformal layout crosses where seams leave two small holes; reopened, it is the start
    of the polish, which takes fewer Newton iterations than from Tutte's embedding (measured in this run) to the
    same or a lower energy."""
    V, F = load_mesh(shared_mesh("beetle.off"))
    surface = Surface.validated(V, F)[0]
    paths = hole_seams(surface.V, surface.F, surface.info.boundary_loops)
    Vs, Fs, src = cut_open(surface.V, surface.F, paths)
    conf = conformal_layout(Vs, Fs)
    assert (_signed(conf, Fs) > 0).all() and metrics.boundary_crossings(conf, Fs) > 0
    x, rep = reopen_crossing_slits(conf, Fs, src)
    assert x is not None and _bijective(x, Fs), rep
    moved = np.flatnonzero((x != conf).any(axis=1))
    assert len(np.unique(src[moved])) == rep["closed"] <= 10 and (np.bincount(src)[src[moved]] > 1).all()
    g, area = surface_gradients(Vs, Fs)
    e_conf, e_x = normalized_energy(conf, Fs, g, area), normalized_energy(x, Fs, g, area)
    assert abs(e_x - e_conf) <= 1e-4 * e_conf
    _, r_x = refine(Vs, Fs, None, lscm=NO_LSCM, extra_starts={"conformal_reopened": x})
    _, r_t = refine(Vs, Fs, None, lscm=NO_LSCM)
    assert r_x["start"]["layout"] == "conformal_reopened" and r_t["start"]["layout"] == "tutte"
    assert r_x["bijective"] and r_t["bijective"]
    assert r_x["polish"]["iterations"] < r_t["polish"]["iterations"]
    assert r_x["polish"]["energy_end"] <= r_t["polish"]["energy_end"] * (1 + 1e-6)
    # the pipeline offers it: beetle's kept (cut) map starts there
    res = parameterize(V, F)
    assert res.seamed and res.report["method"]["refine"]["start"]["layout"] == "conformal_reopened"
    assert res.report["method"]["seams"]["conformal_reopened"]["closed"] == rep["closed"]
