"""Build the installable Blender extension: ``python integrations/blender/build.py [--out DIR]`` writes
``DIR/heatparam_blender-<version>.zip`` (default DIR: integrations/blender/dist), the files of
``heatparam_blender/`` at the archive's root as Blender 4.2+ expects (``blender_manifest.toml`` first). Install it in
Blender with Edit ▸ Preferences ▸ Get Extensions ▸ Install from Disk (integrations/blender/README.md).

The archive holds the extension only: heatparam runs as its own program (``heatparam_blender.runner``), installed
apart with pip or pipx, so no wheels are bundled. Blender's own ``blender --command extension build`` makes the same
archive where a Blender binary is at hand.
"""

from __future__ import annotations

import argparse
import re
import sys
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
SOURCE = HERE / "heatparam_blender"
MANIFEST = "blender_manifest.toml"


def manifest_field(name: str) -> str:
    """A top-level string field of the manifest (``id``, ``version``); SystemExit when it is missing."""
    m = re.search(rf'^{name}\s*=\s*"([^"]+)"', (SOURCE / MANIFEST).read_text(encoding="utf-8"), re.MULTILINE)
    if not m:
        raise SystemExit(f"build.py: {SOURCE / MANIFEST} has no {name} = \"...\" line")
    return m.group(1)


def files() -> list[Path]:
    """The extension's files: the manifest, then every Python module (caches and compiled files left out)."""
    modules = sorted(p for p in SOURCE.rglob("*.py") if "__pycache__" not in p.parts)
    return [SOURCE / MANIFEST, *modules]


def build(out_dir: Path) -> Path:
    """Write the archive into ``out_dir``; its path."""
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / f"{manifest_field('id')}-{manifest_field('version')}.zip"
    with zipfile.ZipFile(target, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for f in files():
            zf.write(f, f.relative_to(SOURCE).as_posix())
    return target


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="build the heatparam Blender extension's zip")
    parser.add_argument("--out", type=Path, default=HERE / "dist", help="output folder (default: %(default)s)")
    args = parser.parse_args(argv)
    print(build(args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
