"""The writing contract shared by every output of a run.

1. :func:`plan_outputs` checks every output path BEFORE any computation (known extension, not a folder, the
   folder exists and a file can be created in it, not an input, no duplicates): a bad path ends the run with a
   one-line error and nothing computed or written.
2. :func:`commit_outputs` writes every output to a temporary file in its own folder and, only when all of them
   succeeded, renames them into place; on any failure the temporaries are removed, pre-existing files stay
   byte-identical, and a one-line HeatparamError is raised.
3. Files are created with mode ``0o666 & ~umask``, like any ordinary program's output.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass
from pathlib import Path

from heatparam.errors import HeatparamError
from heatparam.formats.exporters import EXPORTERS, by_suffix, map_formats
from heatparam.formats.files import file_mode


@dataclass(frozen=True)
class OutputPlan:
    """A checked output: its path and format (from the extension)."""

    path: Path
    format: str


def _extensions(allowed: Collection[str]) -> str:
    return ", ".join(sorted(s for e in EXPORTERS if e.name in allowed for s in e.suffixes))


def plan_outputs(paths: Sequence[str | os.PathLike | tuple[str | os.PathLike, Collection[str]]],
                 inputs: Sequence[str | os.PathLike] = (), allowed: Collection[str] | None = None
                 ) -> list[OutputPlan]:
    """Check output paths before any computation.

    Parameters
    ----------
    paths : output paths, each a path (its format must be in ``allowed``) or ``(path, formats)`` with its own
        allowed formats (e.g. ``(report, {"json"})``), all checked together so a name used twice is caught.
    inputs : files read by the run: none of them may be an output.
    allowed : formats accepted for plain paths (default: what ``unwrap -o`` writes, ``exporters.map_formats``).

    Returns
    -------
    list of OutputPlan, in the given order.

    Raises
    ------
    HeatparamError
        One line naming the path and what is wrong: unknown extension, a folder, a missing folder, a folder in
        which no file can be created, an input file, or a name given twice.
    """
    allowed = map_formats() if allowed is None else allowed
    plans: list[OutputPlan] = []
    seen: dict[Path, Path] = {}
    ins = {Path(i).resolve() for i in inputs if Path(i).exists()}
    for item in paths:
        raw, ok = item if isinstance(item, tuple) else (item, allowed)
        p = Path(raw)
        if p.is_dir():
            raise HeatparamError(f"output {p} is a folder — give a file name")
        exporter = by_suffix(p.suffix)
        fmt = exporter.name if exporter else None
        if fmt is None or fmt not in ok:
            raise HeatparamError(f"output {p}: unknown extension {p.suffix or '(none)'!r} (use {_extensions(ok)})")
        if p.exists() and not p.is_file():
            raise HeatparamError(f"output {p} exists and is not a regular file")
        parent = p.parent if str(p.parent) else Path(".")
        if not parent.is_dir():
            what = "is not a folder" if parent.exists() else "does not exist (create it first)"
            raise HeatparamError(f"cannot write {p}: folder {parent} {what}")
        if not os.access(parent, os.W_OK | os.X_OK) or not can_create(parent):
            raise HeatparamError(f"cannot write {p}: folder {parent} is not writable")
        r = p.resolve()
        if r in ins:
            raise HeatparamError(f"output {p} is the input file — choose another name (the input is never touched)")
        if r in seen:
            raise HeatparamError(f"output {p} is given twice (as {seen[r]})")
        seen[r] = p
        plans.append(OutputPlan(p, fmt))
    return plans


def can_create(folder: Path) -> bool:
    """Whether a file can really be created in ``folder`` (os.access says yes to root on read-only trees)."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=".heatparam-probe.", suffix=".tmp", dir=folder)
    except OSError:
        return False
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(tmp)
    return True


def _temporary(path: Path, mode: int) -> Path:
    """Create an empty temporary file beside ``path`` with ``mode`` (umask already applied) and return it."""
    for _ in range(100):
        tmp = path.parent / f".{path.name}.{os.urandom(4).hex()}.tmp"
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        os.close(fd)
        os.chmod(tmp, mode)  # exactly 0o666 & ~umask (os.chmod: also where os.fchmod is missing)
        return tmp
    raise HeatparamError(f"cannot write {path}: no free temporary name in {path.parent}")


def commit_outputs(writes: Sequence[tuple[str | os.PathLike, Callable[[Path], object]]]) -> list[object]:
    """Write all outputs, all or nothing.

    Parameters
    ----------
    writes : ``(path, writer)`` pairs in writing order; ``writer(tmp)`` writes the whole file at ``tmp`` (a
        temporary in the same folder as ``path``, already created with mode ``0o666 & ~umask``; the writer may
        overwrite or replace it) and returns anything (collected and returned).

    Returns
    -------
    list
        The writers' return values, in order.

    Raises
    ------
    HeatparamError
        One line, when any writer fails (its exception's message) or a rename fails: every temporary is removed,
        files already renamed are restored from hard-link backups, and pre-existing outputs stay byte-identical.
    """
    mode = file_mode()
    temps: list[tuple[Path, Path]] = []
    results = []
    try:
        for raw, writer in writes:
            p = Path(raw)
            tmp = _temporary(p, mode)
            temps.append((p, tmp))
            try:
                results.append(writer(tmp))
            except HeatparamError:
                raise
            except KeyboardInterrupt:
                raise
            except Exception as exc:  # a writer's failure is one line for the user, whatever its type
                msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
                raise HeatparamError(f"cannot write {p}: {msg} (no output written)") from None
            if not tmp.exists():
                raise HeatparamError(f"cannot write {p}: the writer produced no file (no output written)")
            os.chmod(tmp, mode)  # a writer that replaced the temporary (its own atomic write) keeps the umask
        _rename_all(temps)
    except BaseException:
        for _, tmp in temps:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        raise
    return results


def _rename_all(temps: list[tuple[Path, Path]]) -> None:
    """Rename every temporary into place; on a failure put back what was already replaced."""
    backups: list[tuple[Path, Path | None]] = []
    done: list[tuple[Path, Path | None, bool]] = []
    try:
        for p, _ in temps:
            b = None
            if p.exists():
                b = p.parent / f".{p.name}.{os.urandom(4).hex()}.bak"
                try:
                    os.link(p, b)
                except OSError:
                    b = None  # no hard links here: the rename itself is still atomic per file
            backups.append((p, b))
        for (p, tmp), (_, b) in zip(temps, backups, strict=True):
            existed = p.exists()
            try:
                os.replace(tmp, p)
            except OSError as exc:
                raise HeatparamError(f"cannot write {p}: {exc.strerror or exc} (no output written)") from None
            done.append((p, b, existed))
    except BaseException:
        for p, b, existed in reversed(done):
            with contextlib.suppress(OSError):
                if b is not None:
                    os.replace(b, p)
                elif not existed:
                    os.unlink(p)
        raise
    finally:
        for _, b in backups:
            if b is not None:
                with contextlib.suppress(OSError):
                    os.unlink(b)
