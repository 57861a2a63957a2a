"""BioVision BVH reader: hierarchy, bulk-parsed MOTION block, vectorised forward kinematics.

Conventions handled (all seen in the files under shared/data):
- any rotation channel order per joint; a joint's local rotation is the product of its rotation
  channels in the order listed (`Zrotation Xrotation Yrotation` -> Rz @ Rx @ Ry), angles in degrees;
- position channels on any joint replace that joint's OFFSET (Bandai puts 6 channels on every joint;
  Blender reads them the same way);
- `Frames:`/`Frame Time:` separated by spaces or tabs, numbers such as `.0083333`;
- `End Site` blocks are parsed and dropped: a Motion has one joint per ROOT/JOINT;
- the CMU MotionBuilder-friendly dialect's frame 0 is a reference pose, not motion: it is dropped
  when it is recognised exactly (`_drops_reference_frame`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jaxtrack.body.motion import MocapFormatError, Motion

_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}
_INCH = 0.0254
_CMU_UNIT = _INCH / 0.45  # CMU ASF `:units length 0.45`; the cgspeed BVHs keep that unit


def axis_rotations(angles: np.ndarray, axis: str) -> np.ndarray:
    """Rotation matrices about one axis. angles: `(time,)` radians -> `(time, 3, 3)`."""
    cosine, sine = np.cos(angles), np.sin(angles)
    matrices = np.zeros(angles.shape + (3, 3))
    i = _AXIS_INDEX[axis]
    j, k = (i + 1) % 3, (i + 2) % 3
    matrices[..., i, i] = 1.0
    matrices[..., j, j] = cosine
    matrices[..., k, k] = cosine
    matrices[..., j, k] = -sine
    matrices[..., k, j] = sine
    return matrices


def euler_matrices(angles_degrees: np.ndarray, axes: str) -> np.ndarray:
    """`R = R_axes[0] @ R_axes[1] @ ...` (intrinsic order as in BVH CHANNELS).

    angles_degrees: `(time, len(axes))` -> `(time, 3, 3)`.
    """
    angles = np.deg2rad(np.asarray(angles_degrees, dtype=np.float64))
    result = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for column, axis in enumerate(axes):
        result = result @ axis_rotations(angles[..., column], axis)
    return result


@dataclass
class BvhSkeleton:
    """The HIERARCHY block: per joint its name, parent, OFFSET `(3,)` and CHANNELS."""

    names: list[str]
    parents: list[int]
    offsets: list[np.ndarray]
    channels: list[list[str]]


_CHANNEL_NAMES = {f"{axis}{kind}" for axis in "XYZ" for kind in ("position", "rotation")}


def read_lines(path: Path, kind: str) -> list[str]:
    """The lines of a text file (`kind` names it: "a BVH"); MocapFormatError if not text.

    Binary data (a NUL byte, or more than 5 % of the first 64 KiB undecodable or control
    characters) is refused in one line instead of being parsed and quoted back.
    """
    try:
        data = path.read_bytes()
    except OSError as error:
        raise MocapFormatError(path, None, f"cannot read: {error}") from error
    text = data.decode("utf-8-sig", errors="replace")
    sample = text[:65536]
    odd = sum(1 for c in sample
              if c == "\ufffd" or (not c.isprintable() and c not in "\t\n\r\f\v"))
    if "\x00" in sample or odd > 0.05 * len(sample):
        raise MocapFormatError(path, None, f"not {kind} file: it holds binary data, not text")
    return text.splitlines()


def shown(text: str, limit: int = 40) -> str:
    """`text` quoted for an error message: at most `limit` characters, unprintable ones as '?'."""
    clean = "".join(c if c.isprintable() and c != "\ufffd" else "?" for c in text[:limit])
    return repr(clean + ("..." if len(text) > limit else ""))


def _tokens(lines: list[str], first: int, last: int):
    for number in range(first, last):
        for token in lines[number].split():
            yield token, number + 1


def parse_hierarchy(path: Path, lines: list[str], motion_line: int) -> BvhSkeleton:
    """Parse lines `[0, motion_line)`; raise MocapFormatError naming the line of any fault."""
    skeleton = BvhSkeleton([], [], [], [])
    stream = _tokens(lines, 0, motion_line)

    def take(expected: str) -> tuple[str, int]:
        try:
            return next(stream)
        except StopIteration:
            raise MocapFormatError(
                path, motion_line or len(lines),
                f"file ends inside HIERARCHY while expecting {expected}") from None

    def numbers(count: int, what: str) -> tuple[list[float], int]:
        values = []
        line = 0
        for _ in range(count):
            token, line = take(what)
            try:
                values.append(float(token))
            except ValueError:
                raise MocapFormatError(path, line,
                                       f"{what}: {shown(token)} is not a number") from None
        return values, line

    token, line = take("HIERARCHY")
    if token != "HIERARCHY":
        raise MocapFormatError(path, line,
                               f"expected 'HIERARCHY', found {shown(token)} (not a BVH file?)")
    stack: list[int | None] = []  # joint index per open brace, None for an End Site
    pending: int | None | str = "start"
    while True:
        try:
            token, line = next(stream)
        except StopIteration:
            break
        if token in ("ROOT", "JOINT"):
            name, line = take("a joint name")
            if token == "JOINT" and (not stack or stack[-1] is None):
                raise MocapFormatError(path, line, f"JOINT {name} is outside any joint")
            if token == "ROOT" and stack:
                raise MocapFormatError(path, line, f"ROOT {name} inside another joint")
            skeleton.names.append(name)
            skeleton.parents.append(stack[-1] if stack else -1)
            skeleton.offsets.append(np.zeros(3))
            skeleton.channels.append([])
            pending = len(skeleton.names) - 1
        elif token == "End":
            site, line = take("'Site'")
            if site != "Site" or not stack or stack[-1] is None:
                raise MocapFormatError(path, line, "misplaced 'End Site'")
            pending = None
        elif token == "{":
            if pending == "start":
                raise MocapFormatError(path, line, "'{' before any ROOT")
            stack.append(pending)  # type: ignore[arg-type]
            pending = "start"
        elif token == "}":
            if not stack:
                raise MocapFormatError(path, line, "unmatched '}'")
            stack.pop()
        elif token == "OFFSET":
            values, line = numbers(3, "OFFSET")
            if stack and stack[-1] is not None:
                skeleton.offsets[stack[-1]] = np.array(values)
        elif token == "CHANNELS":
            (count,), line = numbers(1, "CHANNELS count")
            if not stack or stack[-1] is None or count != int(count) or not 0 <= count <= 6:
                raise MocapFormatError(path, line, f"bad CHANNELS count {count}")
            names = [take("a channel name")[0] for _ in range(int(count))]
            unknown = [c for c in names if c not in _CHANNEL_NAMES]
            if unknown:
                raise MocapFormatError(path, line, f"unknown channel(s) {unknown}")
            skeleton.channels[stack[-1]] = names
        else:
            raise MocapFormatError(path, line, f"unexpected {shown(token)} in HIERARCHY")
    if stack:
        raise MocapFormatError(path, motion_line or len(lines),
                               f"HIERARCHY ends with {len(stack)} unclosed '{{'")
    if not skeleton.names:
        raise MocapFormatError(path, 1, "HIERARCHY has no ROOT joint")
    return skeleton


def _header_value(path: Path, lines: list[str], number: int, label: str) -> float:
    if number >= len(lines):
        raise MocapFormatError(path, number, f"file ends before '{label}'")
    text = lines[number].strip()
    if not text.startswith(label):
        raise MocapFormatError(path, number + 1, f"expected '{label}', found {shown(text)}")
    try:
        return float(text[len(label):])
    except ValueError:
        raise MocapFormatError(path, number + 1, f"bad value after '{label}'") from None


def parse_motion_block(path: Path, lines: list[str], motion_line: int,
                       num_channels: int) -> tuple[np.ndarray, float]:
    """Parse `Frames:`, `Frame Time:` and the frame lines -> (`(time, channels)`, seconds)."""
    frames = _header_value(path, lines, motion_line + 1, "Frames:")
    frame_time = _header_value(path, lines, motion_line + 2, "Frame Time:")
    if frames != int(frames) or frames < 1:
        raise MocapFormatError(path, motion_line + 2, f"the file declares {frames:g} frames")
    if not np.isfinite(frame_time) or frame_time <= 0:
        raise MocapFormatError(path, motion_line + 3, f"frame time must be positive: {frame_time}")
    frames = int(frames)
    first = motion_line + 3  # index of the first frame line
    body = [(number, text) for number, text in enumerate(lines[first:], start=first + 1)
            if text.strip()]
    # a per-line count is cheap next to float parsing and catches a dropped value on any line
    for number, text in body[:frames]:
        count = len(text.split())
        if count != num_channels:
            raise MocapFormatError(path, number, f"frame line has {count} values, the HIERARCHY "
                                   f"declares {num_channels} channels")
    if len(body) != frames:
        where = body[-1][0] if body else first
        raise MocapFormatError(path, where, f"the file declares {frames} frames but has "
                               f"{len(body)} frame lines (truncated or padded?)")
    try:
        values = np.array(" ".join(text for _, text in body).split(), dtype=np.float64)
    except ValueError:
        values = None
    if values is None or not np.all(np.isfinite(values)):
        for number, text in body:  # slow path: only to name the bad line
            for token in text.split():
                try:
                    value = float(token)
                except ValueError:
                    raise MocapFormatError(path, number,
                                           f"{shown(token)} is not a number") from None
                if not np.isfinite(value):
                    raise MocapFormatError(path, number, f"non-finite value {shown(token)}")
    return values.reshape(frames, num_channels), frame_time


def forward_kinematics(skeleton: BvhSkeleton, values: np.ndarray) -> np.ndarray:
    """World positions of every joint, in file units and axes.

    values: `(time, channels)` -> `(time, joints, 3)`.
    """
    num_frames = values.shape[0]
    positions = np.zeros((num_frames, len(skeleton.names), 3))
    rotations = np.zeros((num_frames, len(skeleton.names), 3, 3))
    column = 0
    for joint, channels in enumerate(skeleton.channels):
        translation = np.broadcast_to(skeleton.offsets[joint], (num_frames, 3)).copy()
        rotation_axes, rotation_columns = "", []
        for name in channels:
            if name.endswith("position"):
                translation[:, _AXIS_INDEX[name[0]]] = values[:, column]
            else:
                rotation_axes += name[0]
                rotation_columns.append(column)
            column += 1
        local = euler_matrices(values[:, rotation_columns], rotation_axes)
        parent = skeleton.parents[joint]
        if parent < 0:
            positions[:, joint] = translation
            rotations[:, joint] = local
        else:
            positions[:, joint] = positions[:, parent] + np.einsum(
                "tij,tj->ti", rotations[:, parent], translation)
            rotations[:, joint] = rotations[:, parent] @ local
    return positions


def detect_rig(names: list[str]) -> str:
    """Which known skeleton convention a BVH hierarchy follows, from its joint names."""
    found = set(names)
    if "joint_Root" in found and {"UpperArm_L", "LowerLeg_R"} <= found:
        return "bandai"
    if {"LHipJoint", "lowerback", "Chest2", "LeftCollar"} <= found:
        return "cmu_bvh"
    if {"Spine3", "RightHandThumb1", "RightHandEnd", "RightToeBase"} <= found and len(names) == 27:
        return "animateddrawings"
    # cgspeed's MotionBuilder-friendly CMU conversion: the ASF bones under MotionBuilder names
    # (lowerback -> LowerBack, upperneck -> Neck1, lhand -> LeftFingerBase, ...)
    if {"LHipJoint", "LowerBack", "Spine1", "Neck1", "LeftFingerBase", "LThumb"} <= found:
        return "cmu_bvh_mb"
    if found == _DEEPMIMIC_JOINTS and len(names) == len(_DEEPMIMIC_JOINTS):
        return "deepmimic"
    return "generic_bvh"


_DEEPMIMIC_JOINTS = frozenset(
    ("Hips", "Spine", "Neck", "Head")
    + tuple(f"{side}{part}" for side in ("Left", "Right")
            for part in ("Arm", "ForeArm", "Hand", "UpLeg", "Leg", "Foot")))
"""The DeepMimic humanoid's 15 joints plus the head sphere's centre, nothing else."""

# The reference frame cgspeed's MotionBuilder-friendly conversion puts before the motion: every
# rotation 0 except these whole-degree rest corrections (root position free). Matching it exactly
# cannot drop a captured frame by accident.
_CMU_MB_REFERENCE_POSE = {
    ("LeftUpLeg", "Zrotation"): -21.0, ("RightUpLeg", "Zrotation"): 21.0,
    ("Neck", "Xrotation"): -16.0, ("Neck1", "Xrotation"): 21.0, ("Head", "Xrotation"): 11.0,
    ("LeftArm", "Zrotation"): -8.0, ("RightArm", "Zrotation"): 8.0,
}


def _drops_reference_frame(rig: str, skeleton: BvhSkeleton, values: np.ndarray) -> bool:
    """Whether frame 0 is the CMU MotionBuilder-friendly reference pose (and motion follows it).

    This is decided here, from what the file holds, rather than in the data catalogue: the pose
    belongs to the conversion dialect, not to a folder, so a clip loaded by path (or copied
    elsewhere) loses it too, and a file of that dialect without it keeps every frame.
    """
    if rig != "cmu_bvh_mb" or values.shape[0] < 2:
        return False
    columns, expected = [], []
    column = 0
    for name, channels in zip(skeleton.names, skeleton.channels, strict=True):
        for channel in channels:
            if channel.endswith("rotation"):
                columns.append(column)
                expected.append(_CMU_MB_REFERENCE_POSE.get((name, channel), 0.0))
            column += 1
    return bool(np.array_equal(values[0, columns], expected))


def _to_y_up(positions: np.ndarray) -> np.ndarray:
    # a rotation by -90 degrees about X, (x, y, z) -> (x, z, -y): Z-up becomes Y-up and
    # handedness is kept, so the subject's left stays left
    return np.stack([positions[..., 0], positions[..., 2], -positions[..., 1]], axis=-1)


def _guess_unit(positions: np.ndarray) -> float:
    # a standing adult is 1.5-1.9 m tall; pick the unit that makes the first frame closest to that
    height = np.ptp(positions[0, :, 1])
    units = np.array([1.0, 0.01, 0.001, _INCH])
    if height <= 0:
        return 1.0
    return float(units[np.argmin(np.abs(np.log(height * units / 1.7)))])


_RIG_UNIT_AND_UP = {"cmu_bvh": (_CMU_UNIT, "Y"), "animateddrawings": (_INCH, "Z"),
                    "bandai": (0.01, "Y"), "cmu_bvh_mb": (_CMU_UNIT, "Y"),
                    "deepmimic": (0.01, "Y")}


def load_bvh(path: Path) -> Motion:
    """Read a BVH file into a Motion in metres, Y up (see jaxtrack.body.motion for the table)."""
    lines = read_lines(path, "a BVH")
    first = next((n for n, line in enumerate(lines) if line.strip()), None)
    if first is None:
        raise MocapFormatError(path, 1, "empty file")
    if lines[first].split()[0] != "HIERARCHY":
        raise MocapFormatError(path, first + 1, f"expected 'HIERARCHY', found "
                               f"{shown(lines[first].strip())} (missing hierarchy, or not BVH)")
    motion_line = next((n for n, line in enumerate(lines) if line.strip() == "MOTION"), None)
    if motion_line is None:
        parse_hierarchy(path, lines, len(lines))  # reports a broken hierarchy first if there is one
        raise MocapFormatError(path, len(lines), "no MOTION section (header only or truncated)")
    skeleton = parse_hierarchy(path, lines, motion_line)
    num_channels = sum(len(channels) for channels in skeleton.channels)
    values, frame_time = parse_motion_block(path, lines, motion_line, num_channels)
    rig = detect_rig(skeleton.names)
    if _drops_reference_frame(rig, skeleton, values):
        values = values[1:]  # the Motion's frame 0 is the file's frame 1, 1/fps s into the file
    positions = forward_kinematics(skeleton, values)
    unit, up = _RIG_UNIT_AND_UP.get(rig, (None, "Y"))
    if up == "Z":
        positions = _to_y_up(positions)
    positions = positions * (unit if unit is not None else _guess_unit(positions))
    if not np.all(np.isfinite(positions)):
        raise MocapFormatError(path, motion_line + 4,
                               "forward kinematics gave non-finite positions")
    parents = list(skeleton.parents)
    if rig == "bandai":
        # joint_Root is the hips' projection on the ground, not a rigid bone: keep it as a joint
        # but make Hips a root of its own so bones (drawing, bone-length checks) are the body's
        parents[skeleton.names.index("Hips")] = -1
    # frame times are written to a few digits (1/30 s as 0.0333333, 1/120 s as .0083333): snap to
    # the whole rate they stand for, but keep rates that are not whole (0.008342 s = 119.875 Hz)
    fps = 1.0 / frame_time
    fps = float(round(fps)) if abs(fps - round(fps)) < 0.01 else fps
    return Motion(positions, tuple(skeleton.names), tuple(parents), fps, str(path), rig)
