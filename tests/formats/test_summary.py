"""A batch's summaries: summary.json, summary.csv and the index.html table."""

from __future__ import annotations

import csv
import json

from heatparam.formats.summary import COLUMNS, write_summary


def _summary() -> dict:
    ok = {"input": "/in/a.obj", "output": "a.obj", "status": "ok", "reason": "", "vertices": 10, "charts": 1,
          "iso_mean": 1.000123456, "flips": 0, "crossings": 0, "seconds": 0.5, "peak_mem_mb": 100.0,
          "warnings": "an atlas of 3 chart(s) | 2 zero-area faces"}
    bad = {**dict.fromkeys(COLUMNS), "input": "/in/<b>.off", "output": "<b>.obj", "status": "refused",
           "reason": "closed & small", "seconds": 0.0}
    return {"heatparam_version": "0", "rows": [ok, bad], "counts": {"ok": 1, "refused": 1, "failed": 0},
            "wall_s": 1.25}


def test_json_csv_and_html(tmp_path):
    (tmp_path / "a.png").write_bytes(b"png")
    write_summary(tmp_path, _summary())
    assert json.loads((tmp_path / "summary.json").read_text()) == _summary()
    rows = list(csv.DictReader((tmp_path / "summary.csv").open()))
    assert tuple(rows[0]) == COLUMNS and rows[1]["vertices"] == "" and rows[1]["reason"] == "closed & small"
    assert rows[0]["warnings"] == "an atlas of 3 chart(s) | 2 zero-area faces"
    page = (tmp_path / "index.html").read_text()
    assert "2 meshes: 1 ok, 1 refused; 1.2 s" in page  # counts of zero left out
    assert '<img src="a.png"' in page and page.count("<img") == 1  # a preview only where there is one
    assert '<a href="a.obj">/in/a.obj</a>' in page and ">1.0001<" in page
    assert "&lt;b&gt;.off" in page and "<b>" not in page.split("<body>")[1]  # names are escaped
    assert not list(tmp_path.glob(".*"))  # no temporary left
