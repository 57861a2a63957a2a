"""Motion: world joint positions over time, read from real motion-capture files.

Every reader (BVH in `_bvh.py`, Acclaim ASF/AMC in `_asf.py`) ends in the same normal form, so the
rest of jaxtrack never sees a file's quirks:

- positions in **metres**, **Y up**, right-handed world coordinates, shape `(time, joints, 3)`;
- one joint per skeleton node (BVH `ROOT`/`JOINT`, ASF root and bones); BVH `End Site`s are
  dropped, and an ASF bone's joint sits at the bone's *start* (its proximal joint), which is also
  where the CMU-to-BVH conversions put it, so `rhumerus` is the shoulder exactly as BVH
  `RightShoulder`/`RightArm` is;
- `parents[j] < j` (parents come before children), `-1` for roots. Bandai's `joint_Root` (the
  hips projected on the ground) is kept as joint 0, but `Hips` is made a root of its own, because
  the ground point does not move rigidly with the body;
- `fps` is 1 / the file's frame time, snapped to a whole rate when within 0.01 Hz of one (files
  write 1/30 s as `0.0333333`); AnimatedDrawings' 0.008342 s stays 119.875 Hz. AMC files carry no
  rate: CMU captured at 120 Hz.

Joint counts of the real files: AnimatedDrawings 27, Bandai 22 (21 body joints + `joint_Root`),
CMU BVH 31 (both dialects), CMU ASF 31 (`root` + 30 bones; the AMC lists 29 lines per frame, root
and the 28 bones with DOFs), DeepMimic 16 (its 15 joints + `Head`, the head sphere's centre).

Units and axes per rig (what each reader converts from):

| rig | files | file unit | up axis |
|---|---|---|---|
| `cmu_asf` | CMU ASF/AMC | `:units length L` -> one unit = 1/L inch (CMU: 0.0254/0.45 m) | Y |
| `cmu_bvh` | CMU BVH (cgspeed, 31 joints) | same scaled inch as the ASF (0.0254/0.45 m) | Y |
| `animateddrawings` | AnimatedDrawings fair1/history (27 joints) | inch (0.0254 m), see below | Z |
| `bandai` | Bandai Namco Research Motiondataset-2 | centimetre | Y |
| `cmu_bvh_mb` | CMU BVH, MotionBuilder-friendly names (31 joints) | same scaled inch | Y |
| `deepmimic` | DeepMimic humanoid (16 joints, ZXY channels) | centimetre | Y |
| `generic_bvh` | anything else | guessed from body height (m, cm, mm or inch) | Y |

The rig is recognised from joint names, not from the folder: `cmu1_jumping_jacks.bvh` in the
AnimatedDrawings folder is a CMU BVH. Units were worked out from the bones: with 0.0254/0.45 m the
CMU subjects' femurs are 0.39-0.43 m and their hips 0.95 m above the floor; AnimatedDrawings
adults (cmu_1006, cmu_new clips) come out 1.6-1.65 m from head joint to floor, and the fair1 rig is
shared with the clip named `8yr_old_wave_hello`, a child about 1.1-1.2 m tall, in the same inches.
The MotionBuilder-friendly CMU files begin with a reference pose (every rotation 0 except fixed
hip, neck and arm corrections); the BVH reader drops that frame when it matches exactly, so frame 0
of such a Motion is the file's frame 1.
Z-up files are turned Y-up by a rotation (x, y, z) -> (x, z, -y), never a reflection, so a subject's
left stays left; every real clip was checked to face the way its toes point (DeepMimic keeps no
toe joint: the way its knees bend).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

__all__ = ["MissingSkeletonError", "MocapFormatError", "Motion", "counterpart_joint", "find_asf",
           "load_motion"]

RIGS = ("cmu_asf", "cmu_bvh", "animateddrawings", "bandai", "cmu_bvh_mb", "deepmimic",
        "generic_bvh")


class MocapFormatError(ValueError):
    """A motion-capture file cannot be read; the message names the file, the line and the fault."""

    def __init__(self, path: str | os.PathLike, line: int | None, problem: str):
        self.path = str(path)
        self.line = line
        self.problem = problem
        where = f"{self.path}, line {line}" if line is not None else self.path
        super().__init__(f"{where}: {problem}")


@dataclass(frozen=True, eq=False)
class Motion:
    """World joint positions of one captured performance.

    Attributes:
        positions: `(time, joints, 3)` float64 metres, Y up, from forward kinematics.
        joint_names: `(joints,)` names as written in the file.
        parents: `(joints,)` parent index per joint, `-1` for a root; parents precede children.
        fps: frames per second.
        source: the file the motion came from (or a description).
        rig: which skeleton convention the file follows, one of `RIGS`.
    """

    positions: np.ndarray
    joint_names: tuple[str, ...]
    parents: tuple[int, ...]
    fps: float
    source: str
    rig: str

    def __post_init__(self):
        positions = np.asarray(self.positions, dtype=np.float64)
        positions = positions.copy() if positions.flags.writeable else positions
        positions.flags.writeable = False  # frozen means frozen: cached clips are shared
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "joint_names", tuple(self.joint_names))
        object.__setattr__(self, "parents", tuple(int(p) for p in self.parents))
        object.__setattr__(self, "fps", float(self.fps))
        if positions.ndim != 3 or positions.shape[2] != 3:
            raise ValueError(f"positions must have shape (time, joints, 3), got {positions.shape}")
        if positions.shape[0] < 1:
            raise ValueError("a Motion needs at least one frame")
        if len(self.joint_names) != positions.shape[1] or len(self.parents) != positions.shape[1]:
            raise ValueError(
                f"positions has {positions.shape[1]} joints but there are "
                f"{len(self.joint_names)} joint names and {len(self.parents)} parents"
            )
        if any(not -1 <= p < j for j, p in enumerate(self.parents)):
            raise ValueError("every parent index must be -1 or the index of an earlier joint")
        if not np.isfinite(self.fps) or self.fps <= 0:
            raise ValueError(f"fps must be a positive number, got {self.fps}")
        if self.rig not in RIGS:
            raise ValueError(f"rig must be one of {RIGS}, got {self.rig!r}")
        if not np.all(np.isfinite(positions)):
            raise ValueError(f"{self.source}: positions contain NaN or infinity")

    @property
    def num_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def num_joints(self) -> int:
        return self.positions.shape[1]

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame."""
        return (self.num_frames - 1) / self.fps

    @property
    def bones(self) -> tuple[tuple[int, int], ...]:
        """`(parent, child)` index pairs, one per non-root joint."""
        return tuple((p, j) for j, p in enumerate(self.parents) if p >= 0)

    def joint_index(self, name: str) -> int:
        """Index of the joint called `name` (exact match)."""
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise KeyError(f"{self.source} ({self.rig}) has no joint {name!r}; "
                           f"joints: {list(self.joint_names)}") from None

    def _replace(self, positions: np.ndarray, fps: float | None = None) -> Motion:
        return Motion(positions, self.joint_names, self.parents,
                      self.fps if fps is None else fps, self.source, self.rig)

    def resample(self, fps: float) -> Motion:
        """The same motion at another frame rate, linearly interpolated in time.

        Frame k of the result is at time k / fps; the result stops at the last original frame.
        """
        if not np.isfinite(fps) or fps <= 0:
            raise ValueError(f"fps must be a positive number, got {fps}")
        ratio = self.fps / float(fps)
        # the small tolerance keeps e.g. 2x-then-0.5x from losing the last frame to rounding
        num_frames = int(np.floor((self.num_frames - 1) / ratio + 1e-9)) + 1
        source_index = np.minimum(np.arange(num_frames) * ratio, self.num_frames - 1)
        lower = np.floor(source_index + 1e-9).astype(int)
        lower = np.minimum(lower, self.num_frames - 1)
        upper = np.minimum(lower + 1, self.num_frames - 1)
        fraction = np.clip(source_index - lower, 0.0, 1.0)[:, None, None]
        positions = (1.0 - fraction) * self.positions[lower] + fraction * self.positions[upper]
        return self._replace(positions, fps=float(fps))

    def select(self, start: float, stop: float | None = None, *,
               unit: Literal["frames", "seconds"] = "frames") -> Motion:
        """Frames `[start, stop)`, given as frame indices or as seconds from the first frame."""
        if unit == "seconds":
            start_frame = int(round(start * self.fps))
            stop_frame = self.num_frames if stop is None else int(round(stop * self.fps))
        elif unit == "frames":
            start_frame = int(start)
            stop_frame = self.num_frames if stop is None else int(stop)
        else:
            raise ValueError(f"unit must be 'frames' or 'seconds', got {unit!r}")
        if not 0 <= start_frame < stop_frame <= self.num_frames:
            raise ValueError(
                f"cannot select frames [{start_frame}, {stop_frame}) from a motion of "
                f"{self.num_frames} frames ({self.duration:.3f} s at {self.fps:g} fps)"
            )
        return self._replace(self.positions[start_frame:stop_frame])

    def mirror(self) -> Motion:
        """The left-right mirror image of the performance.

        Positions are reflected across the subject's sagittal plane in the first frame (vertical,
        through the mean of the hip joints, normal to the left-right hip axis), the same fixed plane
        for every frame so trajectories mirror too. Then the data of each Left/Right joint pair is
        swapped, so joints named left are again on the subject's left: a right-hand wave becomes a
        left-hand wave.
        """
        pairs, left, right, normal = self._left_right("mirror")
        first = self.positions[0]
        centre = 0.5 * (first[left] + first[right]).mean(axis=0)
        distance = (self.positions - centre) @ normal
        reflected = self.positions - 2.0 * distance[..., None] * normal
        order = [self.joint_names.index(pairs[j]) if pairs[j] else j
                 for j in range(self.num_joints)]
        return self._replace(reflected[:, order])

    def _left_right(self, what: str) -> tuple[list, list[int], list[int], np.ndarray]:
        """Each joint's counterpart name (or None), the Left/Right pairs' indices, and the
        subject's left in the first frame as a level unit vector (the pairs' mean left − right
        difference, its height dropped)."""
        pairs = [counterpart_joint(name, self.joint_names) for name in self.joint_names]
        left = [j for j, name in enumerate(self.joint_names) if _side(name) == "left" and pairs[j]]
        if not left:
            raise ValueError(f"{self.source}: no Left/Right joint pairs to {what}")
        right = [self.joint_names.index(pairs[j]) for j in left]
        first = self.positions[0]
        across = (first[left] - first[right]).mean(axis=0)
        across[1] = 0.0  # level (Y up)
        return pairs, left, right, across / np.linalg.norm(across)

    def laid_down(self, face: Literal["up", "down"]) -> Motion:
        """The performance turned a quarter turn onto its back (``face="up"``) or its front
        (``"down"``), resting on the floor: the same joints moving the same way, lying.

        Each frame's pose turns about the horizontal axis through its trunk's centre (the mean
        of its pelvis, hips, shoulders and neck) along the subject's left-right axis (the first
        frame's, as :meth:`mirror` finds it), so the head goes backward (face up) or forward
        (face down) and the subject's left stays on its left; the centres keep their path over
        the floor, and their rise and fall is dropped (turned with the body, a walk forward
        would become a climb). Then the trunk is laid on the floor (the clip's lowest joint
        before the turn): its lowest point over the clip is lowered or lifted onto it, and a
        limb the turn takes below the floor (a hand held behind the back or in front of the
        chest) rests on it instead (its joints' height clamped to the floor). A standing
        gesture becomes a person lying and moving the same limbs: lying postures of real motion
        for a posture classifier, whose data hold few people lying down
        (``jaxtrack.experiments.mixed_state``).
        """
        from jaxtrack.body.markers import marker_positions

        if face not in ("up", "down"):
            raise ValueError(f"face must be 'up' or 'down', got {face!r}")
        *_, axis = self._left_right("tell its left from")  # the subject's left, level
        # +90 degrees about the left axis takes up to forward (face down); about the right
        # axis, up to backward (face up): Rodrigues' formula for a quarter turn
        axis = axis if face == "down" else -axis
        cross = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                          [-axis[1], axis[0], 0.0]])
        rotation = np.eye(3) + cross + cross @ cross
        trunk_markers = ("pelvis", "left_hip", "right_hip", "left_shoulder", "right_shoulder",
                         "neck")
        centre = marker_positions(self, trunk_markers).mean(axis=1, keepdims=True)
        centre[..., 1] = centre[..., 1].mean()
        turned = self._replace((self.positions - centre) @ rotation.T + centre)
        trunk = marker_positions(turned, trunk_markers)
        floor = self.positions[..., 1].min()
        positions = np.array(turned.positions)
        positions[..., 1] = np.maximum(positions[..., 1] + floor - trunk[..., 1].min(), floor)
        return self._replace(positions)


_SIDE_PATTERNS = (
    (re.compile(r"Left"), "Right"), (re.compile(r"Right"), "Left"),
    (re.compile(r"left"), "right"), (re.compile(r"right"), "left"),
    (re.compile(r"_L$"), "_R"), (re.compile(r"_R$"), "_L"),
    (re.compile(r"^L(?=[A-Z_])"), "R"), (re.compile(r"^R(?=[A-Z_])"), "L"),
    (re.compile(r"^l(?=[a-z])"), "r"), (re.compile(r"^r(?=[a-z])"), "l"),
)


def _side(name: str) -> str | None:
    if re.search(r"Left|left|_L$|^L(?=[A-Z_])|^l(?=[a-z])", name):
        return "left"
    if re.search(r"Right|right|_R$|^R(?=[A-Z_])|^r(?=[a-z])", name):
        return "right"
    return None


def counterpart_joint(name: str, joint_names: tuple[str, ...]) -> str | None:
    """The joint on the other side (`LeftArm` -> `RightArm`, `lhumerus` -> `rhumerus`,
    `Hand_L` -> `Hand_R`), or None when no such joint is in `joint_names`."""
    for pattern, replacement in _SIDE_PATTERNS:
        candidate = pattern.sub(replacement, name, count=1)
        if candidate != name and candidate in joint_names:
            return candidate
    return None


class MissingSkeletonError(FileNotFoundError):
    """An `.amc` file was given without its `.asf` skeleton and none was found beside it."""

    def __init__(self, amc_path: Path, tried: list[Path]):
        self.amc_path = Path(amc_path)
        self.tried = tuple(tried)
        super().__init__(f"{amc_path}: no skeleton file given and none found beside it (looked "
                         f"for {', '.join(path.name for path in tried)} or the only .asf in "
                         f"{self.amc_path.parent}); pass load_motion(path, asf=...)")


def find_asf(amc_path: str | os.PathLike) -> Path:
    """The `.asf` skeleton of an `.amc` file: beside it, the one named by the subject prefix
    (`07_01.amc` -> `07.asf`, the CMU convention), or by the same stem (`walk.amc` ->
    `walk.asf`), or else the only `.asf` in the folder; failing those, HDM05's convention, the
    actor's skeleton `HDM_<actor>.asf` of `HDM_<actor>_<class>_<take>.amc`, beside it or in an
    `asf` folder beside the clip's class folder (the `hdm05_cut` layout).

    Raises:
        MissingSkeletonError: none of these exists (or the folder holds several other `.asf`).
    """
    amc_path = Path(amc_path)
    subject = amc_path.stem.split("_")[0]
    stems = dict.fromkeys((subject, amc_path.stem))
    tried = [amc_path.with_name(f"{stem}{suffix}") for stem in stems for suffix in (".asf", ".ASF")]
    for candidate in tried:
        if candidate.is_file():
            return candidate
    folder = amc_path.parent if str(amc_path.parent) else Path(".")
    others = sorted(file for file in folder.iterdir()
                    if file.suffix.lower() == ".asf" and file.is_file())
    if len(others) == 1:
        return others[0]
    actor = "_".join(amc_path.stem.split("_")[:2])  # HDM_bd_lieDownFloor_001_120 -> HDM_bd
    if actor != amc_path.stem:
        for candidate in (folder / f"{actor}.asf", folder.parent / "asf" / f"{actor}.asf"):
            tried.append(candidate)
            if candidate.is_file():
                return candidate
    raise MissingSkeletonError(amc_path, [t for t in tried if t.suffix == ".asf"])


def load_motion(path: str | os.PathLike, *, asf: str | os.PathLike | None = None) -> Motion:
    """Read a `.bvh` file, or an `.amc` file with its `.asf` skeleton, into a `Motion`.

    Args:
        path: the motion file.
        asf: the skeleton for an `.amc` file; by default the `.asf` beside it (`find_asf`: named
            by the subject prefix, `07_01.amc` -> `07.asf`, or by the same stem, or the only
            `.asf` in the folder).

    Raises:
        MocapFormatError: the file is damaged (names the file and line).
        FileNotFoundError: the file (or the given `.asf`) does not exist;
            `MissingSkeletonError` when no `.asf` was given and none is beside the `.amc`.
    """
    # the readers import Motion and MocapFormatError from here, hence the late imports
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no motion file at {path}")
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        from jaxtrack.body._bvh import load_bvh

        return load_bvh(path)
    if suffix == ".amc":
        from jaxtrack.body._asf import load_asf_amc

        if asf is not None and not Path(asf).is_file():
            raise FileNotFoundError(f"no ASF skeleton file at {asf}")
        return load_asf_amc(Path(asf) if asf is not None else find_asf(path), path)
    raise ValueError(f"{path}: unknown motion format {suffix!r}; expected .bvh or .amc")
