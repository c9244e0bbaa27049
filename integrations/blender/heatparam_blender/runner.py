"""heatparam as a separate program: find the ``heatparam`` command, hand it a triangle mesh as an OBJ, read the UVs it
wrote back. No ``bpy`` here.

Running the command (not importing heatparam into Blender's Python) keeps heatparam's dependencies (SciPy, libigl,
MKL, OpenCascade) out of Blender's process and version-independent of Blender's bundled NumPy, lets one heatparam
installation serve every Blender version, and turns its one-line errors into Blender reports as they are.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

INSTALL_HINT = ("install heatparam (from its repository: pipx install . or pip install .) or set the path of "
                "the heatparam program in the extension's preferences")


class RunError(Exception):
    """A one-line message for the user (a Blender ``ERROR`` report)."""


def find_command(configured: str = "") -> list[str]:
    """The command line that runs heatparam: the program set in the preferences (``configured``), else ``heatparam``
    on PATH, else ``python -m heatparam`` when heatparam is installed in Blender's own Python.

    Raises
    ------
    RunError when none is found.
    """
    if configured:
        path = Path(configured).expanduser()
        if path.is_file() and os.access(path, os.X_OK):
            return [str(path)]
        raise RunError(f"the heatparam program set in the preferences ({configured}) is not an executable file: "
                       f"{INSTALL_HINT}")
    found = shutil.which("heatparam")
    if found:
        return [found]
    if importlib.util.find_spec("heatparam") is not None:
        return [sys.executable, "-m", "heatparam"]
    raise RunError(f"the heatparam program was not found: {INSTALL_HINT}")


def write_obj(path: Path, V: np.ndarray, F: np.ndarray) -> None:
    """An OBJ of ``v`` V (n,3) float64 and ``f`` F (m,3) int64 (0-based), exact (``repr`` of each float)."""
    with open(path, "w", encoding="ascii") as fh:
        fh.write(("v %r %r %r\n" * len(V)) % tuple(np.asarray(V, dtype=np.float64).ravel().tolist()))
        fh.write(("f %d %d %d\n" * len(F)) % tuple((np.asarray(F, dtype=np.int64) + 1).ravel().tolist()))


def read_corner_uvs(path: Path, m: int) -> np.ndarray:
    """(m,3,2) float64: the UV of each face corner of heatparam's OBJ (``vt`` lines, faces ``f v/vt`` row for row
    as the input's, which heatparam's OBJ reader and writer keep)."""
    lines = path.read_text(encoding="ascii").splitlines()
    vt = np.array(" ".join(ln[3:] for ln in lines if ln.startswith("vt ")).split(), dtype=np.float64).reshape(-1, 2)
    corners = " ".join(ln[2:] for ln in lines if ln.startswith("f ")).replace("/", " ").split()
    idx = np.array(corners, dtype=np.int64).reshape(-1, 6)
    if len(idx) != m:
        raise RunError(f"heatparam wrote {len(idx)} faces for {m}: its OBJ does not match the mesh sent")
    return vt[idx[:, 1::2] - 1]


class Unwrap:
    """One ``heatparam unwrap`` run on a triangle mesh (``V`` (n,3) float64, ``F`` (m,3) int64, in ``units``) with
    the given flags; ``on_line`` sees each progress line heatparam prints (for the status bar)."""

    def __init__(self, command: list[str], flags: list[str], units: str | None,
                 on_line: Callable[[str], None] | None = None):
        self.command = command
        self.flags = [*flags, *(["--units", units] if units else [])]
        self.on_line = on_line or (lambda line: None)
        self.warnings: list[str] = []
        self.summary = ""

    def corner_uvs(self, V: np.ndarray, F: np.ndarray) -> np.ndarray:
        """(m,3,2) float64: the UV of each corner of F."""
        with tempfile.TemporaryDirectory(prefix="heatparam-blender-") as tmp:
            out = Path(tmp) / "uv.obj"
            self.run(V, F, [out], Path(tmp))
            return read_corner_uvs(out, len(F))

    def export(self, V: np.ndarray, F: np.ndarray, path: Path) -> None:
        """Write heatparam's flat pattern of the mesh to ``path`` (.dxf .svg .step: heatparam's writers)."""
        with tempfile.TemporaryDirectory(prefix="heatparam-blender-") as tmp:
            self.run(V, F, [path], Path(tmp))

    def run(self, V: np.ndarray, F: np.ndarray, outputs: list[Path], tmp: Path) -> None:
        """Run heatparam on the mesh, writing ``outputs``; RunError with heatparam's own one-line message."""
        mesh = tmp / "mesh.obj"
        write_obj(mesh, V, F)
        args = [*self.command, "unwrap", str(mesh), *(a for p in outputs for a in ("-o", str(p))), *self.flags]
        try:
            proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                    encoding="utf-8", errors="replace")
        except OSError as exc:
            raise RunError(f"cannot run {args[0]} ({exc.strerror or exc}): {INSTALL_HINT}") from None
        last = ""
        for line in proc.stderr:  # text mode: tqdm's carriage returns end lines too
            line = line.strip()
            if line:
                last = line
                self._seen(line)
        if proc.wait() != 0:
            raise RunError(last.removeprefix("heatparam: error: ") or f"heatparam exited with code {proc.returncode}")

    def _seen(self, line: str) -> None:
        if line.startswith("heatparam: warning: "):
            self.warnings.append(line.removeprefix("heatparam: warning: "))
        elif line.startswith("wrote "):
            self.summary = line
        self.on_line(line)
