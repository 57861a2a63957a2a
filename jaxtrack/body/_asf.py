"""Acclaim ASF (skeleton) + AMC (motion) reader, as written by the CMU mocap database.

Forward kinematics follows the Acclaim convention. Each bone has a fixed `axis` frame C (Euler
angles in the axis' order) and per-frame rotation M from its DOFs (in the order of the `dof` line):

    G_bone = G_parent @ C @ M @ C^-1,    end_bone = start_bone + length * G_bone @ direction

with `direction` given in world coordinates of the rest pose, and the root placed by the AMC
translation. An Euler order `XYZ` means rotate about X first: `R = Rz @ Ry @ Rx`.

Units: `:units length L` means one file unit is 1/L inch (CMU: L = 0.45), and the AMC root
translation uses the same unit. Angles are degrees unless `:units angle rad`. Y is up.

Joints of the resulting Motion: `root`, then one per bone (depth first from the root), placed at
the bone's *start* (so `lfemur` is the hip joint, `ltibia` the knee, `rhumerus` the shoulder); bone
ends with no child bone (head top, toe and finger tips) are dropped, as BVH End Sites are.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from jaxtrack.body._bvh import euler_matrices, read_lines, shown
from jaxtrack.body.motion import MocapFormatError, Motion

_INCH = 0.0254
_DOF_AXES = {"rx": "X", "ry": "Y", "rz": "Z"}
_TRANSLATIONS = {"tx": 0, "ty": 1, "tz": 2}


@dataclass
class _Bone:
    name: str
    line: int
    direction: np.ndarray | None = None
    length: float | None = None
    axis_angles: np.ndarray = field(default_factory=lambda: np.zeros(3))
    axis_order: str = "XYZ"
    dofs: list[str] = field(default_factory=list)
    parent: int = -1


def _order_matrix(angles_degrees: np.ndarray, order: str) -> np.ndarray:
    # Acclaim orders list the first rotation applied first, i.e. rightmost in the product
    return euler_matrices(np.asarray(angles_degrees)[..., ::-1], order[::-1])


def _floats(path: Path, line: int, tokens: list[str], count: int, what: str) -> np.ndarray:
    if len(tokens) < count:
        raise MocapFormatError(path, line, f"{what} needs {count} numbers, found {len(tokens)}")
    try:
        return np.array([float(t) for t in tokens[:count]])
    except ValueError:
        numbers = shown(" ".join(tokens[:count]))
        raise MocapFormatError(path, line, f"{what}: {numbers} are not all numbers") from None


@dataclass
class AsfSkeleton:
    """Parsed ASF: root DOF order, root axis frame, bones in file order, length unit (metres)."""

    root_order: list[str]
    root_axis: str
    root_orientation: np.ndarray
    bones: list[_Bone]
    metres_per_unit: float
    angles_in_degrees: bool


def parse_asf(path: Path) -> AsfSkeleton:
    """Read an ASF file; raise MocapFormatError naming the line of any fault."""
    lines = read_lines(path, "an ASF")
    section, bone, metres_per_unit, degrees = None, None, _INCH / 0.45, True
    root_order = ["TX", "TY", "TZ", "RX", "RY", "RZ"]
    root_axis, root_orientation = "XYZ", np.zeros(3)
    bones: list[_Bone] = []
    names: dict[str, int] = {"root": -1}
    hierarchy_seen = False
    for number, raw in enumerate(lines, start=1):
        tokens = raw.split()
        if not tokens or tokens[0].startswith("#"):
            continue
        if tokens[0].startswith(":"):
            section = tokens[0]
            continue
        key = tokens[0].lower()
        if section == ":units" and key == "length":
            scale = _floats(path, number, tokens[1:], 1, "length unit")[0]
            if scale <= 0:
                raise MocapFormatError(path, number, f"length unit must be positive, got {scale}")
            metres_per_unit = _INCH / scale
        elif section == ":units" and key == "angle":
            degrees = tokens[1:2] != ["rad"]
        elif section == ":root" and key == "order":
            root_order = [t.upper() for t in tokens[1:]]
        elif section == ":root" and key == "axis":
            root_axis = tokens[1].upper() if len(tokens) > 1 else "XYZ"
        elif section == ":root" and key == "orientation":
            root_orientation = _floats(path, number, tokens[1:], 3, "root orientation")
        elif section == ":bonedata":
            if key == "begin":
                bone = _Bone(name="", line=number)
            elif key == "end":
                if bone is None or not bone.name or bone.direction is None or bone.length is None:
                    raise MocapFormatError(path, number,
                                           "bone block lacks name, direction or length")
                if bone.name in names:
                    raise MocapFormatError(path, number, f"bone {shown(bone.name)} defined twice")
                names[bone.name] = len(bones)
                bones.append(bone)
                bone = None
            elif bone is None:
                raise MocapFormatError(path, number,
                                       f"{shown(tokens[0])} outside a begin/end bone block")
            elif key == "name":
                bone.name = tokens[1] if len(tokens) > 1 else ""
            elif key == "direction":
                bone.direction = _floats(path, number, tokens[1:], 3, "direction")
            elif key == "length":
                bone.length = float(_floats(path, number, tokens[1:], 1, "length")[0])
            elif key == "axis":
                bone.axis_angles = _floats(path, number, tokens[1:], 3, "axis")
                bone.axis_order = tokens[4].upper() if len(tokens) > 4 else "XYZ"
            elif key == "dof":
                bone.dofs = [t.lower() for t in tokens[1:]]
                unknown = [d for d in bone.dofs if d not in _DOF_AXES]
                if unknown:
                    raise MocapFormatError(path, number, f"unsupported dof(s) {unknown}")
        elif section == ":hierarchy" and key not in ("begin", "end"):
            hierarchy_seen = True
            if tokens[0] not in names:
                raise MocapFormatError(path, number,
                                       f"hierarchy names unknown bone {shown(tokens[0])}")
            for child in tokens[1:]:
                if child not in names or child == "root":
                    raise MocapFormatError(path, number,
                                           f"hierarchy names unknown bone {shown(child)}")
                bones[names[child]].parent = names[tokens[0]]
    if bone is not None:
        raise MocapFormatError(path, len(lines),
                               f"file ends inside the bone block begun at line {bone.line}")
    if not bones:
        raise MocapFormatError(path, len(lines), "no :bonedata bones (not an ASF file?)")
    if not hierarchy_seen:
        raise MocapFormatError(path, len(lines), "no :hierarchy section (truncated?)")
    if len(root_order) != 6 or set(root_order) != {"TX", "TY", "TZ", "RX", "RY", "RZ"}:
        raise MocapFormatError(path, None, f"root order must list TX TY TZ RX RY RZ: {root_order}")
    return AsfSkeleton(root_order, root_axis, root_orientation, bones, metres_per_unit, degrees)


def parse_amc(path: Path, skeleton: AsfSkeleton) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Read an AMC file -> root values `(time, 6)` in `root_order` and DOF values per bone."""
    lines = read_lines(path, "an AMC")
    expected = {bone.name: len(bone.dofs) for bone in skeleton.bones if bone.dofs}
    expected["root"] = 6
    frames: list[dict[str, list[float]]] = []
    frame_lines: list[int] = []
    for number, raw in enumerate(lines, start=1):
        tokens = raw.split()
        if not tokens or tokens[0].startswith(("#", ":")):
            continue
        if len(tokens) == 1 and tokens[0].isdigit():
            if frames and len(frames[-1]) != len(expected):
                _missing(path, frame_lines[-1], frames[-1], expected)
            frames.append({})
            frame_lines.append(number)
            continue
        if not frames:
            raise MocapFormatError(path, number,
                                   f"{shown(tokens[0])} before the first frame number "
                                   "(not an AMC file?)")
        name = tokens[0]
        if name not in expected:
            raise MocapFormatError(path, number,
                                   f"unknown bone {shown(name)} (not in the ASF, or it has no dof)")
        if len(tokens) - 1 != expected[name]:
            raise MocapFormatError(path, number, f"bone {shown(name)} has {len(tokens) - 1} "
                                   "values, "
                                   f"the ASF declares {expected[name]}")
        values = _floats(path, number, tokens[1:], expected[name], f"bone {shown(name)}")
        if not np.all(np.isfinite(values)):
            raise MocapFormatError(path, number, f"non-finite value for bone {shown(name)}")
        frames[-1][name] = values
    if not frames:
        raise MocapFormatError(path, len(lines), "no frames (empty motion)")
    if len(frames[-1]) != len(expected):
        _missing(path, frame_lines[-1], frames[-1], expected)
    dofs = {name: np.array([frame[name] for frame in frames]) for name in expected}
    return dofs.pop("root"), dofs


def _missing(path: Path, line: int, frame: dict, expected: dict) -> None:
    missing = sorted(set(expected) - set(frame))
    raise MocapFormatError(path, line, f"frame is missing bone(s) {missing} (truncated?)")


def load_asf_amc(asf_path: Path, amc_path: Path) -> Motion:
    """Read a CMU ASF skeleton and AMC motion into a Motion (metres, Y up, 120 Hz)."""
    skeleton = parse_asf(asf_path)
    root_values, dofs = parse_amc(amc_path, skeleton)
    to_degrees = 1.0 if skeleton.angles_in_degrees else 180.0 / np.pi
    num_frames = root_values.shape[0]
    translation_columns = [skeleton.root_order.index(t.upper()) for t in _TRANSLATIONS]
    rotation_columns = [i for i, name in enumerate(skeleton.root_order) if name.startswith("R")]
    rotation_order = "".join(skeleton.root_order[i][1] for i in rotation_columns)
    root_frame = _order_matrix(skeleton.root_orientation, skeleton.root_axis)
    root_motion = _order_matrix(root_values[:, rotation_columns] * to_degrees, rotation_order)
    bones = skeleton.bones
    starts = np.zeros((num_frames, len(bones) + 1, 3))
    ends = np.zeros((num_frames, len(bones), 3))
    rotations = np.zeros((num_frames, len(bones), 3, 3))
    root_position = root_values[:, translation_columns]
    root_rotation = root_frame @ root_motion @ root_frame.T
    starts[:, 0] = root_position
    # bones may be listed before their parents in an ASF, so walk the tree from the root
    order = _tree_order(bones, asf_path)
    for index in order:
        bone = bones[index]
        frame = _order_matrix(bone.axis_angles, bone.axis_order)
        if bone.dofs:
            axes = "".join(_DOF_AXES[d] for d in bone.dofs)
            motion = _order_matrix(dofs[bone.name] * to_degrees, axes)
        else:
            motion = np.eye(3)
        if bone.parent < 0:
            parent_rotation, start = root_rotation, root_position
        else:
            parent_rotation, start = rotations[:, bone.parent], ends[:, bone.parent]
        rotations[:, index] = parent_rotation @ frame @ motion @ frame.T
        starts[:, index + 1] = start
        ends[:, index] = start + bone.length * np.einsum(
            "tij,j->ti", rotations[:, index], bone.direction)
    parents, names = _motion_parents(bones, order)
    positions = starts[:, [0] + [i + 1 for i in order]] * skeleton.metres_per_unit
    if not np.all(np.isfinite(positions)):
        raise MocapFormatError(amc_path, None, "forward kinematics gave non-finite positions")
    # AMC files carry no frame rate; the CMU database records at 120 Hz
    return Motion(positions, names, parents, 120.0, str(amc_path), "cmu_asf")


def _tree_order(bones: list[_Bone], asf_path: Path) -> list[int]:
    children: dict[int, list[int]] = {}
    for index, bone in enumerate(bones):
        children.setdefault(bone.parent, []).append(index)
    order, stack = [], list(reversed(children.get(-1, [])))
    while stack:
        index = stack.pop()
        order.append(index)
        stack.extend(reversed(children.get(index, [])))
    if len(order) != len(bones):
        unreached = [bones[i].name for i in range(len(bones)) if i not in set(order)]
        raise MocapFormatError(asf_path, None, f"bones not connected to the root: {unreached}")
    return order


def _motion_parents(bones: list[_Bone],
                    order: list[int]) -> tuple[tuple[int, ...], tuple[str, ...]]:
    # joint 0 is the root; a bone's joint (its start) hangs from its parent bone's joint
    position = {index: slot + 1 for slot, index in enumerate(order)}
    parents = [-1] + [0 if bones[i].parent < 0 else position[bones[i].parent] for i in order]
    return tuple(parents), ("root",) + tuple(bones[i].name for i in order)
