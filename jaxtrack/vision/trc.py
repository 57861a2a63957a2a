"""3-D marker tracks as ``.trc`` files, the text format OpenSim and Pose2Sim read.

The layout (OpenSim's "Marker (.trc) Files"; Pose2Sim writes the same five header lines):

.. code-block:: text

    PathFileType  4  (X/Y/Z)  NAME.trc
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  ...
    60  60  100  12  m  60  1  100
    Frame#  Time  head      neck      ...
                  X1 Y1 Z1  X2 Y2 Z2  ...
    1  0.000000  x y z  x y z  ...

(the second line ends with ``OrigNumFrames``). Fields are tab-separated; a marker's name
heads its three columns (two empty fields follow it);
frames are numbered from 1 (``first_frame``) and ``Time`` is ``(Frame# - first_frame) / rate``
seconds. A missing marker (NaN) is left blank, as OpenSim and Pose2Sim read a gap. OpenSim
expects Y up; :func:`write_trc` writes the coordinates as given (``jaxtrack.evaluation.reference.
trc_to_world`` goes the other way for Pose2Sim's files).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from jaxtrack._files import write_atomically

__all__ = ["TRC_HEADER_FIELDS", "TrcFileError", "read_trc", "write_trc"]

TRC_HEADER_FIELDS = ("DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units",
                     "OrigDataRate", "OrigDataStartFrame", "OrigNumFrames")
"""The second header line: the names of the third line's values."""


class TrcFileError(ValueError):
    """A ``.trc`` file or its contents cannot be read or written; one line naming it."""


def _number(value: float) -> str:
    return "" if not math.isfinite(value) else f"{value:.6f}"


def write_trc(path: str | os.PathLike, markers_xyz, names: Sequence[str], rate: float,
              units: str = "m", *, first_frame: int = 1) -> Path:
    """Write a 3-D track as a ``.trc`` file (module docstring), atomically.

    Args:
        path: the file to write (``.trc``).
        markers_xyz: ``(time, markers, 3)`` positions in ``units`` (NaN where a marker is
            missing in a frame).
        names: the markers' names, one per marker (no tabs, not empty).
        rate: frames per second (``DataRate`` and ``CameraRate``).
        units: ``"m"`` or ``"mm"`` (what OpenSim accepts).
        first_frame: the first row's ``Frame#`` (``OrigDataStartFrame``).

    Returns:
        ``path``.

    Raises:
        TrcFileError: positions of the wrong shape or with infinities, names that do not match
            them, a rate that is not positive, unknown units.
    """
    path = Path(path)
    positions = np.asarray(markers_xyz, np.float64)
    names = tuple(str(name) for name in names)
    if positions.ndim != 3 or positions.shape[-1] != 3 or positions.shape[0] < 1:
        raise TrcFileError(f"{path}: markers_xyz must be (time, markers, 3) with at least one "
                           f"frame, got shape {positions.shape}")
    if len(names) != positions.shape[1]:
        raise TrcFileError(f"{path}: {len(names)} names for {positions.shape[1]} markers")
    bad = [name for name in names if not name.strip() or any(c in name for c in "\t\r\n")]
    if bad:
        raise TrcFileError(f"{path}: marker names must be non-empty without tabs or line "
                           f"breaks, got {bad!r}")
    if np.isinf(positions).any():
        raise TrcFileError(f"{path}: infinite positions (use NaN for a missing marker)")
    if not (math.isfinite(rate) and rate > 0):
        raise TrcFileError(f"{path}: rate must be positive frames per second, got {rate}")
    if units not in ("m", "mm"):
        raise TrcFileError(f"{path}: units must be 'm' or 'mm', got {units!r}")
    count, num_markers = positions.shape[:2]
    rate_text = f"{rate:g}"
    lines = [
        f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
        "\t".join(TRC_HEADER_FIELDS),
        "\t".join([rate_text, rate_text, str(count), str(num_markers), units, rate_text,
                   str(first_frame), str(count)]),
        "\t".join(["Frame#", "Time"] + [f"{name}\t\t" for name in names]),
        "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, num_markers + 1)),
    ]
    for row, frame in enumerate(positions):
        values = "\t".join(_number(value) for value in frame.reshape(-1))
        lines.append(f"{first_frame + row}\t{row / rate:.6f}\t{values}")
    text = "\n".join(lines) + "\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomically(path, lambda temporary: temporary.write_text(text))
    return path


def read_trc(path: str | os.PathLike) -> tuple[np.ndarray, tuple[str, ...], dict]:
    """Read a ``.trc`` file (this module's or Pose2Sim's).

    Returns:
        ``(markers_xyz (time, markers, 3), names, header)``: blank fields as NaN; ``header``
        the second line's fields with the third line's values (numbers as float, ``Units``
        as text), plus ``frames``: ``(time,)`` the ``Frame#`` column and ``times`` the
        ``Time`` column.

    Raises:
        TrcFileError: no such file, no ``PathFileType`` line, or rows that disagree with the
            header.
    """
    path = Path(path)
    if not path.is_file():
        raise TrcFileError(f"{path}: no such file")
    lines = path.read_text().splitlines()
    if len(lines) < 5 or not lines[0].startswith("PathFileType"):
        raise TrcFileError(f"{path}: not a .trc file (no PathFileType header line)")
    try:
        header: dict = {}
        for key, value in zip(lines[1].split("\t"), lines[2].split("\t"), strict=True):
            header[key] = value if key == "Units" else float(value)
        names = tuple(name for name in lines[3].split("\t")[2:] if name.strip())
        count = int(header["NumMarkers"])
        rows = [line.split("\t") for line in lines[5:] if line.strip()]
        table = np.array([[float(v) if v.strip() else np.nan for v in row[:2 + 3 * count]]
                          + [np.nan] * (2 + 3 * count - len(row)) for row in rows])
    except (KeyError, ValueError) as error:
        raise TrcFileError(f"{path}: a damaged .trc file ({error})") from None
    if not rows or len(names) != count or len(rows) != int(header["NumFrames"]):
        raise TrcFileError(f"{path}: the header says {count} markers and "
                           f"{int(header['NumFrames'])} frames; the file holds {len(names)} "
                           f"names and {len(rows)} rows")
    header["frames"], header["times"] = table[:, 0].astype(np.int64), table[:, 1]
    return table[:, 2:].reshape(len(rows), count, 3), names, header
