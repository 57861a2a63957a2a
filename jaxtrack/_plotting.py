"""Matplotlib figures without pyplot, saved atomically (shared by every layer that plots).

matplotlib is imported inside the functions, so `import jaxtrack` works without it. Figures are
built with the object-oriented API on an Agg canvas — no pyplot, so no global backend switch and
no figure left registered — and written through :func:`jaxtrack._files.write_atomically`: a
failed save leaves no partial file and keeps any earlier file at that path.
"""

from __future__ import annotations

import os
from pathlib import Path

from jaxtrack._files import write_atomically

__all__ = ["new_figure", "save_figure"]


def new_figure(width: float, height: float, columns: int = 1, rows: int = 1):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(rows, columns)
    return figure, axes


def save_figure(figure, path: str | os.PathLike, dpi: int) -> Path:
    path = Path(path)
    # the temporary file's name does not end in the real suffix, so name the format explicitly
    file_format = path.suffix.lstrip(".").lower() or "png"

    def write(temporary: Path) -> None:
        with open(temporary, "wb") as file:
            figure.savefig(file, format=file_format, dpi=dpi)
            file.flush()
            os.fsync(file.fileno())

    try:
        write_atomically(path, write)
    finally:
        figure.clear()
    return path
