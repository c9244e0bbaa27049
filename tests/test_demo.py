"""``heatparam demo``: the embedded noisy scan-like part, on which the paper's pipeline datasets the result (the heat
geodesics run and the MDS layout starts the refinement), and what the demo writes and says."""

from __future__ import annotations

import json

import numpy as np

from heatparam import datasets
from heatparam.cli import main
from heatparam.mesh import boundary_loops


def test_noisy_scan_part_is_deterministic_noisy_and_has_two_holes():
    a, b = datasets.noisy_scan_part(), datasets.noisy_scan_part()
    assert np.array_equal(a.V, b.V) and np.array_equal(a.F, b.F)
    assert not np.array_equal(a.V, datasets.noisy_scan_part(seed=1).V)
    assert 3000 <= len(a.V) <= 8000
    assert len(boundary_loops(a.F)) == 3  # outer border + two holes
    clean = datasets.bend_cylinder(a.uv_true, 100.0)
    edge = np.mean(np.linalg.norm(clean[a.F[:, 1]] - clean[a.F[:, 0]], axis=1))
    sigma = np.std(a.V - clean)
    assert 0.08 * edge < sigma < 0.12 * edge  # noise 0.1 x the mean edge
    # the flat layout is in mm: a 240 x 180 mm pattern
    assert np.allclose(np.ptp(a.uv_true, axis=0), [240.0, 180.0], rtol=1e-3)


def test_demo_runs_the_heat_stage_and_starts_from_the_better_layout(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "-o", str(out)]) == 0
    for name in ("demo.obj", "demo-report.json", "demo-preview.png"):
        assert (out / name).stat().st_size > 0
    assert (out / "demo-preview.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    report = json.loads((out / "demo-report.json").read_text())
    method = report["method"]
    assert report["input"] == "generated:noisy_scan_part"
    # the heat geodesics ran (not "skipped: ...") and the lower-energy of the MDS and conformal layouts started the
    # refinement
    assert method["geodesics"] in ("landmarks", "all-pairs")
    start = method["refine"]["start"]
    assert set(start["energy"]) == {"mds", "conformal"}
    assert start["layout"] == min(start["energy"], key=start["energy"].get)
    assert method["fill"]["used"]
    m = report["metrics"]
    assert m["bijective"] and m["flips"] == 0
    assert m["layout_error_rel"] < 0.02
    label = f"{start['layout'].upper()} layout"
    assert report["demo"]["stages"]["start"].startswith(label)
    err = capsys.readouterr().err
    stages = [x for x in err.splitlines() if x.startswith("demo: stages:")]
    assert len(stages) == 1
    assert "geodesics: ran" in stages[0] and f"start: {label}" in stages[0] and "fill: " in stages[0]
    assert "seams: " in stages[0]
    assert "\r" not in err  # captured stderr is not a terminal: one line per stage
