"""The unwrap job's units: the unit assumed when none is given (said once when the part is implausible in it) and
the unit every length in its messages carries."""

from __future__ import annotations

import json

import numpy as np
import pytest

from heatparam import datasets
from heatparam.cli import main
from heatparam.formats.units import assumed_units_warning
from heatparam.options import make_options
from heatparam.unwrap import unwrap_file

from conftest import shared_mesh


def write_off(path, V, F):
    with open(path, "w") as fh:
        fh.write(f"OFF\n{len(V)} {len(F)} 0\n")
        np.savetxt(fh, V)
        np.savetxt(fh, np.column_stack([np.full(len(F), 3), F]), fmt="%d")


def test_assumed_unit_is_said_once_when_implausible(tmp_path, capsys):
    """The cow is 1.04 units across: read as mm without --units, a single stderr line says so and what to pass, and
    the report keeps it; with --units m nothing is said."""
    cow = shared_mesh("cow.off")
    assert main(["unwrap", str(cow), "-o", str(tmp_path / "c.obj"), "--report", str(tmp_path / "c.json")]) == 0
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if "no --units given" in x]
    assert len(lines) == 1 and lines[0].startswith("heatparam: warning:") and "1.04 mm across" in lines[0]
    assert "--units" in lines[0].split("across", 1)[1]  # says what to pass
    report = json.loads((tmp_path / "c.json").read_text())
    assert report["units"] == "mm" and report["units_assumed"] is True
    assert sum("no --units given" in w for w in report["warnings"]) == 1
    assert main(["unwrap", str(cow), "-o", str(tmp_path / "m.obj"), "--units", "m", "--report",
                 str(tmp_path / "m.json")]) == 0
    assert "no --units given" not in capsys.readouterr().err
    report = json.loads((tmp_path / "m.json").read_text())
    assert report["units"] == "m" and report["units_assumed"] is False and report["parameters"]["unit_name"] == "m"


@pytest.mark.parametrize("size_mm,said", [(0.5, True), (5.0, True), (50.0, False), (5e4, False), (2e5, True)])
def test_plausible_sizes(size_mm, said):
    w = assumed_units_warning(size_mm)
    assert (w is not None) == said
    if said:
        assert "pass --units" in w and ("under 10 mm" in w if size_mm < 10 else "over 100 m" in w)


def test_seam_lengths_carry_the_unit(tmp_path):
    """The seams warning names the unit the lengths are in: the unit given, or mm assumed."""
    s = datasets.cylinder_with_holes(h=0.09)
    write_off(tmp_path / "p.off", 100 * s.V, s.F)  # 100 mm-ish across: a plausible part
    r = unwrap_file(tmp_path / "p.off", tmp_path / "p.obj", units="cm", options=make_options(seams="holes"))
    seams = [w for w in r.report["warnings"] if w.startswith("the map has seams")]
    assert len(seams) == 1 and " cm long in all" in seams[0]
    assert not r.report["units_assumed"] and not any("no --units" in w for w in r.report["warnings"])


def test_faces_repeating_a_vertex_are_left_out_with_a_warning(tmp_path):
    """A face that repeats a vertex index is a segment or a point (an STL triangle whose corners merged, as in
    pybullet's l_finger_collision.stl; OpenMesh's cube-minimal-degenerated.obj): the file's surface flattens, the
    warning says how many were left out, the outputs hold the other faces. A file of nothing else is refused."""
    from heatparam.errors import HeatparamError
    from heatparam.formats import load_uv_obj

    s = datasets.flat_square(h=0.25)
    F = np.vstack([s.F, [[0, 0, 1], [2, 3, 3]]])
    write_off(tmp_path / "p.off", s.V, F)
    r = unwrap_file(tmp_path / "p.off", tmp_path / "p.obj", units="mm")
    assert r.report["warnings"][0].startswith("2 faces repeat a vertex index"), r.report["warnings"]
    V2, F2, UV, _ = load_uv_obj(tmp_path / "p.obj")
    assert np.array_equal(F2, s.F) and np.isfinite(UV).all()
    write_off(tmp_path / "q.off", s.V, np.array([[0, 0, 1], [2, 3, 3]]))
    with pytest.raises(HeatparamError, match="repeat a vertex index"):
        unwrap_file(tmp_path / "q.off", tmp_path / "q.obj", units="mm")
