"""The maps did not change with the restructuring (issue 13): every recorded surface (tests/baseline/record.py:
the public meshes that flatten and the generated surfaces, default options and ``refine="none"``) gives the same
map and the same metrics as the code before it.

Recorded on this project's machine kind; the map is compared bit for bit (its sha256) and, as a diagnostic that
holds across CPUs too, against the stored array to 1e-9 of its extent."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from baseline.record import METRICS, MODES, SHARED, cases, digest, run


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
    for mode in MODES:
        key = f"{name}|{mode}"
        uv, Fuv, met = run(V, F, mode)
        ref = arrays[key]
        assert uv.shape == ref.shape, key
        extent = float(np.ptp(ref, axis=0).max())
        assert np.abs(uv - ref).max() <= 1e-9 * extent, (key, float(np.abs(uv - ref).max()))
        assert digest(uv) == table[key]["uv_sha"], f"{key}: same map to 1e-9 but not bit for bit"
        assert digest(np.asarray(Fuv, dtype=np.int64)) == table[key]["fuv_sha"], key
        for k in METRICS:
            a, b = met[k], table[key]["metrics"][k]
            assert a == b or (isinstance(a, float) and math.isclose(a, b, rel_tol=1e-12)), (key, k, a, b)
