"""Every knob of the pipeline, declared once: the :data:`OPTIONS` table drives :class:`Options` (the API), its
validation, the command line (``cli``: flags, groups and one-line ``--help``) and docs/options.md
(:func:`options_markdown`: the long explanations).

No numerics are imported here: ``heatparam --help`` reads this table and nothing else.

The policy thresholds the help texts quote (and the stages use) live here too, each with the reason for its value.
"""

from __future__ import annotations

import math
import re
from dataclasses import asdict, field, make_dataclass
from typing import Any, NamedTuple

from heatparam.errors import HeatparamError

FILL_MODES = ("auto", "poisson", "biharmonic", "none")
GEODESIC_MODES = ("auto", "all-pairs", "landmarks")
STRESS_MODES = ("none", "smacof")
MDS_START_MODES = ("auto", "always", "never")
SEAM_MODES = ("auto", "holes", "none")
PACK_MODES = ("scale", "texture")
REFINE_MODES = ("none", "sd")
MASS_KINDS = ("lumped", "consistent")
TIME_STEPS = ("default", "paper")
BACKENDS = ("auto", "cholespy", "scipy", "pardiso")
#: the model units the outputs can declare (``formats.units``; listed here so that --help loads nothing)
UNITS = ("mm", "cm", "m", "in", "ft")
#: the rotations a pattern piece may take on a sheet (``--grain``): none (the grain kept), a half turn, or free
#: (quarter turns of the piece and of its minimum-area rectangle's frame)
GRAIN_RULES = ("none", "180", "free")
#: seconds the sheet nesting may search by default (``--nest-time``; 0 = the shelf packing of boxes): the first
#: ordering always runs; the bunny's 26 charts take about 1 s on one sheet
NEST_TIME = 3.0

#: With ``mds_start auto`` the heat geodesics and MDS are skipped when the conformal start is bijective and its energy
#: exceeds an isometry's (1) by at most this: no start can be better by more than this, and the polish converges
#: from it in 0-3 iterations. The MDS start's excess measured 2.7e-3 to 0.34 on every surface tried
#: (docs/refine.md), so skipping changed no start.
ISOMETRIC_START_EXCESS = 1e-3
#: On meshes of at least this many vertices whose conformal start is bijective the heat geodesics and MDS are skipped
#: too: there the polish from the conformal layout reached the same map quality in less time on every part measured,
#: even where MDS had the lower start energy (the iso mean equal to 6 digits; docs/history.md §13b). Where the
#: conformal layout is not bijective (strong scan noise; halftunnel without seams) the heat stage runs: MDS may be
#: the only bijective start.
CONFORMAL_START_MIN_VERTICES = 30_000
#: ``seams auto`` keeps the cut-open map only when it lowers the mean isometric distortion by at least this fraction
#: (halftunnel 1.536 → 1.18, beetle 1.080 → 1.02) ...
SEAM_MIN_GAIN = 0.02
#: ... so it tries the cut-open mesh only when the map without seams exceeds 1 by more than this (2.04%): every map's
#: mean isometric distortion is at least 1 (max(σ1, 1/σ2) ≥ 1 on every face), so below 1 / (1 - SEAM_MIN_GAIN) no
#: cut map can be kept and the trial is wasted (noisy parts with holes, iso mean 1.013, would cut for nothing).
SEAM_TRY_EXCESS = 1.0 / (1.0 - SEAM_MIN_GAIN) - 1.0
#: ``seams auto`` decides on paused polishes: each of the two flattenings (without and with seams) pauses once a
#: Newton iteration gains less than this fraction of the energy's excess over an isometry (the map without seams
#: at its coarse levels too, ``pipeline.seams.seam_pause``) ...
SEAM_PAUSE_EXCESS = 0.03
#: ... and the decision is taken there when it holds for any finished iso mean between this fraction of the paused
#: map's excess (iso mean - 1) and all of it (the polish lowers it); otherwise both are finished first. Only the
#: kept map is finished: the same map, the same iterations as without pausing. Finished excess / paused excess
#: measured 0.908-1.000 on 12 maps (docs/history.md §11c); a lower floor leaves close decisions undecided, and both
#: maps are then finished.
SEAM_PAUSE_FLOOR = 0.75
#: Default of ``refine_multilevel``: meshes this large polish coarse-to-fine (docs/refine.md).
MULTILEVEL_MIN_VERTICES = 30_000
#: Largest vertex count for which ``geodesics auto`` takes the all-pairs path (n×n distances).
ALL_PAIRS_MAX = 3000
#: Largest ``t_coef``: t = c·h² with c beyond this diffuses across any mesh of up to ~10⁴ edges in one step (the
#: distances then carry no information) and makes the heat system's matrix lose positive definiteness in floating
#: point (``t_coef 1e300`` on halftunnel).
T_COEF_MAX = 1e4


class Option(NamedTuple):
    """One knob: its name (the Options field), default, kind (``choice``, ``int``, ``float``, ``time``, ``bool``),
    the allowed values or range, the full explanation (``help``: ``{default}`` and the constants above may be
    quoted; docs/options.md), whether the command line offers it (``flag``: the CLI spelling, None = API only), its
    metavar, the one-line ``short`` help that ``--help`` shows, and its ``group`` (a key of :data:`GROUPS`)."""

    name: str
    default: Any
    kind: str
    help: str
    choices: tuple = ()
    low: float | None = None
    high: float | None = None
    flag: str | None = None
    metavar: str | None = None
    positive: bool = False  # a number that must be > low (not >=)
    short: str = ""
    group: str = ""


#: The option groups, in the order ``--help`` and docs/options.md show them: key → title.
GROUPS = {
    "heat": "method: heat geodesics and MDS (the paper's stages)",
    "refine": "method: refinement (the bijective true-scale polish)",
    "atlas": "atlas: meshes that are not one disk (or --max-distortion, --pack texture)",
    "run": "run: solver, seed and display",
}


OPTIONS: tuple[Option, ...] = (
    Option("fill", "auto", "choice", "fill surface M* for holes and concave borders (§2.5): auto decides from the "
           "mesh (holes, or a concave outline) and uses the biharmonic fill; poisson = the paper's screened Poisson "
           "surface (Kazhdan's PoissonRecon through gpytoolbox), trimmed to M; biharmonic = M plus its holes and "
           "border bays triangulated and lifted by a biharmonic extension (docs/fill.md); none",
           FILL_MODES, flag="--fill", short="fill surface over holes and bays", group="heat"),
    Option("fill_depth", 0, "int", "octree depth of the Poisson reconstruction (fill poisson); 0 = automatic from "
           "the mesh's size and edge length, 6-9", low=0, high=12, flag="--fill-depth", metavar="D",
           short="Poisson octree depth; 0 = automatic", group="heat"),
    Option("geodesics", "auto", "choice", "all-pairs = the paper (n×n matrix, classical MDS); landmarks = k "
           "farthest-point sources, landmark MDS, O(n·k) memory; auto = all-pairs up to {ALL_PAIRS_MAX} vertices",
           GEODESIC_MODES, flag="--geodesics", short="n×n distances or k landmarks", group="heat"),
    Option("landmarks", 0, "int", "landmark count for the landmark path (0 = automatic: min(n, 100); quality is "
           "flat from k = 50 to 400 on developable patches, time grows linearly: BENCHMARKS.md)",
           low=0, high=100_000, flag="--landmarks", metavar="K", short="landmark count; 0 = min(n, 100)",
           group="heat"),
    Option("time_step", "default", "time", "heat time: default t = c·h² (h = mean edge, scale-invariant); paper = "
           "Eq. 7 (longest edge; not scale-invariant); or a positive number", TIME_STEPS, flag="--time-step",
           metavar="{default,paper}|T", short="c·h² (default), Eq. 7 (paper) or T", group="heat"),
    Option("t_coef", 1.0, "float", "the c in t = c·h² for time_step default", low=0.0, high=T_COEF_MAX,
           flag="--t-coef", metavar="C", positive=True, short="the c in t = c·h²", group="heat"),
    Option("mass", "lumped", "choice", "mass matrix B: lumped (default: the consistent one of Eq. 6 gives heat "
           "kernels that oscillate for short times) or consistent (Eq. 6)", MASS_KINDS,
           short="mass matrix B: lumped or consistent", group="heat"),
    Option("solver", "auto", "choice", "sparse factorization backend; auto = MKL PARDISO (pypardiso, x86-64) for "
           "the refinement and for large heat systems, CHOLMOD (cholespy) otherwise, SciPy's SuperLU if neither is "
           "installed (BENCHMARKS.md §2, §4)", BACKENDS, flag="--solver", short="sparse factorization backend",
           group="run"),
    Option("seed", 0, "int", "seeds every random choice (first landmark, Lanczos start vector): same input and seed, "
           "same output", low=0, high=2**32 - 1, flag="--seed", metavar="N", short="seed of every random choice",
           group="run"),
    Option("all_pairs_max", ALL_PAIRS_MAX, "int", "largest vertex count for which geodesics auto takes the "
           "all-pairs path", low=3, high=100_000, short="largest n for all-pairs geodesics", group="heat"),
    Option("stress_sources", 32, "int", "number of sources for the sampled Eq. 1 stress in the report",
           low=1, high=10_000, short="sources of the report's sampled stress", group="heat"),
    Option("refine", "sd", "choice", "sd = a bijective start (the lower-energy bijective one of the MDS layout and "
           "the conformal one (spectral, no pins), either with <= 0.1% of its triangles flipped repaired "
           "first; else the conformal layout of the surface smoothed, else Tutte) polished by projected-Newton "
           "symmetric Dirichlet at true scale inside a re-triangulated scaffold, so no triangle flips and no "
           "boundary crosses another (docs/refine.md); none = the paper's raw MDS map",
           REFINE_MODES, flag="--refine", short="sd = bijective polish; none = raw MDS", group="refine"),
    Option("mds_start", "auto", "choice", "with refine sd, whether the fill, the heat geodesics and MDS run to offer "
           "the MDS layout as a start candidate. auto skips them (a) when the conformal layout is bijective and "
           "within {ISOMETRIC_START_EXCESS:.1%} of an isometry in energy (developable parts: the same map, faster); "
           "(b) on meshes of >= {CONFORMAL_START_MIN_VERTICES} vertices whenever the conformal layout is bijective, "
           "a few flips repaired (measured: the same map quality in less time; docs/history.md §13, §18); (c) on the "
           "seams stage's cut-open mesh (MDS folds across the slits: the same map); (d) on a large mesh, for the "
           "seams stage's trial map without seams when the conformal layout is not bijective (MDS folded on every "
           "such part measured; §18). Skipped, the report's stress_rel_rms is null. auto never skips them when "
           "fill, geodesics, landmarks or stress is set explicitly. always = compute them as a start candidate "
           "anyway (in an atlas: every chart through the pipeline instead of the charts' joint polish); never = "
           "skip them (the conformal layout, or the smoothed surface's, or Tutte starts; an atlas's charts are "
           "polished together from LSCM unless this is always: docs/history.md §10)",
           MDS_START_MODES, flag="--mds-start", short="when MDS competes for the start", group="refine"),
    Option("seams", "auto", "choice", "cut holes open to the border along the shortest surface paths: auto = when "
           "the map without seams is more than {SEAM_TRY_EXCESS:.2%} from an isometry, and on large meshes its "
           "coarse level more than {SEAM_MIN_GAIN:.0%} of its iso mean (else no cut map could gain enough: scan "
           "noise is not the holes' doing), keep the cut one if it is bijective and lowers the mean isometric "
           "distortion by {SEAM_MIN_GAIN:.0%} or more (reported, with a warning); holes = always; none = never, "
           "one uncut piece",
           SEAM_MODES, flag="--seams", short="cut holes open to the border", group="refine"),
    Option("stress", "none", "choice", "smacof = stress majorization (SMACOF, Guttman transform) of the raw stress "
           "of Eq. 1 on the geodesic distances MDS used, applied to the MDS layout before refine (BENCHMARKS.md "
           "§7); none = the MDS layout as is", STRESS_MODES, flag="--stress",
           short="SMACOF stress majorization after MDS", group="heat"),
    Option("refine_multilevel", MULTILEVEL_MIN_VERTICES, "int", "meshes of at least N vertices are polished "
           "coarse-to-fine (a ~1/8-size coarse mesh first; docs/refine.md); 0 = never", low=0, high=2**40,
           flag="--refine-multilevel", metavar="N", short="coarse-to-fine from N vertices; 0 = off",
           group="refine"),
    Option("refine_iters", 200, "int", "iteration cap of the symmetric Dirichlet polish", low=0, high=100_000,
           short="iteration cap of the polish", group="refine"),
    Option("refine_tol", 1e-6, "float", "the polish stops when an iteration lowers the energy by less than this "
           "fraction", low=0.0, high=1.0, positive=True, short="relative energy gain that ends the polish",
           group="refine"),
    Option("max_distortion", 0.0, "float", "atlas (any mesh that is not a single disk: closed, handles, several "
           "parts, non-manifold scans; docs/atlas.md): the bound on each chart's mean isometric distortion; 0 = "
           "automatic: a mesh that is one disk, or a scan's main piece (every other part under 1% of its area), stays "
           "one piece with --pack scale, and every chart of an atlas, or "
           "of a texture (--pack texture), is held to 1.05; a number > 1 is the bound for every chart, a disk's "
           "too", low=0.0, high=100.0, flag="--max-distortion",
           metavar="X", short="chart distortion bound; 0 = auto (1.05)", group="atlas"),
    Option("max_charts", 0, "int", "atlas: a cap on the charts of each part (merging goes on past the bound while "
           "the merged charts stay bijective); 0 = no cap", low=0, high=10**6, flag="--max-charts", metavar="N",
           short="cap on the charts per part; 0 = none", group="atlas"),
    Option("pack", "scale", "choice", "atlas: scale = charts at true scale in model units, laid side by side without "
           "overlap (patterns); texture = UVs in [0,1]², one common scale, a gutter of --padding pixels at "
           "--resolution (texture maps)", PACK_MODES, flag="--pack", short="true scale, or UVs in [0,1]²",
           group="atlas"),
    Option("padding", 4.0, "float", "atlas, pack texture: gutter between charts in pixels", low=0.0, high=1e4,
           flag="--padding", metavar="PX", short="gutter between charts, pixels", group="atlas"),
    Option("resolution", 1024, "int", "atlas, pack texture: the texture's size in pixels (for --padding)", low=16,
           high=2**20, flag="--resolution", metavar="PX", short="texture size in pixels", group="atlas"),
    Option("texels_per_unit", 0.0, "float", "atlas, pack texture: the texel density, pixels of the --resolution "
           "texture per model unit, the same for every chart; 0 = the largest at which all charts fit (an error when "
           "the density given does not fit)", low=0.0, high=1e12, flag="--texels-per-unit", metavar="D",
           short="pixels per unit; 0 = largest that fits", group="atlas"),
    Option("unit_name", "model units", "choice", "the model's length unit, a name only (nothing is scaled): the "
           "lengths in messages carry it (the seams warning). heatparam unwrap sets it from --units (default mm, with "
           "a warning when the part would be under 10 mm or over 100 m across in mm)", ("model units", *UNITS),
           short="name of the model's length unit in messages", group="run"),
    Option("progress", False, "bool", "show stage messages and progress bars on stderr (the CLI: unless --quiet)",
           short="stage messages and progress bars on stderr", group="run"),
)

_BY_NAME = {o.name: o for o in OPTIONS}
_CONSTANTS = {"ALL_PAIRS_MAX": ALL_PAIRS_MAX, "ISOMETRIC_START_EXCESS": ISOMETRIC_START_EXCESS,
              "CONFORMAL_START_MIN_VERTICES": CONFORMAL_START_MIN_VERTICES,
              "SEAM_TRY_EXCESS": SEAM_TRY_EXCESS, "SEAM_MIN_GAIN": SEAM_MIN_GAIN}


def help_text(opt: Option) -> str:
    """The option's help with the quoted constants filled in."""
    return opt.help.format(**_CONSTANTS)


def check_value(opt: Option, value: Any) -> Any:
    """``value`` if it is allowed for ``opt``, else :class:`HeatparamError` in API terms (``name=value``)."""
    if opt.kind == "choice":
        if value not in opt.choices:
            raise HeatparamError(f"{opt.name} must be one of {', '.join(opt.choices)}; got {value!r}")
        return value
    if opt.kind == "bool":
        if not isinstance(value, bool):
            raise HeatparamError(f"{opt.name} must be True or False; got {value!r}")
        return value
    if opt.kind == "time":
        if isinstance(value, str):
            if value not in opt.choices:
                raise HeatparamError(f"{opt.name} must be one of {', '.join(opt.choices)} or a positive number; "
                                     f"got {value!r}")
            return value
        return _number(opt, value, float, positive=True)
    return _number(opt, value, int if opt.kind == "int" else float, positive=opt.positive)


def _number(opt: Option, value: Any, kind: type, positive: bool) -> Any:
    integral = isinstance(value, int) or (isinstance(value, float) and value.is_integer())
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (kind is int and not integral):
        raise HeatparamError(f"{opt.name} must be {'an integer' if kind is int else 'a number'}; got {value!r}")
    if not math.isfinite(value):
        raise HeatparamError(f"{opt.name} must be finite; got {value!r}")
    if positive and not value > 0:
        raise HeatparamError(f"{opt.name} must be positive; got {value!r}")
    if opt.high is None and opt.low is not None and value < opt.low:
        raise HeatparamError(f"{opt.name} must be at least {opt.low:g}; got {value!r}")
    if (opt.low is not None and value < opt.low) or (opt.high is not None and value > opt.high):
        lo, hi = (f"{int(b)}" if kind is int else f"{b:g}" for b in (opt.low, opt.high))
        raise HeatparamError(f"{opt.name} must be between {lo} and {hi}; got {value!r}")
    return kind(value)


def _validate(self) -> None:
    """Raise :class:`HeatparamError` for a value outside its range (every option, from the table)."""
    for opt in OPTIONS:
        setattr(self, opt.name, check_value(opt, getattr(self, opt.name)))
    if self.landmarks in (1, 2):
        raise HeatparamError(f"landmarks must be 0 (automatic) or at least 3; got {self.landmarks}")
    if 0 < self.max_distortion <= 1:
        raise HeatparamError(f"max_distortion must be 0 (automatic) or more than 1 (1 = isometry); got "
                             f"{self.max_distortion}")


def _replace(self, **changes) -> Options:
    """A copy with ``changes`` applied (validated)."""
    out = Options(**{**asdict(self), **changes})
    out.validate()
    return out


Options = make_dataclass(
    "Options",
    [(o.name, type(o.default) if o.kind != "time" else str | float, field(default=o.default)) for o in OPTIONS],
    namespace={"validate": _validate, "replace": _replace, "__module__": __name__},
)
Options.__doc__ = ("Every knob of the pipeline (:data:`OPTIONS` is the table of allowed values and help).\n\n"
                   + "\n".join(f"{o.name} : default={o.default!r}. {help_text(o)}" for o in OPTIONS))


def make_options(options: Options | None = None, **overrides) -> Options:
    """An :class:`Options` from ``options`` (or the defaults) with keyword ``overrides``, validated.

    Raises HeatparamError for an unknown name or a value outside its range."""
    unknown = sorted(set(overrides) - set(_BY_NAME))
    if unknown:
        raise HeatparamError(f"unknown option {unknown[0]!r}; the options are {', '.join(_BY_NAME)}")
    opts = Options(**{**(asdict(options) if options is not None else {}), **overrides})
    opts.validate()
    return opts


def cli_options() -> list[Option]:
    """The options the command line offers, in table order."""
    return [o for o in OPTIONS if o.flag]


_API_SPELLING = re.compile(r"\b(" + "|".join(o.name for o in OPTIONS) + r")=(?:'([^']*)'|(\S+?))(?=[\s,;:)]|$)")
#: A bare option name: one with an underscore anywhere but inside a path or a longer name (an identifier, never an
#: English word: "fill" is both), and any one as the subject a refusal starts with (``landmarks must be ...``, the
#: validation's wording).
_API_NAME = re.compile(r"(?<![\w./\\'-])(" + "|".join(o.name for o in OPTIONS if "_" in o.name)
                       + r")(?![\w/\\=-]|\.\w)|^(" + "|".join(o.name for o in OPTIONS) + r")(?= must\b)")


def to_cli_terms(message: str) -> str:
    """A library message in command-line terms: ``name='value'`` / ``name=value`` become ``--flag value``, and a
    bare option name becomes its flag where it is unambiguous (see ``_API_NAME``). Options the command line does
    not offer keep their API name."""

    def setting(m: re.Match) -> str:
        opt = _BY_NAME[m.group(1)]
        if not opt.flag:
            return m.group(0)
        return f"{opt.flag} {m.group(2) if m.group(2) is not None else m.group(3)}"

    def name(m: re.Match) -> str:
        return _BY_NAME[m.group(1) or m.group(2)].flag or m.group(0)

    return _API_NAME.sub(name, _API_SPELLING.sub(setting, message))


def _spelling(o: Option) -> str:
    """The flag as the command line spells it, with its choices or metavar."""
    return f"{o.flag} {{{','.join(o.choices)}}}" if o.kind == "choice" else f"{o.flag} {o.metavar or ''}".rstrip()


def _cell(text: str) -> str:
    """Text inside a markdown table cell: a ``|`` would end the cell."""
    return text.replace("|", "\\|")


def markdown_table() -> str:
    """The command-line options in one table (flag, one-line meaning, default), generated from :data:`OPTIONS`:
    the summary at the top of docs/options.md."""
    rows = ["| option | meaning | default |", "|---|---|---|"]
    for o in cli_options():
        rows.append(f"| [`{_cell(_spelling(o))}`](#{o.name}) | {_cell(o.short)} | `{o.default}` |")
    return "\n".join(rows)


def _allowed(o: Option) -> str:
    """What values ``o`` takes, in words, from its table row."""
    if o.kind == "choice":
        return "one of " + ", ".join(f"`{c}`" for c in o.choices)
    if o.kind == "bool":
        return "True or False"
    if o.kind == "time":
        return " or ".join(f"`{c}`" for c in o.choices) + " or a positive number"
    what, bound = ("an integer", lambda b: f"{int(b)}") if o.kind == "int" else ("a number", lambda b: f"{b:g}")
    low = f"more than {bound(o.low)}" if o.positive else f"at least {bound(o.low)}"
    return f"{what}, {low} and at most {bound(o.high)}"


_DOCS_HEADER = ("<!-- Generated from heatparam.options.OPTIONS; do not edit. Regenerate with:",
                "python -c \"from heatparam.options import options_markdown; print(options_markdown(), end='')\" "
                "> docs/options.md -->")
_DOCS_INTRO = (
    "Every knob of the pipeline. The API takes the names (`parameterize(V, F, fill=\"none\")`, "
    "`heatparam.options.make_options`), `heatparam unwrap` and `heatparam batch` the flags (`heatparam geodesics` "
    "the heat method's: `--time-step`, `--t-coef`, `--solver`); `--help` shows one line each. The output flags "
    "(`-o`, `--units`, `--sheet`, `--gap`, `--grain`, `--nest-time`, `--strain-map`, `--fit-tolerance`, "
    "`--report`, `--preview`) are described in [formats.md](formats.md), `heatparam batch`'s own (`--workers`, "
    "`--scheduler`, `--task-timeout`, `--task-memory`, `--format`, `--force`, `--units` as unwrap's) by "
    "`heatparam batch --help`; "
    "`--quiet` silences the progress lines. Paths (docs/fill.md) are relative to the repository's root; section "
    "signs after BENCHMARKS name sections of BENCHMARKS.md, or of docs/history.md where the label moved there (the "
    "fill's section 2.5 is the paper's).")


def options_markdown() -> str:
    """docs/options.md: every option, grouped, with its flag, default, allowed values and full explanation, generated
    from :data:`OPTIONS` (``tests/test_docs.py`` keeps the file equal to this)."""
    out = ["# Options", "", *_DOCS_HEADER, "", _wrap(_DOCS_INTRO), "", markdown_table(), ""]
    for key, title in GROUPS.items():
        out += [f"## {title[0].upper()}{title[1:]}", ""]
        for o in (o for o in OPTIONS if o.group == key):
            where = f"`{_spelling(o)}`" if o.flag else "API only (no flag)"
            out += [f"### {o.name}", "", _wrap(f"{where} · default `{o.default}` · {_allowed(o)}"), "",
                    _wrap(help_text(o)), ""]
    return "\n".join(out)


def _wrap(paragraph: str) -> str:
    """A paragraph of docs/options.md at the docs' 120 columns, words kept whole; no line starts with a word that
    markdown would read as a quote, list or heading marker (``> 1`` would start a quote)."""
    lines = [""]
    for word in paragraph.split(" "):
        if lines[-1] and len(lines[-1]) + 1 + len(word) > 120 and not _MARKER.match(word):
            lines.append(word)
        else:
            lines[-1] = f"{lines[-1]} {word}" if lines[-1] else word
    return "\n".join(lines)


_MARKER = re.compile(r"([>#*+=-]+|\d+[.)])$")
