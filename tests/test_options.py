"""``heatparam.options``: one table drives the API's Options, their validation, the CLI (its ``--help``) and
docs/options.md."""

from __future__ import annotations

import math
import re
import subprocess
import sys
from dataclasses import fields

import pytest

from heatparam.cli import build_parser
from heatparam.errors import HeatparamError
from heatparam.options import GROUPS, OPTIONS, Options, cli_options, make_options, to_cli_terms


def test_options_fields_are_the_table():
    assert [f.name for f in fields(Options)] == [o.name for o in OPTIONS]
    d = Options()
    for o in OPTIONS:
        assert getattr(d, o.name) == o.default
    d.validate()  # the defaults are allowed values


@pytest.mark.parametrize("name, value", [
    ("t_coef", math.inf), ("t_coef", 1e300), ("t_coef", 0.0), ("t_coef", -1.0), ("t_coef", math.nan),
    ("time_step", math.inf), ("time_step", -2.0), ("time_step", 0.0), ("time_step", "later"),
    ("landmarks", -1), ("landmarks", 2), ("landmarks", 1.5), ("fill_depth", -1), ("fill_depth", 40),
    ("refine_multilevel", -1), ("seed", -3), ("refine_tol", 0.0), ("fill", "poison"), ("progress", "yes"),
    ("refine_iters", True),
])
def test_values_outside_the_table_are_refused_in_one_line(name, value):
    with pytest.raises(HeatparamError) as e:
        make_options(**{name: value})
    assert name in str(e.value) and "\n" not in str(e.value)


def test_unknown_option_named():
    with pytest.raises(HeatparamError, match="unknown option 'fil'"):
        make_options(fil="none")


def test_numbers_are_normalized():
    o = make_options(t_coef=2, time_step=3, landmarks=50.0)
    assert o.t_coef == 2.0 and isinstance(o.t_coef, float) and o.time_step == 3.0 and o.landmarks == 50
    assert make_options(o, seed=4).t_coef == 2.0  # overrides keep the rest


def test_cli_is_generated_from_the_table():
    unwrap = build_parser()._subparsers._group_actions[0].choices["unwrap"]
    actions = {a.dest: a for a in unwrap._actions}
    for o in cli_options():
        a = actions[o.name]
        assert o.flag in a.option_strings and a.default == o.default
        if o.kind == "choice":
            assert tuple(a.choices) == o.choices
    assert {o.name for o in OPTIONS if not o.flag} & set(actions) == set()


@pytest.mark.parametrize("argv", [["--t-coef", "inf"], ["--t-coef", "1e300"], ["--time-step", "inf"],
                                  ["--time-step", "nan"], ["--landmarks", "-4"], ["--seed", "x"]])
def test_cli_refuses_out_of_range_values(argv, tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        build_parser().parse_args(["unwrap", "in.obj", "-o", str(tmp_path / "o.obj"), *argv])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and argv[0] in err


def test_api_terms_become_flags():
    assert to_cli_terms("use geodesics='landmarks' (or 'auto')") == "use --geodesics landmarks (or 'auto')"
    assert to_cli_terms("try fill='none', then refine=none;") == "try --fill none, then --refine none;"
    assert to_cli_terms("mass='lumped' stays") == "mass='lumped' stays"  # no flag: kept in API terms
    assert to_cli_terms("split (seams='none': one piece)") == "split (--seams none: one piece)"


@pytest.mark.parametrize("message, expect", [
    # the validation's refusals name the option as their subject, without a value
    ("max_distortion must be 0 (automatic) or more than 1 (1 = isometry); got 0.5",
     "--max-distortion must be 0 (automatic) or more than 1 (1 = isometry); got 0.5"),
    ("landmarks must be 0 (automatic) or at least 3; got 2", "--landmarks must be 0 (automatic) or at least 3; got 2"),
    # an underscored name is an identifier wherever it stands
    ("the fill failed — try another fill_depth or fill='none'",
     "the fill failed — try another --fill-depth or --fill none"),
    ("(mds_start='always' computes them)", "(--mds-start always computes them)"),
    # English words, paths, longer names and API-only options stay as they are
    ("the fill must close the holes", "the fill must close the holes"),
    ("refine_iters must be an integer; got 1.5", "refine_iters must be an integer; got 1.5"),
    ("/tmp/max_distortion/x.obj: no triangles", "/tmp/max_distortion/x.obj: no triangles"),
    ("fill_depth.obj: no triangles", "fill_depth.obj: no triangles"),
    ("time_step_value is 0.5", "time_step_value is 0.5"),
])
def test_bare_option_names_become_flags(message, expect):
    assert to_cli_terms(message) == expect


def test_every_refusal_of_the_validation_reads_in_flags():
    """Each option the command line offers, refused by the API's validation, is named by its flag once turned
    into command-line terms (the path ``cli._run`` takes)."""
    bad = {"choice": "nonsense", "int": -7, "float": -7.0, "time": -7.0, "bool": "yes"}
    for o in cli_options():
        with pytest.raises(HeatparamError) as e:
            make_options(**{o.name: bad[o.kind]})
        text = to_cli_terms(str(e.value))
        assert text.startswith(o.flag) and o.name not in text.replace(o.flag, ""), text
    with pytest.raises(HeatparamError) as e:
        make_options(max_distortion=0.5)
    assert to_cli_terms(str(e.value)).startswith("--max-distortion must be")


def test_every_option_has_a_short_help_and_a_group():
    """--help shows ``short``: one line, no section signs or stop numbers (those belong in docs/options.md)."""
    for o in OPTIONS:
        assert o.group in GROUPS, o.name
        assert 0 < len(o.short) <= 44 and "\n" not in o.short, o.name
        assert "§" not in o.short and not re.search(r"\bstop \d", o.short, re.IGNORECASE), o.name
        assert o.help and len(o.help) > len(o.short), o.name  # the long explanation stays in the table


def test_help_imports_no_numerics():
    heavy = "('numpy', 'scipy', 'igl', 'trimesh', 'matplotlib', 'distributed', 'OCP')"
    code = ("import sys, heatparam.cli as c; c.build_parser().format_help(); "
            f"print(sorted(m for m in {heavy} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_cli_units_are_the_formats_units():
    """``cli.UNITS`` repeats the unit names so that --help loads no numerics: the same names as formats.units."""
    from heatparam.cli import UNITS
    from heatparam.formats.units import UNITS as FORMAT_UNITS

    assert tuple(UNITS) == tuple(FORMAT_UNITS)
