"""The maps did not change with the restructuring (issue 13): every recorded surface (tests/baseline/record.py:
the public meshes that flatten and the generated surfaces, default options and ``refine="none"``) gives the same
map and the same metrics as the code before it.

Recorded on this project's machine kind. In the recording's environment (``record.environment``: CPU model and
flags, numerical libraries' versions) the map is compared bit for bit (its sha256) and, as a diagnostic, against the
stored array to 1e-9 of its extent. In another environment round-off differs (the same code: 1e-8 of the extent on
beetle, stop 19) and is amplified by the Newton iterations, so the map is compared to ``OTHER_ENV_TOL`` of its extent
and the float metrics to that relative tolerance; counts (flips, crossings) and the seams still exactly. Raw maps
there: ``RAW_OTHER_ENV_STRESS``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from baseline.record import METRICS, MODES, SHARED, cases, digest, environment, run

#: Tolerance (of the extent, and relative for float metrics) outside the recording's environment: 10x the largest
#: difference measured between two machines (beetle, 1.05e-8 of its extent), 100x below what one Newton iteration
#: more or less moves a map (refine_tol 1e-7 instead of 1e-6: camelhead 5.7e-5, cylinder_with_holes 1.3e-5 of the
#: extent; stop 19)
OTHER_ENV_TOL = 1e-7

#: The raw map (``refine="none"``: the MDS layout) is not reproducible to OTHER_ENV_TOL on another CPU: the fill's
#: gaps are triangulated with Steiner points at the mean edge (``fill``), a discrete process that responds to the
#: round-off of the conformal layout it starts from, and the geodesics and MDS follow. Measured (stop 21): on a
#: second CPU type of this project's kind the raw maps of halftunnel, beetle, woody, cylinder_with_holes and
#: cone_s_strip moved by 1-100% of their extent, 0.2-2% after the best rigid motion (gap vertices 1918 vs 1898 on
#: cone_s_strip; a 1e-13 relative perturbation of the input does the same on one machine), their stress (Eq. 1)
#: by ≤ 2.2% (halftunnel 0.1402 vs 0.1433), while every polished map stayed within OTHER_ENV_TOL. So outside the
#: recording's environment a raw map is held to its face structure and its relative stress within this fraction.
RAW_OTHER_ENV_STRESS = 0.05


def _reference():
    from pathlib import Path

    here = Path(__file__).resolve().parent / "baseline"
    return json.loads((here / "maps.json").read_text()), np.load(here / "maps.npz")


CASES = [name for name, _, _ in cases(load=False)]


@pytest.mark.slow
@pytest.mark.parametrize("name", CASES)
def test_same_maps_as_before_the_restructuring(name):
    table, arrays = _reference()
    if not name.startswith("generated:") and not (SHARED / name).exists():
        pytest.skip(f"{SHARED / name} not found")
    V, F = next((V, F) for n, V, F in cases(only=name))
    same_env = table.get("_environment") == environment()
    tol = 1e-9 if same_env else OTHER_ENV_TOL
    for mode in MODES:
        key = f"{name}|{mode}"
        uv, Fuv, met = run(V, F, mode)
        ref = arrays[key]
        assert uv.shape == ref.shape, key
        assert digest(np.asarray(Fuv, dtype=np.int64)) == table[key]["fuv_sha"], key
        if mode == "raw" and not same_env:  # RAW_OTHER_ENV_STRESS
            a, b = met["stress_rel_rms"], table[key]["metrics"]["stress_rel_rms"]
            assert math.isclose(a, b, rel_tol=RAW_OTHER_ENV_STRESS), (key, a, b)
            continue
        extent = float(np.ptp(ref, axis=0).max())
        assert np.abs(uv - ref).max() <= tol * extent, (key, float(np.abs(uv - ref).max()) / extent)
        if same_env:
            assert digest(uv) == table[key]["uv_sha"], f"{key}: same map to 1e-9 but not bit for bit"
        for k in METRICS:
            a, b = met[k], table[key]["metrics"][k]
            rel = 1e-12 if same_env else OTHER_ENV_TOL
            assert a == b or (isinstance(a, float) and math.isclose(a, b, rel_tol=rel)), (key, k, a, b)
