"""Atomic file writing shared by every layer that saves results (sequences, priors, metrics), and
the checks the commands make before they allocate or write something large: the memory the
machine has available, and the size of an output (``jaxtrack render`` refuses one above
:data:`LARGE_OUTPUT_BYTES` unless asked).

A file written here is never seen half-written: it is written to a temporary file beside it and
renamed onto its name; a failure or an interrupt (Ctrl-C) while writing removes the temporary
file."""

from __future__ import annotations

import json
import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

__all__ = ["LARGE_OUTPUT_BYTES", "NotEnoughMemoryError", "available_memory", "check_memory",
           "format_bytes", "warn_large_output", "write_atomically", "write_json_atomically",
           "write_npz_atomically"]

LARGE_OUTPUT_BYTES = 300_000_000
"""The largest output a command writes without being asked (``jaxtrack render --allow-large``):
300 frames of 640x480, uncompressed."""


class NotEnoughMemoryError(RuntimeError):
    """A run would need more memory than the machine has available; says how much of each.

    Attributes:
        needed: the estimated bytes.
        available: the bytes available.
    """

    def __init__(self, message: str, needed: float, available: int):
        super().__init__(message)
        self.needed = needed
        self.available = available


def format_bytes(size: float) -> str:
    """``size`` bytes in decimal units: ``2.1 GB``, ``340 MB``, ``12 kB``."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if size >= scale:
            value = size / scale
            return f"{value:.1f} {unit}" if value < 10 else f"{value:.0f} {unit}"
    return f"{int(size)} bytes"


def available_memory() -> int | None:
    """Bytes a new allocation can get without swapping: ``MemAvailable`` of ``/proc/meminfo``,
    else free physical pages (``os.sysconf``); None when the system says neither."""
    try:
        with open("/proc/meminfo") as file:
            for line in file:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (OSError, ValueError, AttributeError):
        return None


def check_memory(needed: float, what: str) -> None:
    """Raise :class:`NotEnoughMemoryError` when ``needed`` bytes (an estimate) exceed the memory
    available; ``what`` names the run in the message (e.g. ``"rendering 7000 frames of
    640x480"``). Does nothing when the available memory is unknown."""
    available = available_memory()
    if available is not None and needed > available:
        raise NotEnoughMemoryError(f"{what} needs about {format_bytes(needed)} of memory, but "
                                   f"this machine has {format_bytes(available)} available",
                                   needed, available)


def warn_large_output(path: str | os.PathLike, size: float, what: str = "") -> None:
    """Print a one-line warning to stderr before writing ``path`` of about ``size`` bytes, when
    that is more than :data:`LARGE_OUTPUT_BYTES`."""
    if size > LARGE_OUTPUT_BYTES:
        detail = f" ({what})" if what else ""
        print(f"warning: {path} will be about {format_bytes(size)}{detail}", file=sys.stderr,
              flush=True)


_INTERRUPTS = [0]
"""Ctrl-Cs recorded by :func:`record_interrupt` since :func:`clear_interrupts`."""


def record_interrupt() -> None:
    """Note a Ctrl-C (the command line's SIGINT handler calls this before it raises
    ``KeyboardInterrupt``): where that exception is swallowed on its way (it can land inside
    a callback XLA runs, whose exception does not reach the caller), the next file written
    atomically raises it again, before anything is moved into place."""
    _INTERRUPTS[0] += 1


def clear_interrupts() -> None:
    """Forget the recorded Ctrl-Cs (a command starts with none)."""
    _INTERRUPTS[0] = 0


def write_atomically(path: str | os.PathLike, write: Callable[[Path], None],
                     suffix: str = ".tmp") -> None:
    """Call ``write(temporary_path)``, then move the result onto ``path``.

    On any failure the temporary file is removed and ``path`` is left as it was, so a reader
    never sees a partially written file. After a recorded Ctrl-C (:func:`record_interrupt`)
    nothing is written: ``KeyboardInterrupt`` is raised instead.
    """
    if _INTERRUPTS[0]:
        raise KeyboardInterrupt
    path = Path(path)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.",
                                         suffix=suffix)
    os.close(handle)
    try:
        write(Path(temporary))
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)  # mkstemp makes it private; a plain file is not
        if _INTERRUPTS[0]:  # a Ctrl-C while writing that the writer swallowed
            raise KeyboardInterrupt
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def write_json_atomically(path: str | os.PathLike, value) -> Path:
    """Write ``value`` as indented JSON to ``path`` atomically. Returns the path."""
    path = Path(path)

    def write(temporary: Path) -> None:
        with open(temporary, "w") as file:
            json.dump(value, file, indent=2)
            file.write("\n")
            file.flush()
            os.fsync(file.fileno())

    write_atomically(path, write)
    return path


def write_npz_atomically(path: str | os.PathLike, arrays: dict, metadata: dict | None = None,
                         *, compress: bool = False, what: str = "description") -> Path:
    """Write ``arrays`` (and ``metadata`` as a JSON string under the key ``"metadata"``) as one
    ``.npz`` file, atomically (:func:`write_atomically`), synced to disk. Returns the path.

    Raises:
        ValueError: ``metadata`` is not JSON-serialisable (``what`` names the culprit in the
            message), before anything is written.
    """
    import numpy as np

    contents = dict(arrays)
    if metadata is not None:
        try:
            contents["metadata"] = np.array(json.dumps(metadata))
        except TypeError as error:
            raise ValueError(f"{what} must be JSON-serialisable: {error}") from None
    saver = np.savez_compressed if compress else np.savez
    path = Path(path)

    def write(temporary: Path) -> None:
        with open(temporary, "wb") as file:
            saver(file, **contents)
            file.flush()
            os.fsync(file.fileno())

    write_atomically(path, write)
    return path
