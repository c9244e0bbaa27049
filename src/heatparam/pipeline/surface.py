"""The surface a flattening works on: the validated mesh without unreferenced vertices, with what several stages
share computed once (its conformal layout, the refinement's per-face gradients)."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from heatparam.errors import HeatparamError
from heatparam.layout.conformal import SCP_MAX_ITERS, ConformalLayouts
from heatparam.mesh.frame import UnitFrame, frame_of
from heatparam.mesh.topology import Compaction, compact
from heatparam.mesh.validate import MeshInfo, check_arrays, validate_mesh


class Surface:
    """A validated disk (V (n,3), F (m,3)) whose vertices are all referenced, and its :class:`MeshInfo`, in the
    internal units of its :class:`~heatparam.mesh.frame.UnitFrame` (the input's own, except for extreme sizes).

    ``conformal()`` (the spectral conformal layout scaled to the 3D area, read-only) and ``gradients()`` (the
    refinement's hat gradients and areas) are computed at most once and shared by the fill decision, the start
    checks and the refinement; ``smoothed_conformal(steps)`` (the refinement's fallback start) once per ``steps``,
    refactorizing the conformal layout's matrix pattern (``layout.conformal.ConformalLayouts``) until
    ``release_layouts()``.
    ``conformal_method``, ``conformal_max_solves``: how the spectral layouts are solved
    (``layout.conformal.spectral_conformal``'s ``method`` and ``max_solves``; the seams stage's cut-open mesh uses
    ``inverse`` and ``SCP_CUT_MAX_ITERS``). ``conformal_skipped``: why the conformal layout is not computed (None:
    it is); ``conformal()`` then raises a ``HeatparamError`` saying so, which the start checks report as that
    candidate's failure (the seams stage sets it where the start is known without it).
    """

    def __init__(self, V: np.ndarray, F: np.ndarray, info: MeshInfo, frame: UnitFrame | None = None,
                 conformal_method: str = "krylov", conformal_max_solves: int = SCP_MAX_ITERS):
        self.V, self.F, self.info = V, F, info
        self.frame = frame if frame is not None else UnitFrame(0, np.zeros(3))
        self.conformal_method, self.conformal_max_solves = conformal_method, conformal_max_solves
        self.conformal_skipped: str | None = None
        # the conformal layouts' factorization, kept from conformal() to smoothed_conformal() until release_layouts()
        self._layouts = ConformalLayouts(F, method=conformal_method, max_solves=conformal_max_solves)

    @classmethod
    def validated(cls, V: np.ndarray, F: np.ndarray) -> tuple[Surface, Compaction, MeshInfo]:
        """Validate the input (``mesh.validate_mesh``, in the unit frame ``mesh.frame.unit_frame``) and drop its
        unreferenced vertices: (surface, the compaction that maps input ids to the surface's, the input's
        MeshInfo in internal units)."""
        V, F = check_arrays(V, F)
        frame = frame_of(V, F)
        info = validate_mesh(frame.to_unit(V), F)
        comp = compact(info.referenced)
        own = dataclasses.replace(info, referenced=np.ones(len(comp.keep), dtype=bool), warnings=[],
                                  boundary_loops=[comp.remap[lp] for lp in info.boundary_loops])
        return cls(frame.to_unit(V[comp.keep]), comp.faces(F), own, frame), comp, info

    @functools.cache  # noqa: B019 - one Surface per flattening; the cache lives exactly as long as it
    def conformal(self) -> np.ndarray:
        """The conformal layout (``layout.conformal.conformal_layout``: spectral, no pins), (n,2), computed once."""
        if self.conformal_skipped is not None:
            raise HeatparamError(f"not computed: {self.conformal_skipped}")
        uv0 = self._layouts.layout(self.V)
        uv0.setflags(write=False)
        return uv0

    @functools.cache  # noqa: B019
    def smoothed_conformal(self, steps: int) -> np.ndarray:
        """The conformal layout of the surface smoothed by ``steps`` umbrella steps
        (``layout.conformal.smoothed_conformal_layout``), (n,2), computed once per ``steps``."""
        uv = self._layouts.smoothed(self.V, steps)
        self._layouts.free()  # the last layout a flattening asks for (one ``steps``)
        uv.setflags(write=False)
        return uv

    def release_layouts(self) -> None:
        """Free the factorization that :meth:`conformal` keeps for :meth:`smoothed_conformal` (the same faces: a
        numerical factorization only); a later layout factorizes anew. The flattening releases it once the
        refinement's start is chosen, and before the heat stage."""
        self._layouts.free()

    @functools.cache  # noqa: B019
    def gradients(self) -> tuple[np.ndarray, np.ndarray]:
        """The refinement's per-face hat gradients (m,3,2) and areas (m,) (``refine.energy.surface_gradients``)."""
        from heatparam.refine.energy import surface_gradients

        return surface_gradients(self.V, self.F)
