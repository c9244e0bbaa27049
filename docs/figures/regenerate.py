"""Rebuild the pictures: the README's two from ``heatparam demo`` (its SVG pattern rendered on white with cairosvg,
its preview PNG) and docs/atlas.md's preview of ``../shared/meshes/cow.off``'s atlas. Usage:
``python docs/figures/regenerate.py`` (about a minute; writes into docs/figures/)."""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import cairosvg

HERE = Path(__file__).resolve().parent
COW = HERE.parents[2] / "shared" / "meshes" / "cow.off"


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([sys.executable, "-m", "heatparam", "demo", "--output-dir", tmp, "--quiet"], check=True)
        svg = next(Path(tmp).glob("*.svg"))
        cairosvg.svg2png(url=str(svg), write_to=str(HERE / "pattern-demo-svg.png"), output_width=900,
                         background_color="white")
        shutil.copyfile(next(Path(tmp).glob("*.png")), HERE / "pattern-demo-preview.png")
        subprocess.run([sys.executable, "-m", "heatparam", "unwrap", str(COW), "-o", str(Path(tmp) / "cow.obj"),
                        "--preview", str(HERE / "atlas-cow-preview.png"), "--quiet"], check=True)


if __name__ == "__main__":
    main()
