"""Atomic file writing shared by every layer that saves results (sequences, priors, metrics)."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

__all__ = ["write_atomically", "write_json_atomically"]


def write_atomically(path: str | os.PathLike, write: Callable[[Path], None],
                     suffix: str = ".tmp") -> None:
    """Call ``write(temporary_path)``, then move the result onto ``path``.

    On any failure the temporary file is removed and ``path`` is left as it was, so a reader
    never sees a partially written file.
    """
    path = Path(path)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.",
                                         suffix=suffix)
    os.close(handle)
    try:
        write(Path(temporary))
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)  # mkstemp makes it private; a plain file is not
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
