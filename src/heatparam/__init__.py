"""heatparam: near-isometric, true-scale mesh parameterization (Mejia-Parra et al. 2019).

The public API, loaded lazily so that ``heatparam --help`` imports no numerics:

- :func:`parameterize` (``heatparam.pipeline``): flatten a mesh, returns a :class:`Result` (``uv, report``);
- :class:`Options` and :data:`OPTIONS` (``heatparam.options``): every knob, one table;
- :func:`geodesic_distances` (``heatparam.heat``): heat-method geodesics in one call;
- :func:`batch` (``heatparam.batching``): many meshes on a Dask cluster, resumable;
- ``heatparam.datasets``: generated surfaces with known flat layouts; ``heatparam.formats``: reading and writing.
"""

from heatparam.errors import HeatparamError, MeshError, ResourceError
from heatparam.version import __version__

__all__ = ["OPTIONS", "HeatparamError", "MeshError", "Options", "ResourceError", "Result", "__version__", "batch",
           "geodesic_distances", "parameterize"]

_LAZY = {"parameterize": "heatparam.pipeline", "Result": "heatparam.pipeline", "Options": "heatparam.options",
         "OPTIONS": "heatparam.options", "geodesic_distances": "heatparam.heat"}


def batch(paths, out_dir, client=None, **options):
    """Flatten many meshes (files, folders, globs) on a Dask cluster: :func:`heatparam.batching.run_batch`
    (``client``: a ``distributed.Client``; None = a LocalCluster). Returns the summary (one row per input)."""
    from heatparam.batching import run_batch

    return run_batch(paths, out_dir, client=client, **options)


def __getattr__(name):  # lazy: keep `import heatparam` light for the CLI's --help
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(name)
