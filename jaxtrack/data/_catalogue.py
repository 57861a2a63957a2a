"""Find real motion-capture clips by name: bundled with the package, or in a data folder.

A clip name is `<collection>/<path inside the folder, no extension>`, for example
`animateddrawings/fair1_wave_hello`, `animateddrawings/history_c119d6b/cmu_1006_wave_hello_1`,
`cmu_amc/07_01`, `cmu_bvh/131_01`, `cmu_posture_bvh/75_19`,
`bandai/dataset-2_wave-right-hand_normal_001`. The folder's own
name works as the collection too (`animateddrawings_bvh/fair1_wave_hello.bvh`), and any other file
is found by its name with extension (`pose2sim/Calib.qca.txt`).

Places searched, in order (the first that has the file wins):
1. the files bundled in the package (`jaxtrack/data/files/`, MIT/CMU/BSD data only; the trained
   models of `jaxtrack.data.models` are in its `models/` folder);
2. the folder named by the environment variable `JAXTRACK_DATA`;
3. a `shared/data` folder in any folder above the package or the working directory (the project's
   full collection, e.g. `/work/shared/data`, or `../shared/data` beside a CI clone);
4. `tests/data` of a source checkout (the non-commercial Bandai clips used by the tests).

With the environment variable `JAXTRACK_NO_SHARED=1`, places 3 and 4 are not searched: jaxtrack
finds what a user's machine with only the installed package finds (the bundled files, and
`$JAXTRACK_DATA` when it is set). The tests run the notebooks and the README's commands so.

Clips come back exactly as the readers make them: format quirks (units, axes, the reference frame 0
of the MotionBuilder-friendly CMU BVHs) are handled by the readers, from what the file holds, not
here by folder, so a file loaded by path reads the same as one found by name.
"""

from __future__ import annotations

import importlib.resources
import os
from pathlib import Path

from jaxtrack.body.motion import Motion, load_motion

__all__ = ["COLLECTIONS", "bundled_folder", "clip_files", "data_folders", "list_clips", "load_clip",
           "path", "shared_folder"]

COLLECTIONS = {
    "animateddrawings": "animateddrawings_bvh",
    "bandai": "bandai_namco_gestures",
    "cmu_amc": "cmu_asfamc_walk",
    "cmu_bvh": "cmu_bvh_131",
    "cmu_posture_bvh": "cmu_posture_bvh",
    "pose2sim": "pose2sim_demo_singleperson",
}
"""Clip-name collection -> data folder name (the same in the package and in shared/data).
``cmu_posture_bvh`` keeps its folder's name: two of its clips (75_19 sits, 64_26 stoops) are
bundled for the posture model (``jaxtrack.data.models``), the rest are in shared/data."""

MOTION_SUFFIXES = (".bvh", ".amc")


def bundled_folder() -> Path | None:
    """The folder of data files shipped inside the package (None in a zipped install)."""
    resource = importlib.resources.files(__package__).joinpath("files")
    # a zipped install has no real folder; the .amc reader needs the .asf beside it on disk
    return resource if isinstance(resource, Path) and resource.is_dir() else None


def _ancestors(start: Path) -> list[Path]:
    start = start.resolve()
    return [start, *start.parents]


NO_SHARED = "JAXTRACK_NO_SHARED"
"""Environment variable: set (to anything but `0`, `false`, `no` or empty), the catalogue
searches no `shared/data` nor `tests/data` above the package or the working directory."""


def _no_shared() -> bool:
    return os.environ.get(NO_SHARED, "").strip().lower() not in ("", "0", "false", "no")


def data_folders() -> list[tuple[str, Path]]:
    """Every place searched for data, in search order, as `(description, folder)`."""
    folders: list[tuple[str, Path]] = []
    bundled = bundled_folder()
    if bundled is not None:
        folders.append(("files bundled with jaxtrack", bundled))
    environment = os.environ.get("JAXTRACK_DATA")
    if environment:
        folders.append(("$JAXTRACK_DATA", Path(environment).expanduser()))
    if _no_shared():
        return folders
    seen: set[Path] = set()
    here = Path(__file__).parent
    for ancestor in _ancestors(here) + _ancestors(Path.cwd()):
        for description, candidate in (("shared/data", ancestor / "shared" / "data"),
                                       ("tests/data", ancestor / "tests" / "data")):
            if candidate not in seen and candidate.is_dir():
                seen.add(candidate)
                folders.append((f"{description} at {candidate}", candidate))
    # shared/data before tests/data, whatever the nesting
    folders.sort(key=lambda item: item[0].startswith("tests/data"))
    return folders


def _relative_candidates(name: str) -> list[Path]:
    parts = name.replace("\\", "/").strip("/").split("/")
    if len(parts) < 2:
        raise ValueError(f"a clip name looks like 'collection/clip', e.g. "
                         f"'animateddrawings/fair1_wave_hello'; got {name!r}")
    folder = COLLECTIONS.get(parts[0], parts[0])
    relative = Path(folder, *parts[1:])
    if relative.suffix.lower() in MOTION_SUFFIXES or relative.suffix.lower() in (".asf", ".txt"):
        return [relative]
    return [relative.with_name(relative.name + suffix) for suffix in MOTION_SUFFIXES] + [relative]


def path(name: str) -> Path:
    """The file behind a clip name (or a `collection/file.ext` name).

    Raises:
        FileNotFoundError: listing every place searched.
    """
    candidates = _relative_candidates(name)
    folders = data_folders()
    for _, folder in folders:
        for relative in candidates:
            if (folder / relative).is_file():
                return folder / relative
    searched = "\n".join(f"  - {description}: {folder}" for description, folder in folders)
    raise FileNotFoundError(
        f"no data file for {name!r} (tried {[str(c) for c in candidates]}) in:\n"
        f"{searched or '  (no data folder found)'}\n"
        "set JAXTRACK_DATA to a folder holding the collections (e.g. a copy of shared/data)"
    )


def shared_folder() -> Path | None:
    """The full data collection outside the package ($JAXTRACK_DATA or a shared/data), if any."""
    for description, folder in data_folders():
        if description.startswith(("$JAXTRACK_DATA", "shared/data")) and folder.is_dir():
            return folder
    return None


def clip_files(folder: Path) -> dict[str, Path]:
    """Every motion clip (.bvh, .amc) under one data folder: clip name -> file, sorted by name."""
    aliases = {name: alias for alias, name in COLLECTIONS.items()}
    clips = {}
    for file in Path(folder).rglob("*"):
        if file.suffix.lower() in MOTION_SUFFIXES and file.is_file():
            relative = file.relative_to(folder)
            collection = aliases.get(relative.parts[0], relative.parts[0])
            clips["/".join((collection, *relative.parts[1:-1], file.stem))] = file
    return dict(sorted(clips.items()))


def list_clips() -> list[str]:
    """Names of every motion clip (.bvh, .amc) that `load_clip` can find, sorted."""
    return sorted({name for _, folder in data_folders() for name in clip_files(folder)})


def load_clip(name: str | os.PathLike, *, asf: str | os.PathLike | None = None) -> Motion:
    """Load a clip into a Motion (metres, Y up): a catalogue name (see `path` for where it is
    looked up) or a path to a `.bvh` file or an `.amc` file (its `.asf` given as `asf` or found
    beside it; `jaxtrack.data.resolve_clip`)."""
    if Path(name).expanduser().is_file():
        from jaxtrack.data._sources import resolve_clip

        return resolve_clip(name, asf=asf).load()
    return load_motion(path(os.fspath(name)))
