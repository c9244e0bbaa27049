"""Progress output: a terminal gets stage announcements and tqdm bars; a log (stderr not a terminal) gets one
line per stage with its elapsed time and no carriage returns."""

from __future__ import annotations

import io
import re
import sys
import time

import numpy as np
import pytest

import heatparam
from heatparam import datasets
from heatparam.progress import Progress, stderr_is_tty

LINE = re.compile(r"^heatparam: (?P<stage>[a-z][a-z ]*)(?: \((?P<run>[a-z ,]+)\))?: (?P<s>\d+\.\d\d) s$")


class FakeTTY(io.StringIO):
    def isatty(self) -> bool:
        return True


def _run_bar(prog: Progress) -> None:
    """A stage with a bar that lives past tqdm's 1 s display delay."""
    with prog.stage("busy"), prog.bar(3, "busy", "step") as bar:
        for _ in range(3):
            time.sleep(0.4)
            bar.update(1)


def test_log_gets_one_line_per_stage_and_no_carriage_return(monkeypatch):
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    assert not stderr_is_tty()
    prog = Progress(enabled=True)
    _run_bar(prog)
    with prog.stage("quick"):
        pass
    out = err.getvalue()
    assert "\r" not in out
    lines = out.splitlines()
    assert [LINE.match(s)["stage"] for s in lines] == ["busy", "quick"]
    assert float(LINE.match(lines[0])["s"]) >= 1.1  # the elapsed time of the stage
    assert set(prog.timings) == {"busy", "quick"}


def test_terminal_keeps_bars(monkeypatch):
    """The same stage on a terminal: an announcement and a tqdm bar (carriage returns) — so the check above can
    fail."""
    err = FakeTTY()
    monkeypatch.setattr(sys, "stderr", err)
    _run_bar(Progress(enabled=True))
    out = err.getvalue()
    assert out.startswith("heatparam: busy ...\n")
    assert "\r" in out and "busy" in out.split("\n", 1)[1]


def test_quiet_writes_nothing(monkeypatch):
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    prog = Progress(enabled=False)
    _run_bar(prog)
    assert err.getvalue() == "" and "busy" in prog.timings


def test_pipeline_log_lines_match_its_timings(monkeypatch):
    """parameterize(progress=True) into a log: every line is a stage line (or a warning), no '\\r', and the stages
    named are those the report times."""
    s = datasets.cylinder_with_holes(h=0.09)
    rng = np.random.default_rng(0)
    V = s.V + 0.003 * rng.standard_normal(s.V.shape)
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    _, report = heatparam.parameterize(V, s.F, progress=True)
    out = err.getvalue()
    assert "\r" not in out
    lines = [x for x in out.splitlines() if not x.startswith("heatparam: warning:")]
    assert all(LINE.match(x) for x in lines), lines
    assert {LINE.match(x)["stage"] for x in lines} == set(report["timings_s"])


def test_passes_and_details_name_each_run(monkeypatch):
    """A stage run twice says which run it is (its detail, the pass it runs in); its timing stays keyed by the
    bare name, summed."""
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    prog = Progress(enabled=True)
    with prog.in_pass("map without seams"):
        with prog.stage("refine"):
            pass
        with prog.stage("geodesics", "landmarks"):
            pass
    with prog.stage("refine"):
        pass
    lines = err.getvalue().splitlines()
    assert [(LINE.match(x)["stage"], LINE.match(x)["run"]) for x in lines] == [
        ("refine", "map without seams"), ("geodesics", "landmarks, map without seams"), ("refine", None)]
    assert set(prog.timings) == {"refine", "geodesics"} and prog.pass_name == ""


def _stage_lines(out: str) -> list[re.Match]:
    lines = [x for x in out.splitlines() if not x.startswith("heatparam: warning:")]
    assert all(LINE.match(x) for x in lines), lines
    return [LINE.match(x) for x in lines]


def test_seams_stage_log_names_its_passes(monkeypatch):
    """A part whose holes are cut open (seams holes): the map without seams and the one with seams each get their
    lines, no line is repeated, and the lines add up to the report's timings."""
    s = datasets.cylinder_with_holes(h=0.09)
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    _, report = heatparam.parameterize(s.V, s.F, progress=True, seams="holes")
    lines = _stage_lines(err.getvalue())
    shown = [(m["stage"], m["run"]) for m in lines]
    assert len(shown) == len(set(shown)), shown
    assert ("refine", "map without seams") in shown and ("refine", "map with seams") in shown
    assert ("seams", "cut open") in shown
    printed = sum(float(m["s"]) for m in lines)
    assert printed == pytest.approx(sum(report["timings_s"].values()), abs=0.01 * len(lines))


def test_atlas_stage_times_add_up(monkeypatch):
    """An atlas (a closed mesh): the report times exactly the stages printed (the disk check, the atlas), so the
    atlas line is never more than the total."""
    s = datasets.closed_cube()
    V, F = (s.V, s.F) if hasattr(s, "V") else s[:2]
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    _, report = heatparam.parameterize(V, F, progress=True)
    lines = _stage_lines(err.getvalue())
    assert {m["stage"] for m in lines} == set(report["timings_s"]) == {"validate", "atlas"}
    assert report["timings_s"]["atlas"] <= sum(report["timings_s"].values())
    printed = sum(float(m["s"]) for m in lines)
    assert printed == pytest.approx(sum(report["timings_s"].values()), abs=0.01 * len(lines))
