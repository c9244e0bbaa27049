"""The start of a mesh cut open along seams: its conformal layout with the crossing slits reopened
(``refine.reopen_slits.reopen_crossing_slits``): local, bijective, the start of beetle's cut mesh."""

from __future__ import annotations

import numpy as np
import pytest

from heatparam import datasets, metrics, parameterize
from heatparam.formats import load_mesh
from heatparam.layout.conformal import conformal_layout
from heatparam.mesh.seams import cut_open, hole_seams
from heatparam.pipeline.surface import Surface
from heatparam.refine import LscmStart, refine
from heatparam.refine.energy import normalized_energy, surface_gradients
from heatparam.refine.reopen_slits import reopen_crossing_slits
from heatparam.refine.scaffold import build_scaffold

from conftest import shared_mesh

NO_LSCM = LscmStart(None, -1, -1, None, "left out by the test")


def _signed(uv, F):
    a, b, c = uv[F[:, 0]], uv[F[:, 1]], uv[F[:, 2]]
    return 0.5 * ((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])


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
    opened, _ = reopen_crossing_slits(flat, Fs, src)  # the zero-width slits opened
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


class _NoFallback:
    """No fallback start (``refine.start.SmoothedStart``): Tutte's embedding is the reference."""

    def start(self):
        return None, {}

    def release(self):
        pass


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
    _, r_t = refine(Vs, Fs, None, lscm=NO_LSCM, fallback=_NoFallback())
    assert r_x["start"]["layout"] == "conformal_reopened" and r_t["start"]["layout"] == "tutte"
    assert r_x["bijective"] and r_t["bijective"]
    assert r_x["polish"]["iterations"] < r_t["polish"]["iterations"]
    assert r_x["polish"]["energy_end"] <= r_t["polish"]["energy_end"] * (1 + 1e-6)
    # the pipeline offers it: beetle's kept (cut) map starts there
    res = parameterize(V, F)
    assert res.seamed and res.report["method"]["refine"]["start"]["layout"] == "conformal_reopened"
    assert res.report["method"]["seams"]["conformal_reopened"]["closed"] == rep["closed"]
