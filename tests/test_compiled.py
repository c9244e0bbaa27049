import subprocess
import sys

import numpy as np

from heatparam.compiled import compiled

from conftest import imports_numba


@compiled()
def _twice(x):
    return 2.0 * x


@compiled(_twice)
def _sum_of_twice(a):
    s = 0.0
    for x in a:
        s += _twice(x)
    return s


def test_a_compiled_loop_calls_the_compiled_loops_it_names():
    assert _sum_of_twice(np.arange(4.0)) == 12.0
    assert _twice.dispatcher() is _twice.dispatcher()  # compiled once


def test_importing_the_compiled_loops_loads_no_numba():
    assert not imports_numba("import heatparam.atlas.grow, heatparam.atlas.overlap, heatparam.mesh.nest, "
                             "heatparam.refine.energy")


def test_warming_up_compiles_the_atlas_loops_before_any_atlas():
    code = ("import heatparam.pipeline.atlas_stage\n"
            "from heatparam import compiled\n"
            "atlas = lambda: [n for n in compiled.pending() if n.startswith('heatparam.atlas')]\n"
            "before = atlas()\n"
            "compiled.warm_all()\n"
            "print(len(before) > 0, atlas())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "True []"
