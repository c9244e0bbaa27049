"""Writing files safely: every output goes to a temporary beside it and is renamed into place only when complete."""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from heatparam import interrupt
from heatparam.errors import HeatparamError


def current_umask() -> int:
    """The process umask (read without changing it where /proc allows, else set-and-restore)."""
    with contextlib.suppress(OSError, ValueError):
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def file_mode() -> int:
    """Mode of a new output file: 0o666 less the umask."""
    return 0o666 & ~current_umask()


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "w"):
    """Open a temporary file beside ``path``; on success rename it over ``path``, on failure delete it.

    A failed run therefore never leaves a half-written or clobbered output.
    """
    p = Path(path)
    if not p.parent.exists():
        raise HeatparamError(f"cannot write {p}: folder {p.parent} does not exist (create it first)")
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    try:
        os.chmod(tmp, file_mode())  # mkstemp makes 0600: outputs get 0666 & ~umask like any program's
        with os.fdopen(fd, mode) as fh:
            yield fh
        interrupt.check()  # an interrupt a library swallowed still leaves nothing written
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise

def save_json(path: str | os.PathLike, data: dict) -> None:
    """Write ``data`` as indented JSON, atomically."""
    with atomic_write(path) as fh:
        json.dump(data, fh, indent=2, default=_json_default)
        fh.write("\n")

def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serializable: {type(o).__name__}")

def save_npy(path: str | os.PathLike, array: np.ndarray) -> None:
    """Write a .npy array atomically."""
    with atomic_write(path, "wb") as fh:
        np.save(fh, array)
