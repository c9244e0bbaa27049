"""The ``heatparam`` command: unwrap, geodesics, evaluate, demo.

Bad input ends with one line on stderr (``heatparam: error: ...``), exit code 2, no traceback, and no output
file written or replaced.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from heatparam import __version__
from heatparam.errors import HeatparamError
from heatparam.pipeline import (
    FILL_MODES,
    GEODESIC_MODES,
    MDS_START_MODES,
    REFINE_MODES,
    SEAM_MODES,
    STRESS_MODES,
    Options,
)

EXIT_BAD_INPUT = 2


def _time_step(value: str) -> str | float:
    if value in ("default", "paper"):
        return value
    try:
        t = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'default', 'paper' or a positive number, got {value!r}") from None
    if not t > 0:
        raise argparse.ArgumentTypeError(f"time step must be positive, got {value}")
    return t


def _add_heat_options(p: argparse.ArgumentParser) -> None:
    d = Options()
    p.add_argument("--time-step", type=_time_step, default=d.time_step, metavar="{default,paper}|FLOAT",
                   help="heat diffusion time: default t = c·h² (scale-invariant), paper = Eq. 7 (longest edge), "
                        "or a number (default: %(default)s)")
    p.add_argument("--t-coef", type=float, default=d.t_coef, metavar="C",
                   help="the c in t = c·h² for --time-step default (default: %(default)s)")
    p.add_argument("--solver", choices=("auto", "cholespy", "scipy", "pardiso"), default=d.solver,
                   help="sparse Cholesky/LU backend (default: %(default)s = MKL PARDISO, where installed, for the "
                        "refinement and for the heat method on meshes of >= 100k vertices; CHOLMOD through "
                        "cholespy otherwise)")
    p.add_argument("--quiet", action="store_true", help="no progress output")


def build_parser() -> argparse.ArgumentParser:
    d = Options()
    ap = argparse.ArgumentParser(
        prog="heatparam",
        description="Near-isometric (true-scale) mesh parameterization: heat-method geodesics + MDS "
                    "(Mejia-Parra et al. 2019).",
    )
    ap.add_argument("--version", action="version", version=f"heatparam {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")

    u = sub.add_parser("unwrap", help="flatten a mesh and write an OBJ with UVs",
                       description="Flatten a disk-like mesh (with holes) into the plane at true scale.")
    u.add_argument("input", help="mesh file (.obj .off .ply .stl .glb)")
    u.add_argument("-o", "--output", required=True, help="output OBJ (v in input order; one vt per vertex, or per "
                   "seam side when the map has seams)")
    u.add_argument("--fill", choices=FILL_MODES, default=d.fill,
                   help="fill surface M* for holes/concave borders: auto decides from the mesh (and uses the "
                        "biharmonic fill), poisson = the paper's screened Poisson surface (default: %(default)s)")
    u.add_argument("--fill-depth", type=int, default=d.fill_depth, metavar="D",
                   help="octree depth of the Poisson reconstruction for --fill poisson (default: automatic "
                        "from the mesh's size and edge length, 6-9)")
    u.add_argument("--geodesics", choices=GEODESIC_MODES, default=d.geodesics,
                   help=f"all-pairs (paper), landmarks (O(n·k)), or auto: all-pairs up to "
                        f"{d.all_pairs_max} vertices (default: %(default)s)")
    u.add_argument("--landmarks", type=int, default=d.landmarks, metavar="K",
                   help="landmark count for the landmark path (default: automatic)")
    u.add_argument("--refine", choices=REFINE_MODES, default=d.refine,
                   help="sd = flip-free symmetric Dirichlet polish at true scale with overlap checks; none = the "
                        "paper's raw MDS map (default: %(default)s)")
    u.add_argument("--mds-start", choices=MDS_START_MODES, default=d.mds_start,
                   help="auto = with --refine sd, skip the fill, geodesics and MDS when the LSCM layout is already "
                        "bijective and within 0.1%% of an isometry (developable parts), or, from 30k vertices, when "
                        "the MDS layout of a 1/8 coarse mesh folds (curved scans): the same map, faster; "
                        "stress_rel_rms is then null; always = compute them as a start candidate anyway "
                        "(default: %(default)s)")
    u.add_argument("--seams", choices=SEAM_MODES, default=d.seams,
                   help="cut holes open to the border along the shortest surface paths: auto = when the map "
                        "without seams is more than 1%% from an isometry, keep the cut one if it lowers the mean "
                        "isometric distortion by 2%% or more (reported, with a warning); holes = always; none = "
                        "never, one uncut piece (default: %(default)s)")
    u.add_argument("--refine-multilevel", type=int, default=d.refine_multilevel, metavar="N",
                   help="meshes of at least N vertices are polished coarse-to-fine (a ~1/8-size coarse mesh "
                        "first; docs/refine.md); 0 = never (default: %(default)s)")
    u.add_argument("--stress", choices=STRESS_MODES, default=d.stress,
                   help="smacof = stress majorization of Eq. 1 on the geodesic distances after MDS, before "
                        "--refine (see BENCHMARKS.md §7); none = the MDS layout as is (default: %(default)s)")
    u.add_argument("--seed", type=int, default=d.seed, help="random seed (default: %(default)s)")
    u.add_argument("--report", metavar="R.json", help="write a JSON report (parameters, timings, metrics)")
    u.add_argument("--preview", metavar="P.png", help="write a PNG: UV layout coloured by distortion + 3D view")
    _add_heat_options(u)

    g = sub.add_parser("geodesics", help="heat-method geodesic distances from source vertices",
                       description="Write an (n, k) .npy array: column j = distances from source j.")
    g.add_argument("input", help="mesh file")
    g.add_argument("--source", type=int, nargs="+", required=True, metavar="I", help="source vertex indices")
    g.add_argument("-o", "--output", required=True, help="output .npy")
    _add_heat_options(g)

    e = sub.add_parser("evaluate", help="print distortion/bijectivity metrics of any OBJ with UVs",
                       description="Judge any tool's map (OBJ with vt) with heatparam's yardstick.")
    e.add_argument("input", help="OBJ with vt")
    e.add_argument("--report", metavar="R.json", help="also write the metrics as JSON")
    e.add_argument("--quiet", action="store_true", help="do not print the metrics")

    m = sub.add_parser("demo", help="run on a built-in generated surface (no download)",
                       description="Unwrap a generated S-shaped strip on a cone (exactly developable) "
                                   "and write OBJ, report and preview.")
    m.add_argument("-o", "--output-dir", default="heatparam-demo", help="folder for the outputs "
                   "(created; default: %(default)s)")
    m.add_argument("--quiet", action="store_true", help="no progress output")
    return ap


def _check_output(path: str, inputs: tuple[str, ...], suffix: str) -> Path:
    p = Path(path)
    if p.suffix.lower() != suffix:
        raise HeatparamError(f"output {p} must end in {suffix}")
    for i in inputs:
        if Path(i).exists() and p.exists() and p.resolve() == Path(i).resolve():
            raise HeatparamError(f"output {p} is the input file — choose another name (the input is never touched)")
    if not p.parent.resolve().is_dir():
        raise HeatparamError(f"cannot write {p}: folder {p.parent} does not exist")
    return p


def cmd_unwrap(args: argparse.Namespace) -> int:
    from heatparam import io
    from heatparam.pipeline import parameterize

    out = _check_output(args.output, (args.input,), ".obj")
    rep = _check_output(args.report, (args.input, args.output), ".json") if args.report else None
    prev = _check_output(args.preview, (args.input, args.output), ".png") if args.preview else None
    V, F = io.load_mesh(args.input)
    opts = Options(fill=args.fill, geodesics=args.geodesics, landmarks=args.landmarks, time_step=args.time_step,
                   t_coef=args.t_coef, solver=args.solver, seed=args.seed, refine=args.refine,
                   refine_multilevel=args.refine_multilevel, mds_start=args.mds_start, seams=args.seams,
                   stress=args.stress, fill_depth=args.fill_depth, progress=not args.quiet)
    result = parameterize(V, F, opts)
    result.report["input"] = str(args.input)
    _write_results(V, F, result, out, rep, prev, quiet=args.quiet)
    return 0


def _write_results(V, F, result, out: Path, rep: Path | None, prev: Path | None, quiet: bool) -> None:
    """Preview (optional), OBJ and report (optional) of a pipeline ``Result``, each written atomically."""
    from heatparam import io

    uv, report = result
    if prev is not None:
        from heatparam import render

        render.save_preview(prev, V[result.uv_vertex], result.Fuv, uv, title=Path(report.get("input", out.stem)).name,
                            fill_surface=result.fill_surface)
    io.save_uv_obj(out, V, F, uv, header=f"heatparam {__version__}: vt = true-scale UV (model units)",
                   Fuv=result.Fuv)
    if rep is not None:
        io.save_json(rep, report)
    if not quiet:
        m = report["metrics"]
        print(
            f"wrote {out}: {m['flips']} flipped, {m['boundary_crossings']} boundary crossings, "
            f"isometric distortion mean {m['iso_mean']:.4f} / p95 {m['iso_p95']:.4f}, "
            f"{sum(report['timings_s'].values()):.2f} s",
            file=sys.stderr,
        )


def cmd_geodesics(args: argparse.Namespace) -> int:
    import numpy as np

    from heatparam import heat, io
    from heatparam.mesh import validate_mesh
    from heatparam.operators import build_operators

    out = _check_output(args.output, (args.input,), ".npy")
    V, F = io.load_mesh(args.input)
    info = validate_mesh(V, F, flatten=False)  # distances need no boundary: closed scans are fine here
    src = np.asarray(args.source, dtype=np.int64)
    bad = src[(src < 0) | (src >= len(V))]
    if len(bad):
        raise HeatparamError(f"source vertex {int(bad[0])} is out of range (the mesh has {len(V)} vertices)")
    if not info.referenced[src].all():
        raise HeatparamError(f"source vertex {int(src[~info.referenced[src]][0])} is not used by any face")
    # operators on the referenced vertices; unreferenced ones are unreachable (inf)
    keep = np.flatnonzero(info.referenced)
    remap = np.full(len(V), -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    op = build_operators(V[keep], remap[F])
    t = heat.time_step(op, args.time_step, args.t_coef)
    warning = heat.underflow_warning(op, t) if args.time_step != "default" else None
    if warning:
        print(f"heatparam: warning: {warning}", file=sys.stderr)
    solver = heat.HeatGeodesics(op, t, backend=args.solver)
    D = np.full((len(V), len(src)), np.inf)
    D[keep] = solver.distances(remap[src])
    io.save_npy(out, D)
    if not args.quiet:
        extra = f" ({info.n_unreferenced} unreferenced vertices: inf)" if info.n_unreferenced else ""
        print(f"wrote {out}: distances from {len(src)} sources to {len(V)} vertices{extra}", file=sys.stderr)
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from heatparam import io, metrics
    from heatparam.mesh import validate_mesh

    rep = _check_output(args.report, (args.input,), ".json") if args.report else None
    V, F, UV, FUV = io.load_uv_obj(args.input)
    validate_mesh(V, F)
    if FUV.max() >= len(UV) or FUV.min() < 0:
        raise HeatparamError(f"{args.input}: texture coordinate index out of range")
    summary = metrics.summary(V, F, UV, FUV)
    if rep is not None:
        io.save_json(rep, {"input": str(args.input), "metrics": summary})
    if not args.quiet:
        print(json.dumps(summary, indent=2))
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from heatparam import shapes
    from heatparam.pipeline import parameterize

    outdir = Path(args.output_dir)
    if outdir.exists() and not outdir.is_dir():
        raise HeatparamError(f"{outdir} exists and is not a folder")
    outdir.mkdir(parents=True, exist_ok=True)
    shape = shapes.DEMO_SHAPE()
    result = parameterize(shape.V, shape.F, progress=not args.quiet)
    uv, report = result
    report["input"] = f"generated:{shape.name}"
    if shape.uv_true is not None:
        report["metrics"]["layout_error_rel"] = shapes.layout_error(uv, shape.uv_true[result.uv_vertex])
    _write_results(shape.V, shape.F, result, outdir / "demo.obj", outdir / "demo-report.json",
                   outdir / "demo-preview.png", quiet=args.quiet)
    if not args.quiet:
        print(f"demo: {shape.name} ({len(shape.V)} vertices) → {outdir}/demo.obj, demo-report.json, "
              "demo-preview.png", file=sys.stderr)
    return 0


COMMANDS = {"unwrap": cmd_unwrap, "geodesics": cmd_geodesics, "evaluate": cmd_evaluate, "demo": cmd_demo}


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except HeatparamError as exc:
        print(f"heatparam: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("heatparam: interrupted (no output written)", file=sys.stderr)
        return 130
    except MemoryError:
        print("heatparam: error: out of memory — use --geodesics landmarks or a smaller --landmarks",
              file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
