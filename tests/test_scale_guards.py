"""Option ranges and coordinate scale (issue 16): the lead's options table and internal normalization.

The options table validates every value (finite, positive, sane bounds: one line naming the option, exit 2,
before any work; a time step too large for the surface once the mesh is read, before anything is written) and
the pipeline computes extreme sizes in a power-of-two unit frame (``mesh.frame``), so that any finite scale gives
the same map × scale.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from heatparam import datasets, formats
from heatparam.cli import main

SRC = str(Path(__file__).resolve().parents[1] / "src")


@pytest.fixture(scope="module")
def patch(tmp_path_factory):
    """A small curved part (cylinder patch, ~100 vertices) as an OBJ."""
    sh = datasets.cylinder_patch(h=0.2)
    p = tmp_path_factory.mktemp("scale") / "patch.obj"
    formats.save_uv_obj(p, sh.V, sh.F, np.zeros((len(sh.V), 2)))
    return p, sh


def _refused(tmp_path, capsys, argv: list[str], option: str):
    out = tmp_path / ("o.npy" if argv[0] == "geodesics" else "o.obj")
    out.write_text("previous content\n")
    try:
        code = main([*argv, "-o", str(out), "--quiet"])
    except SystemExit as exc:  # argparse's own refusal (usage + error: two lines)
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("heatparam: error:") and err.count("\n") == 1, err
    assert option in err, err  # the message names the option
    assert out.read_text() == "previous content\n"


# ----------------------------------------------------------------------------------------------------------
# option values: one line naming the option, before any work
# ----------------------------------------------------------------------------------------------------------
OPTION_CASES = [
    ("unwrap", "--t-coef", "inf"),
    ("unwrap", "--t-coef", "nan"),
    ("unwrap", "--t-coef", "-1"),
    ("unwrap", "--t-coef", "0"),
    ("unwrap", "--t-coef", "1e300"),
    ("unwrap", "--time-step", "inf"),
    ("unwrap", "--time-step", "nan"),
    ("unwrap", "--time-step", "1e300"),
    ("unwrap", "--time-step", "-1"),
    ("unwrap", "--landmarks", "-5"),
    ("unwrap", "--landmarks", "1000000000000"),
    ("unwrap", "--fill-depth", "99"),
    ("unwrap", "--fill-depth", "-1"),
    ("unwrap", "--seed", "-1"),
    ("unwrap", "--seed", "1" + "0" * 30),
    ("unwrap", "--refine-multilevel", "1" + "0" * 30),
    ("geodesics", "--t-coef", "1e300"),
    ("geodesics", "--time-step", "nan"),
]
#: passing already (geodesics checks the time step it computes)
OPTION_CASES_DONE = [("geodesics", "--t-coef", "nan"), ("geodesics", "--t-coef", "inf"),
                     ("geodesics", "--time-step", "inf")]


@pytest.mark.parametrize("cmd,option,value", OPTION_CASES + OPTION_CASES_DONE,
                         ids=[f"{c}{o}={v[:8]}" for c, o, v in OPTION_CASES + OPTION_CASES_DONE])
def test_option_values_checked_against_their_ranges(tmp_path, capsys, patch, cmd, option, value):
    extra = ["--source", "0"] if cmd == "geodesics" else []
    _refused(tmp_path, capsys, [cmd, str(patch[0]), option, value, *extra], option)


# ----------------------------------------------------------------------------------------------------------
# scale: the same map × scale, for any finite scale
# ----------------------------------------------------------------------------------------------------------
def _unwrap_scaled(tmp_path, sh, s: float) -> np.ndarray:
    """The map of the patch scaled by s, through a subprocess with a memory cap (2 GB) and a time limit, so that
    a scale that makes memory grow without bound fails the test instead of the machine."""
    src, out = tmp_path / f"s{s:g}.obj", tmp_path / f"o{s:g}.obj"
    formats.save_uv_obj(src, sh.V * s, sh.F, np.zeros((len(sh.V), 2)))
    code = ("import resource, sys; resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30)); "
            "from heatparam.cli import main; sys.exit(main(sys.argv[1:]))")
    env = dict(os.environ, PYTHONPATH=SRC)
    try:
        r = subprocess.run([sys.executable, "-c", code, "unwrap", str(src), "-o", str(out), "--quiet"],
                           env=env, capture_output=True, text=True, timeout=30)
    except subprocess.TimeoutExpired:
        pytest.fail(f"scale {s:g}: no result within 30 s")
    assert r.returncode == 0, f"scale {s:g}: {r.stderr.strip()}"
    assert "Traceback" not in r.stderr
    return formats.load_uv_obj(out)[2]


@pytest.fixture(scope="module")
def unit_map(tmp_path_factory, patch):
    return _unwrap_scaled(tmp_path_factory.mktemp("unit"), patch[1], 1.0)


@pytest.mark.parametrize("s", [1e-80, 1e-6, 1e6, 1e80, 1e155, 1e-155])
def test_same_map_times_scale(tmp_path, patch, unit_map, s):
    uv = _unwrap_scaled(tmp_path, patch[1], s)
    assert np.isfinite(uv).all()
    diam = float(np.ptp(unit_map, axis=0).max())
    assert np.abs(uv / s - unit_map).max() <= 1e-6 * diam, f"scale {s:g}"
