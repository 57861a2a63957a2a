"""The commands' output paths and memory: an output folder or file is probed (a file created
and removed in it) before any work, :func:`outputs_or_nothing` removes what a failed or
interrupted command wrote, and :func:`check_memory` refuses work that cannot fit; each raises a
:class:`UserError` that names the argument and what is wrong."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from jaxtrack.cli._common import UserError

__all__ = ["available_memory", "check_memory", "format_bytes", "output_directory",
           "output_folder", "outputs_or_nothing"]


def _probe(folder: Path) -> str | None:
    """Why no file can be created in ``folder`` (None when one can): a probe file is created
    and removed, which sees what ``os.access`` does not (``/proc``, a read-only mount, a root
    user's view of a folder without write permission)."""
    try:
        handle, name = tempfile.mkstemp(dir=folder, prefix=".jaxtrack-probe-")
    except OSError as error:
        return error.strerror or type(error).__name__
    os.close(handle)
    os.unlink(name)
    return None


def _writable(folder: Path, path: Path, option: str) -> None:
    """``folder`` may not exist yet (it is created after every check), but what exists of it
    must be a folder in which a file can be created."""
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise UserError(f"{option} {path}: cannot create folder {folder}, {existing} is a file")
    reason = _probe(existing)
    if reason is not None:
        raise UserError(f"{option} {path}: cannot write into folder {existing} ({reason})")


def output_folder(path: Path, option: str) -> Path:
    """The folder an output file goes in: it may not exist yet (it is created after every
    check), but what exists of it must be a folder a file can be created in (a probe file is
    created and removed there). Returns the folder."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    _writable(folder, path, option)
    if path.is_dir():
        raise UserError(f"{option} {path} is a folder; give a file name")
    return folder


def output_directory(folder: Path, option: str) -> Path:
    """An output folder (``--out DIR``): a folder, or nothing yet below a folder that files can
    be created in (probed). Returns the folder."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise UserError(f"{option} {folder} is a file; give a folder")
    _writable(folder, folder, option)
    return folder


@contextlib.contextmanager
def outputs_or_nothing(*folders: Path) -> Iterator[list]:
    """Create ``folders``; yield a list to which the body adds each file it writes. If the body
    fails or is interrupted (Ctrl-C), those files and the folders created here (when left
    empty) are removed, so that a command leaves all its outputs or none. (A file being written
    atomically, ``jaxtrack._files.write_atomically``, removes its own temporary file.)"""
    created, written = [], []
    for folder in folders:
        missing, existing = [], Path(folder)
        while not existing.exists():
            missing.append(existing)
            existing = existing.parent
        Path(folder).mkdir(parents=True, exist_ok=True)
        created.extend(missing)
    created.sort(key=lambda folder: len(folder.parts), reverse=True)  # deepest first
    try:
        yield written
    except BaseException:
        for path in written:
            Path(path).unlink(missing_ok=True)
        for folder in created:
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise


def format_bytes(count: float) -> str:
    """``1.5 GB``-style sizes (powers of 1000)."""
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if abs(count) < 1000 or unit == "TB":
            return f"{count:.0f} {unit}" if unit == "B" else f"{count:.1f} {unit}"
        count /= 1000
    raise AssertionError("unreachable")


def available_memory() -> int | None:
    """Bytes the run can still allocate: the accelerator's free memory when JAX runs on one,
    else the machine's available memory (``MemAvailable`` of /proc/meminfo, or ``sysconf``);
    None when neither can be read."""
    import jax

    device = jax.devices()[0]
    if device.platform != "cpu":
        stats = device.memory_stats() or {}
        if "bytes_limit" in stats:
            return int(stats["bytes_limit"]) - int(stats.get("bytes_in_use", 0))
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(needed: int, what: str, option: str) -> None:
    """Refuse a run whose estimated memory ``needed`` (bytes) exceeds what is available."""
    available = available_memory()
    if available is not None and needed > available:
        raise UserError(f"{option}: {what} needs about {format_bytes(needed)} of memory but "
                        f"this machine has {format_bytes(available)} available; use fewer")
