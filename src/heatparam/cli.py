"""The ``heatparam`` command: unwrap, batch, geodesics, evaluate, demo.

The unwrap options are generated from ``heatparam.options.OPTIONS`` (choices, defaults and help written once).
Bad input ends with one line on stderr (``heatparam: error: ...``), exit code 2, no traceback, and no output
file written or replaced. Importing this module loads no numerics: ``heatparam --help`` is fast.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import textwrap
from pathlib import Path

from heatparam.errors import HeatparamError
from heatparam.options import (
    GRAIN_RULES,
    GROUPS,
    NEST_TIME,
    UNITS,
    Option,
    check_value,
    cli_options,
    make_options,
    to_cli_terms,
)
from heatparam.version import __version__

EXIT_BAD_INPUT = 2
#: options shared by ``unwrap`` and ``geodesics`` (the heat method's own)
HEAT_OPTIONS = ("time_step", "t_coef", "solver")


def _parse_value(opt: Option):
    """argparse ``type`` for a table option: the string converted and checked by the table's rules."""

    def parse(text: str):
        value: object = text
        if opt.kind == "int":
            try:
                value = int(text)
            except ValueError:
                raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        elif opt.kind == "float" or (opt.kind == "time" and text not in opt.choices):
            try:
                value = float(text)
            except ValueError:
                expect = "'default', 'paper' or a positive number" if opt.kind == "time" else "a number"
                raise argparse.ArgumentTypeError(f"expected {expect}, got {text!r}") from None
        try:
            return check_value(opt, value)
        except HeatparamError as exc:  # argparse names the flag ("argument --x: ..."): not the API name too
            rule = str(exc).removeprefix(f"{opt.name} ").split("; got")[0]
            raise argparse.ArgumentTypeError(f"{rule}; got {text}") from None

    return parse


def _number(text: str, what: str, ok, integer: bool = False) -> float:
    """argparse ``type``: ``text`` as an int (``integer``) or a float for which ``ok`` holds; else "expected
    ``what``"."""
    try:
        value = int(text) if integer else float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
    if not ok(value):
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return value


def _positive(text: str) -> float:
    return _number(text, "a positive finite number", lambda v: 0 < v < math.inf)


def _nonnegative(text: str) -> float:
    return _number(text, "a finite number of at least 0", lambda v: 0 <= v < math.inf)


def _positive_int(text: str) -> int:
    return _number(text, "a whole number of at least 1", lambda v: v >= 1, integer=True)


#: Where the options' one-line help starts (columns): at 100 columns the choice flags fit beside their help; on a
#: narrower terminal the help starts earlier, so that it keeps its one line and the long flags get a line of their own.
WIDE_HELP_COLUMN, NARROW_HELP_COLUMN = 42, 26

UNWRAP_DESCRIPTION = (
    "Flatten a mesh into the plane at true scale (UVs in model units). A disk, with or without holes, becomes one "
    "bijective map; any other mesh (closed, with handles, several parts, non-manifold) an atlas of charts, each "
    "within --max-distortion. Writes each -o (its extension picks the format), --report and --preview.")
UNWRAP_EXAMPLES = """examples:
  heatparam unwrap part.obj -o part_uv.obj -o part.dxf --report part.json
  heatparam unwrap scan.ply -o scan.glb --geodesics landmarks --landmarks 300
  heatparam unwrap cow.off -o cow.svg --strain-map        # closed: an atlas
  heatparam unwrap cow.off -o cow.obj --max-distortion 1.03 --pack texture
  heatparam unwrap part.stl -o part.step --units in --fit-tolerance 0.01

Each option at length: docs/options.md; the output formats: docs/formats.md."""
BATCH_EXAMPLES = """examples:
  heatparam batch scans/ -o out --format obj,dxf,svg --workers 8
  heatparam batch 'parts/*.stl' -o out --scheduler tcp://host:8786

Rerun the same command to resume (--force redoes all). Each pipeline option at length: docs/options.md."""
DEMO_DESCRIPTION = (
    "Flatten a generated scan-like part (a 240 x 180 mm cylinder patch with two holes and scanner noise) and write "
    "its OBJ, DXF, SVG (strain map), STEP, report and preview. The paper's stages run on it: a fill over the holes, "
    "heat geodesics and MDS, whose layout competes with the conformal one to start the bijective polish (the "
    "conformal one wins here). The log says which stages ran and why.")


class _Help(argparse.RawDescriptionHelpFormatter):
    """--help with one line per option: the description filled to the terminal's width, a paragraph with indented
    lines (the examples) kept as written."""

    def __init__(self, prog: str):
        width = shutil.get_terminal_size().columns - 2
        super().__init__(prog, max_help_position=min(WIDE_HELP_COLUMN, max(NARROW_HELP_COLUMN, width - 56)))

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        raw = super()._fill_text
        return "\n\n".join(raw(p, width, indent) if "\n  " in p else
                           textwrap.fill(p, width, initial_indent=indent, subsequent_indent=indent,
                                         break_on_hyphens=False)
                           for p in text.split("\n\n"))


def _add_batch_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``heatparam batch``: its own in their groups, then the option table's (``--help`` order)."""
    from heatparam.batching import MESH_SUFFIXES
    from heatparam.formats.exporters import batch_formats

    p.add_argument("inputs", nargs="+", metavar="INPUT", help="mesh files, folders (searched recursively for "
                   f"{' '.join(MESH_SUFFIXES)}) or globs")
    g = p.add_argument_group("outputs")
    g.add_argument("-o", "--output-dir", required=True, metavar="OUTDIR",
                   help="folder: <path>/<stem>.*, summary.csv/.json, index.html")
    g.add_argument("--format", default="obj", metavar="FMT[,FMT...]",
                   help=f"formats: {','.join(batch_formats())} (default: %(default)s)")
    g.add_argument("--preview", action="store_true", help="also write <stem>.png previews (in index.html)")
    g.add_argument("--force", action="store_true", help="redo inputs whose outputs are up to date")
    g.add_argument("--units", choices=UNITS, help="the models' units, as unwrap's --units, for every mesh "
                   "(default: mm, with a warning per mesh under 10 mm or over 100 m across)")
    g = p.add_argument_group("cluster")
    g.add_argument("--workers", type=_positive_int, metavar="N",
                   help="local Dask worker processes (default: one per core)")
    g.add_argument("--scheduler", metavar="ADDRESS",
                   help="Dask scheduler (tcp://host:8786 or its JSON file)")
    g.add_argument("--task-timeout", type=_positive, metavar="S",
                   help="seconds one mesh may take, then failed (default: no limit)")
    g.add_argument("--task-memory", metavar="SIZE",
                   help="memory of one mesh's process, e.g. 4GB (default: the worker's)")
    _add_option_groups(p)


def _add_option(p: argparse.ArgumentParser | argparse._ArgumentGroup, opt: Option) -> None:
    kw: dict = {"default": opt.default, "help": opt.short.replace("%", "%%") + " (default: %(default)s)"}
    if opt.kind == "choice":
        kw["choices"] = opt.choices
    else:
        kw["type"] = _parse_value(opt)
        kw["metavar"] = opt.metavar
    p.add_argument(opt.flag, dest=opt.name, **kw)


def _add_option_groups(p: argparse.ArgumentParser) -> None:
    """The table's options (``options.cli_options``) as flags of ``p`` in their groups (``options.GROUPS``), with
    ``--quiet`` and ``--help`` in the last."""
    groups = {key: p.add_argument_group(title) for key, title in GROUPS.items()}
    for opt in cli_options():
        _add_option(groups[opt.group], opt)
    run = groups[next(reversed(GROUPS))]
    run.add_argument("--quiet", action="store_true", help="no progress output")
    run.add_argument("-h", "--help", action="help", help="show this help and exit")


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (no usage block): ``heatparam: error: <what>; see heatparam <cmd> --help``."""

    def error(self, message: str):
        cmd = self.prog.split()[-1] if " " in self.prog else ""
        self.exit(EXIT_BAD_INPUT, f"heatparam: error: {message} (see heatparam {cmd + ' ' if cmd else ''}--help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The ``heatparam`` parser: one subcommand per ``COMMANDS`` entry."""
    ap = _Parser(
        prog="heatparam",
        description="Near-isometric (true-scale) mesh parameterization: heat-method geodesics + MDS "
                    "(Mejia-Parra et al. 2019).",
    )
    ap.add_argument("--version", action="version", version=f"heatparam {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)
    for add in (_add_unwrap, _add_batch, _add_geodesics, _add_evaluate, _add_demo):
        add(sub)
    return ap


def _add_unwrap(sub) -> None:
    from heatparam.batching import MESH_SUFFIXES
    from heatparam.formats.exporters import BY_NAME, map_formats

    u = sub.add_parser("unwrap", help=f"flatten any mesh at true scale ({', '.join(map_formats()).upper()}, report, "
                       "preview)", description=UNWRAP_DESCRIPTION, epilog=UNWRAP_EXAMPLES, formatter_class=_Help,
                       usage="%(prog)s input -o OUT [-o OUT ...] [options]", add_help=False)
    u.add_argument("input", help=f"mesh file ({' '.join(MESH_SUFFIXES)})")
    g = u.add_argument_group("outputs")
    g.add_argument("-o", "--output", required=True, action="append", metavar="OUT",
                   help=f"output, repeatable: {' '.join(BY_NAME[f].suffixes[0] for f in map_formats())}")
    g.add_argument("--report", metavar="R.json", help="write the JSON report (parameters, timings, metrics)")
    g.add_argument("--preview", metavar="P.png", help="write a PNG: the layout by distortion + 3D view")
    g.add_argument("--units", choices=UNITS, help="the model's units, stated in every output and message "
                   "(default: mm, with a warning when the part would be under 10 mm or over 100 m across)")
    g.add_argument("--sheet", metavar="WxH", help="DXF/SVG: charts on sheets of this size")
    g.add_argument("--gap", type=_positive, metavar="G", help="--sheet: spacing between pieces and to the edge, "
                   "model units (default: 0.5%% of the sheet's shorter side)")
    g.add_argument("--grain", choices=GRAIN_RULES, default="free", help="--sheet: none keeps each piece's direction, "
                   "180 allows a half turn, free quarter turns too (default: %(default)s)")
    g.add_argument("--nest-time", type=_nonnegative, default=NEST_TIME, metavar="S", help="--sheet: seconds to "
                   "nest the pieces by their outlines; 0 = boxes on shelves (default: %(default)s)")
    g.add_argument("--strain-map", action="store_true", help="SVG: faces coloured by distortion, with a legend")
    g.add_argument("--fit-tolerance", type=_positive, metavar="TOL",
                   help="STEP: fit tolerance (default: 0.1%% of the diagonal)")
    _add_option_groups(u)


def _add_options(p: argparse.ArgumentParser, only=None) -> None:
    """The table's options (``options.cli_options``) as flags of ``p``; ``only``: those names alone."""
    for opt in cli_options():
        if only is None or opt.name in only:
            _add_option(p, opt)


def _add_batch(sub) -> None:
    b = sub.add_parser("batch", help="flatten many meshes (files, folders, globs) on a Dask cluster",
                       description="Run the unwrap pipeline on every mesh found, one task per mesh, on a local Dask "
                                   "cluster (default) or the scheduler at --scheduler; resumable; writes "
                                   "OUTDIR/summary.csv, summary.json and index.html.",
                       epilog=BATCH_EXAMPLES, formatter_class=_Help, add_help=False,
                       usage="%(prog)s INPUT [INPUT ...] -o OUTDIR [options]")
    _add_batch_arguments(b)


def _add_geodesics(sub) -> None:
    g = sub.add_parser("geodesics", help="heat-method geodesic distances from source vertices",
                       description="Write an (n, k) .npy array: column j = distances from source j.")
    g.add_argument("input", help="mesh file")
    g.add_argument("--source", nargs="+", required=True, metavar="I", help="source vertex indices")
    g.add_argument("-o", "--output", required=True, help="output .npy")
    _add_options(g, only=HEAT_OPTIONS)
    g.add_argument("--quiet", action="store_true", help="no progress output")


def _add_evaluate(sub) -> None:
    e = sub.add_parser("evaluate", help="print distortion/bijectivity metrics of any OBJ with UVs",
                       description="Judge any tool's map (OBJ with vt) with heatparam's yardstick.")
    e.add_argument("input", help="OBJ with vt")
    e.add_argument("--report", metavar="R.json", help="also write the metrics as JSON")
    e.add_argument("--quiet", action="store_true", help="do not print the metrics")


def _add_demo(sub) -> None:
    m = sub.add_parser("demo", help="run on a built-in generated surface (no download)",
                       description=DEMO_DESCRIPTION)
    m.add_argument("-o", "--output-dir", default="heatparam-demo", help="folder for the outputs "
                   "(created; default: %(default)s)")
    m.add_argument("--quiet", action="store_true", help="no progress output")


def cmd_unwrap(args: argparse.Namespace) -> int:
    from heatparam.progress import print_warning
    from heatparam.unwrap import plan, unwrap_planned

    plans = plan(args.output, args.report, args.preview, inputs=(args.input,))
    sheet = None
    if args.sheet:
        from heatparam.formats.pattern import Sheets, parse_sheet

        sheet = Sheets(parse_sheet(args.sheet), args.gap, args.grain, args.nest_time, args.seed)
    formats = {pl.format for pl in plans}
    for flag, used, where in (("--sheet", args.sheet, ("dxf", "svg")), ("--strain-map", args.strain_map, ("svg",)),
                              ("--fit-tolerance", args.fit_tolerance, ("step",))):
        if used and not formats & set(where):
            print_warning(f"{flag} applies to {' and '.join('.' + w for w in where)} outputs only (none requested)")
    opts = make_options(progress=not args.quiet, **{o.name: getattr(args, o.name) for o in cli_options()})
    unwrap_planned(args.input, plans, options=opts, quiet=args.quiet, units=args.units, sheet=sheet,
                   strain_map=args.strain_map, fit_tolerance=args.fit_tolerance)
    return 0


def cmd_geodesics(args: argparse.Namespace) -> int:
    from heatparam.formats import load_mesh, save_npy
    from heatparam.formats.outputs import plan_outputs
    from heatparam.heat import geodesic_distances
    from heatparam.progress import print_warning

    out = plan_outputs([(args.output, {"npy"})], inputs=(args.input,))[0].path
    sources = []
    for s in args.source:
        try:
            sources.append(int(s))
        except ValueError:
            raise HeatparamError(f"source {s!r} is not a vertex index (an integer)") from None
    V, F = load_mesh(args.input)
    D, warning = geodesic_distances(V, F, sources, args.time_step, args.t_coef, args.solver)
    if warning:
        print_warning(warning)
    from heatparam import interrupt

    with interrupt.deferred():
        save_npy(out, D)
    if not args.quiet:
        unreached = int((~(D < float("inf"))).all(axis=1).sum())
        extra = f" ({unreached} unreferenced vertices: inf)" if unreached else ""
        print(f"wrote {out}: distances from {len(sources)} sources to {len(V)} vertices{extra}", file=sys.stderr)
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from heatparam import metrics
    from heatparam.formats import load_uv_obj, save_json
    from heatparam.formats.outputs import plan_outputs
    from heatparam.mesh.validate import check_arrays

    rep = plan_outputs([(args.report, {"json"})], inputs=(args.input,))[0].path if args.report else None
    V, F, UV, FUV = load_uv_obj(args.input)
    check_arrays(V, F)  # any mesh the metrics can judge: an atlas of a closed or multi-part mesh too
    if FUV.max() >= len(UV) or FUV.min() < 0:
        raise HeatparamError(f"{args.input}: texture coordinate index out of range")
    summary = metrics.summary(V, F, UV, FUV)
    if rep is not None:
        from heatparam import interrupt

        with interrupt.deferred():
            save_json(rep, {"input": str(args.input), "metrics": summary})
    if not args.quiet:
        print(json.dumps(summary, indent=2))
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from heatparam import demo

    outdir = Path(args.output_dir)
    if outdir.exists() and not outdir.is_dir():
        raise HeatparamError(f"{outdir} exists and is not a folder")
    outdir.mkdir(parents=True, exist_ok=True)
    _, summary = demo.run(outdir, quiet=args.quiet)
    if not args.quiet:
        print(f"demo: {summary['surface']} ({summary['vertices']} vertices, {summary['units']}, noise "
              f"{summary['noise']}) → {outdir}/{', '.join(summary['outputs'])}", file=sys.stderr)
        print("demo: stages: " + "; ".join(f"{k}: {v}" for k, v in summary["stages"].items()), file=sys.stderr)
    return 0


def cmd_batch(args: argparse.Namespace) -> int:
    """``heatparam batch``: 0 when every mesh succeeded (or was up to date), 1 when any failed or was refused
    (listed on stderr); usage errors raise HeatparamError (exit 2)."""
    from heatparam.batching import run_batch

    try:
        summary = run_batch(args.inputs, args.output_dir, formats=args.format, force=args.force,
                            workers=args.workers, scheduler=args.scheduler, task_timeout=args.task_timeout,
                            task_memory=args.task_memory, preview=args.preview, progress=not args.quiet,
                            options=make_options(**{o.name: getattr(args, o.name) for o in cli_options()},
                                                 **({"unit_name": args.units} if args.units else {})))
    except KeyboardInterrupt:
        print(f"heatparam: interrupted: the meshes in flight were dropped; {args.output_dir}/summary.json lists "
              "what is done — rerun the same command to resume", file=sys.stderr)
        return 130
    bad = [r for r in summary["rows"] if r["status"] in ("failed", "refused")]
    c = summary["counts"]
    if not args.quiet or bad:
        print(f"heatparam: {len(summary['rows'])} meshes: {c['ok']} ok, {c['skipped']} up to date, "
              f"{c['refused']} refused, {c['failed']} failed in {summary['wall_s']:.1f} s → "
              f"{Path(args.output_dir) / 'summary.csv'}", file=sys.stderr)
    warned = sum(1 for r in summary["rows"] if r["status"] in ("ok", "skipped") and r.get("warnings"))
    if warned and not args.quiet:
        print(f"heatparam: {warned} of the meshes flattened have warnings: see the warnings column of "
              f"{Path(args.output_dir) / 'summary.csv'}", file=sys.stderr)
    for r in bad:  # the file named once (a reader's message names it already)
        where = "" if r["input"] in r["reason"] else f"{r['input']}: "
        print(f"heatparam: {r['status']}: {where}{to_cli_terms(r['reason'])}", file=sys.stderr)
    return 1 if bad else 0


COMMANDS = {"unwrap": cmd_unwrap, "batch": cmd_batch, "geodesics": cmd_geodesics, "evaluate": cmd_evaluate,
            "demo": cmd_demo}


def main(argv: list[str] | None = None) -> int:
    """Run one command; returns the exit code (0, 2 for bad input, 130 when interrupted).

    A SIGINT handler (``interrupt.handling``) is installed first, so Ctrl-C at any moment — in an import that
    swallows ``KeyboardInterrupt`` too — ends with one line, exit code 130 and nothing written. The console script
    enters through ``heatparam.__main__.main``, which installs it before this module's imports.
    """
    from heatparam import interrupt

    with interrupt.handling():
        try:
            args = build_parser().parse_args(argv)
            code = _run(args)
            if interrupt.interrupted():  # it came while the outputs were being written: they were completed
                print("heatparam: interrupted while writing the outputs: they were completed first", file=sys.stderr)
            return code
        except KeyboardInterrupt:
            print("heatparam: interrupted (no output written)", file=sys.stderr)
            return 130


def _run(args: argparse.Namespace) -> int:
    from heatparam import interrupt

    try:
        if args.command != "batch":  # the numerics (numpy, scipy, libigl) load here, an interrupt only noted
            with interrupt.noted():
                import heatparam.pipeline  # noqa: F401
        return COMMANDS[args.command](args)
    except HeatparamError as exc:
        print(f"heatparam: error: {to_cli_terms(str(exc))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except MemoryError:
        print("heatparam: error: out of memory — use --geodesics landmarks or a smaller --landmarks",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    except Exception as exc:  # noqa: BLE001 - a failure no stage anticipated: one line, never a traceback
        if os.environ.get("HEATPARAM_DEBUG"):
            raise
        print(f"heatparam: error: the computation failed ({type(exc).__name__}) — the mesh may be too degenerate; "
              "set HEATPARAM_DEBUG=1 to see where, and please report it", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
