"""The one table of output formats: every command reads it, and it loads no numerics."""

from __future__ import annotations

import subprocess
import sys

import pytest

from heatparam.errors import HeatparamError
from heatparam.formats import exporters
from heatparam.formats.outputs import plan_outputs


def test_each_suffix_names_one_format():
    suffixes = [s for e in exporters.EXPORTERS for s in e.suffixes]
    assert len(suffixes) == len(set(suffixes)) and all(s.startswith(".") and s == s.lower() for s in suffixes)
    assert exporters.by_suffix(".STP").name == "step" and exporters.by_suffix(".gif") is None
    assert list(exporters.BY_NAME) == [e.name for e in exporters.EXPORTERS]


def test_map_and_batch_formats():
    assert exporters.map_formats() == ("obj", "ply", "glb", "dxf", "svg", "step")
    assert exporters.batch_formats() == ("obj", "json", "ply", "glb", "dxf", "svg", "step")
    for e in exporters.EXPORTERS:
        e.check_importable()  # every writer module of this installation imports
        assert e.missing_requirement() is None
        assert (e.write is None) == (e.name == "npy")  # every run output has its writer


def test_plan_outputs_reads_the_table():
    assert [p.format for p in plan_outputs(["a.obj", "b.Glb", ("r.json", {"json"}), ("p.png", {"png"})])] == [
        "obj", "glb", "json", "png"]
    with pytest.raises(HeatparamError, match=r"\.dxf, \.glb, \.obj, \.ply, \.step, \.stp, \.svg"):
        plan_outputs(["a.png"])  # the preview is not a map format


def test_an_unimportable_writer_is_one_line(monkeypatch):
    monkeypatch.setitem(sys.modules, "heatparam.formats.step", None)
    with pytest.raises(HeatparamError, match=r"STEP output \(\.step/\.stp\) is unavailable in this installation"):
        exporters.BY_NAME["step"].check_importable()


def test_reading_the_table_loads_no_numerics():
    code = ("import sys; from heatparam.formats import exporters; exporters.batch_formats(); "
            "print(sorted(m for m in ('numpy', 'scipy', 'matplotlib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
