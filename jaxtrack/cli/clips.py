"""``jaxtrack clips``: the catalogue of motion-capture clips, with where each one comes from."""

from __future__ import annotations

import argparse

__all__ = ["add_parser", "catalogue"]

_ORIGINS = ("bundled", "data", "shared", "test-only")


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "clips", help="list the motion-capture clips that every --mocap/--clips option takes",
        description=(
            "List the catalogue names of the motion-capture clips this installation can find "
            "(jaxtrack.data.list_clips), one a line with its origin: bundled (shipped inside "
            "the package, MIT/CMU/BSD data), data ($JAXTRACK_DATA), shared (a shared/data "
            "folder above the package or the working directory) or test-only (a source "
            "checkout's tests/data, non-commercial clips used by the tests). Writes nothing."),
        epilog="example: jaxtrack clips wave --origin bundled")
    parser.add_argument("pattern", nargs="?", default="",
                        help="list only the names that contain this text (case-insensitive)")
    parser.add_argument("--origin", choices=_ORIGINS, action="append",
                        help="list only clips of this origin (repeat for several; default all)")
    parser.add_argument("--paths", action="store_true",
                        help="also print the file each name loads")
    parser.set_defaults(handler=run)


def _origin(description: str) -> str:
    if description.startswith("files bundled"):
        return "bundled"
    if description.startswith("$JAXTRACK_DATA"):
        return "data"
    if description.startswith("tests/data"):
        return "test-only"
    return "shared"


def catalogue() -> list[tuple[str, str, str]]:
    """``(name, origin, file)`` of every clip, sorted by name; a name found in several places
    has the origin of the first place searched (the file ``load_clip`` loads)."""
    from jaxtrack.data import clip_files, data_folders

    found: dict[str, tuple[str, str]] = {}
    for description, folder in data_folders():
        for name, file in clip_files(folder).items():
            found.setdefault(name, (_origin(description), str(file)))
    return [(name, origin, file) for name, (origin, file) in sorted(found.items())]


def run(args: argparse.Namespace) -> int:
    origins = set(args.origin or _ORIGINS)
    pattern = args.pattern.lower()
    rows = [row for row in catalogue() if row[1] in origins and pattern in row[0].lower()]
    width = max((len(name) for name, _, _ in rows), default=0)
    for name, origin, file in rows:
        print(f"{name:<{width}}  {origin}" + (f"  {file}" if args.paths else ""))
    counts = {origin: sum(row[1] == origin for row in rows) for origin in _ORIGINS}
    summary = ", ".join(f"{count} {origin}" for origin, count in counts.items() if count)
    print(f"{len(rows)} clip(s)" + (f" ({summary})" if summary else "")
          + "; use a name with jaxtrack render --mocap, train --clips or evaluate --train/--test")
    return 0
