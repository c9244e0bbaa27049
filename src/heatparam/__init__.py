"""heatparam: near-isometric mesh parameterization (Mejia-Parra et al. 2019)."""

from heatparam.errors import HeatparamError, MeshError, ResourceError

__version__ = "0.1.0"

__all__ = ["HeatparamError", "MeshError", "ResourceError", "__version__", "parameterize", "Options"]


def __getattr__(name):  # lazy: keep `import heatparam` light for the CLI's --help
    if name in ("parameterize", "Options"):
        from heatparam import pipeline

        return getattr(pipeline, name)
    raise AttributeError(name)
