"""A batch's summaries: ``summary.json`` (everything), ``summary.csv`` (one row per input) and ``index.html`` (a
static table, sortable by any column, with each mesh's preview), all written atomically."""

from __future__ import annotations

import csv
import html
import io
from pathlib import Path

from heatparam.formats.files import atomic_write, save_json

#: The columns of a batch's rows (``summary.csv``'s header), one row per input; ``warnings``: the mesh's report's
#: warnings in command-line terms, joined by " | ".
COLUMNS = ("input", "output", "status", "reason", "vertices", "charts", "iso_mean", "flips", "crossings",
           "seconds", "peak_mem_mb", "warnings")


def write_summary(out: Path, summary: dict) -> None:
    """``summary.json``, ``summary.csv`` (one row per input, :data:`COLUMNS`) and ``index.html``, atomically.

    ``summary`` is :func:`heatparam.batching.run_batch`'s: its ``rows`` (dicts of :data:`COLUMNS`, paths relative
    to ``out``), ``counts``, ``wall_s`` and ``heatparam_version``.
    """
    save_json(out / "summary.json", summary)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in summary["rows"]:
        w.writerow({k: "" if r[k] is None else r[k] for k in COLUMNS})
    with atomic_write(out / "summary.csv") as fh:
        fh.write(buf.getvalue())
    with atomic_write(out / "index.html") as fh:
        fh.write(_gallery(out, summary))


_SORT_JS = """
document.querySelectorAll('th').forEach((th, col) => th.addEventListener('click', () => {
  const body = th.closest('table').tBodies[0], rows = Array.from(body.rows);
  const asc = th.dataset.asc !== '1'; th.dataset.asc = asc ? '1' : '0';
  const key = r => { const t = r.cells[col].dataset.v ?? r.cells[col].textContent; const x = parseFloat(t);
                     return isNaN(x) ? t : x; };
  rows.sort((a, b) => { const x = key(a), y = key(b); return (x > y ? 1 : x < y ? -1 : 0) * (asc ? 1 : -1); });
  rows.forEach(r => body.appendChild(r));
}));
"""


def _gallery(out: Path, summary: dict) -> str:
    """A static, sortable HTML table of the summary, with each mesh's preview when there is one."""
    cols = [c for c in COLUMNS if c != "output"]
    head = "".join(f"<th>{html.escape(c)}</th>" for c in ["preview", *cols])
    body = []
    for r in summary["rows"]:
        png = Path(r["output"]).with_suffix(".png").as_posix()
        img = (f'<a href="{html.escape(png)}"><img src="{html.escape(png)}" loading="lazy"></a>'
               if (out / png).is_file() else "")
        obj = html.escape(Path(r["output"]).as_posix())
        cells = [f"<td>{img}</td>"]
        for c in cols:
            v = r[c]
            text = "" if v is None else (f"{v:.4f}" if isinstance(v, float) and c == "iso_mean" else str(v))
            if c == "input" and r["status"] in ("ok", "skipped"):
                cells.append(f'<td><a href="{obj}">{html.escape(text)}</a></td>')
            else:
                cls = html.escape(r["status"]) if c == "status" else ""
                cells.append(f'<td class="{cls}">{html.escape(text)}</td>')
        body.append("<tr>" + "".join(cells) + "</tr>")
    counts = ", ".join(f"{n} {s}" for s, n in summary["counts"].items() if n)
    return (
        "<!doctype html><html><head><meta charset='utf-8'><title>heatparam batch</title><style>"
        "body{font-family:sans-serif;margin:1em}table{border-collapse:collapse}td,th{border:1px solid #ccc;"
        "padding:2px 6px;font-size:13px}th{cursor:pointer;background:#eee}img{height:80px}"
        ".refused{color:#b60}.failed{color:#c00}.ok{color:#070}</style></head><body>"
        f"<h1>heatparam batch</h1><p>{len(summary['rows'])} meshes: {html.escape(counts)}; "
        f"{summary['wall_s']:.1f} s; heatparam {html.escape(summary['heatparam_version'])}; click a column to sort."
        f"</p><table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"
        f"<script>{_SORT_JS}</script></body></html>\n"
    )
