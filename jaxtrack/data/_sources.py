"""A clip given by catalogue name or by file path: what the commands and the priors read.

Everything that takes a clip (``jaxtrack evaluate --train/--test``, ``jaxtrack train --clips``,
:func:`jaxtrack.priors.train.train_prior`, :func:`jaxtrack.experiments.render_test_sequences`)
takes either a catalogue name (``cmu_amc/07_01``, see :mod:`jaxtrack.data._catalogue`) or a path
to a ``.bvh`` file or an ``.amc`` file, whose ``.asf`` skeleton is given or found beside it
(:func:`jaxtrack.body.motion.find_asf`). A path that names an existing file wins over a catalogue
name; a catalogue name reads exactly as it always did.

A file's identity in a cache key is its name and the SHA-256 of its bytes (and of its skeleton's),
so a copied file reuses a prior trained on it and an edited one does not.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

from jaxtrack.body.motion import Motion, find_asf, load_motion
from jaxtrack.data._catalogue import MOTION_SUFFIXES, path

__all__ = ["ClipSource", "clip_identity", "is_clip_file", "resolve_clip"]


@dataclass(frozen=True)
class ClipSource:
    """Where one clip's motion comes from.

    Attributes:
        spec: the catalogue name or path, as given.
        file: the ``.bvh`` or ``.amc`` file.
        asf: the skeleton of an ``.amc`` given by path (None for a BVH, and for a catalogue clip,
            whose ``.asf`` is found by the reader as always).
        from_catalogue: whether ``spec`` was a catalogue name.
    """

    spec: str
    file: Path
    asf: Path | None
    from_catalogue: bool

    @property
    def short_name(self) -> str:
        """The clip's own name: the last part of a catalogue name, a file's stem."""
        return self.spec.split("/")[-1] if self.from_catalogue else self.file.stem

    def load(self) -> Motion:
        """The clip as a Motion (metres, Y up)."""
        return load_motion(self.file, asf=self.asf)


def is_clip_file(spec: str | os.PathLike) -> bool:
    """Whether ``spec`` names an existing file (a path, not a catalogue name)."""
    return Path(spec).expanduser().is_file()


def resolve_clip(spec: str | os.PathLike, *, asf: str | os.PathLike | None = None) -> ClipSource:
    """Find the file behind a clip name or path.

    Args:
        spec: a catalogue name (``animateddrawings/fair1_wave_hello``) or a path to a ``.bvh``
            or ``.amc`` file.
        asf: the skeleton of an ``.amc`` path; by default found beside it (same subject prefix,
            same stem, or the only ``.asf`` in its folder). Not used for catalogue names.

    Raises:
        FileNotFoundError: no such file or clip (for a catalogue name, listing where it looked);
            :class:`~jaxtrack.body.motion.MissingSkeletonError` when an ``.amc``'s skeleton is
            neither given nor beside it.
        ValueError: the file is not a motion file (``.bvh`` or ``.amc``).
    """
    text = os.fspath(spec)
    file = Path(text).expanduser()
    if file.is_file():
        suffix = file.suffix.lower()
        if suffix not in MOTION_SUFFIXES:
            raise ValueError(f"{text}: not a motion file (expected .bvh, or .amc with its .asf)")
        skeleton = None
        if suffix == ".amc":
            if asf is None:
                skeleton = find_asf(file)
            elif Path(asf).expanduser().is_file():
                skeleton = Path(asf).expanduser()
            else:
                raise FileNotFoundError(f"no ASF skeleton file at {asf}")
        return ClipSource(text, file, skeleton, from_catalogue=False)
    try:
        found = path(text)
    except (FileNotFoundError, ValueError):
        if file.suffix.lower() in MOTION_SUFFIXES:
            raise FileNotFoundError(f"no motion file at {text}") from None
        raise
    if found.suffix.lower() not in MOTION_SUFFIXES:
        raise ValueError(f"{text} names {found.name}, not a motion clip (.bvh or .amc)")
    return ClipSource(text, found, None, from_catalogue=True)


def _digest(*files: Path) -> str:
    hasher = hashlib.sha256()
    for file in files:
        hasher.update(file.read_bytes())
    return hasher.hexdigest()[:16]


def clip_identity(spec: str | os.PathLike, *, asf: str | os.PathLike | None = None) -> str:
    """What a cache key records for a clip: a catalogue name as it is (nothing is read, so a
    cached prior needs no data files), a file as ``file:<name> sha256:<digest of its bytes and
    its skeleton's>``."""
    if not is_clip_file(spec):
        return os.fspath(spec)
    source = resolve_clip(spec, asf=asf)
    files = [source.file] + ([source.asf] if source.asf is not None else [])
    return f"file:{source.file.name} sha256:{_digest(*files)}"
