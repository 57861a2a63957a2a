"""Damaged motion files, made from the real ones, raise MocapFormatError naming file and line."""

import re
from pathlib import Path

import numpy as np
import pytest

from jaxtrack.body.motion import MocapFormatError, load_motion
from jaxtrack.data import bundled_folder

BUNDLED = bundled_folder()
TESTS_DATA = Path(__file__).parents[1] / "data"
BVH_SOURCES = {
    "cmu": BUNDLED / "cmu_bvh_131" / "131_01.bvh",  # ZYX, '.0083333'
    "fair1": BUNDLED / "animateddrawings_bvh" / "fair1_wave_hello.bvh",  # XYZ, Z up
    "bandai": TESTS_DATA / "bandai_namco_gestures" / "dataset-2_wave-left-hand_normal_001.bvh",
}
ASF = BUNDLED / "cmu_asfamc_walk" / "07.asf"
AMC = BUNDLED / "cmu_asfamc_walk" / "07_01.amc"


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines()


def _motion_line(lines: list[str]) -> int:
    return next(n for n, line in enumerate(lines) if line.strip() == "MOTION")


def _frame(lines: list[str], k: int) -> int:
    """0-based list index of frame k's line."""
    return _motion_line(lines) + 3 + k


def _drop_value(lines, k):
    index = _frame(lines, k)
    lines[index] = " ".join(lines[index].split()[:-1])
    return lines, index + 1


def _put_abc(lines, k):
    index = _frame(lines, k)
    values = lines[index].split()
    values[4] = "abc"
    lines[index] = " ".join(values)
    return lines, index + 1


def _put_nan(lines, k):
    index = _frame(lines, k)
    values = lines[index].split()
    values[7] = "nan"
    lines[index] = " ".join(values)
    return lines, index + 1


def _truncate_mid_frame(lines, k):
    index = _frame(lines, k)
    lines[index] = lines[index][: len(lines[index]) // 2]
    return lines[: index + 1], index + 1


def _zero_frames(lines, _):
    motion = _motion_line(lines)
    return lines[: motion + 1] + ["Frames: 0", "Frame Time: 0.0333333"], motion + 2


def _header_only(lines, _):
    return lines[: _motion_line(lines)], None


def _truncated_hierarchy(lines, _):
    return lines[: _motion_line(lines) // 2], None


def _no_hierarchy(lines, _):
    return lines[_motion_line(lines):], 1


def _unbalanced_brace(lines, _):
    index = next(n for n, line in enumerate(lines) if line.strip() == "}")
    return lines[:index] + lines[index + 1:], None


def _zero_frame_time(lines, _):
    index = _motion_line(lines) + 2
    lines[index] = "Frame Time: 0"
    return lines, index + 1


def _extra_frame_line(lines, _):
    return lines + [lines[-1]], None


def _empty(lines, _):
    return [], 1


BVH_DAMAGE = {
    "drop_value": _drop_value, "abc": _put_abc, "nan": _put_nan,
    "truncated_mid_frame": _truncate_mid_frame, "zero_frames": _zero_frames,
    "header_only": _header_only, "truncated_hierarchy": _truncated_hierarchy,
    "no_hierarchy": _no_hierarchy, "unbalanced_brace": _unbalanced_brace,
    "zero_frame_time": _zero_frame_time, "extra_frame_line": _extra_frame_line, "empty": _empty,
}


def _check(error: MocapFormatError, path: Path, line: int | None) -> None:
    message = str(error)
    assert str(path) in message and path.name in message
    found = re.search(r"line (\d+)", message)
    assert found is not None, message
    if line is not None:
        assert int(found.group(1)) == line, message


@pytest.mark.parametrize("source", sorted(BVH_SOURCES))
@pytest.mark.parametrize("damage", sorted(BVH_DAMAGE))
def test_damaged_bvh(tmp_path, source, damage):
    lines, line = BVH_DAMAGE[damage](_lines(BVH_SOURCES[source]), 17)
    path = tmp_path / f"{damage}_{source}.bvh"
    path.write_text("\n".join(lines) + ("\n" if lines else ""))
    with pytest.raises(MocapFormatError) as caught:
        load_motion(path)
    _check(caught.value, path, line)
    assert isinstance(caught.value, ValueError)


def _asf_truncated(lines):
    index = next(n for n, line in enumerate(lines) if "name lradius" in line)
    return lines[:index], None


def _asf_bad_length(lines):
    index = next(n for n, line in enumerate(lines) if "length" in line and n > 20)
    lines[index] = "     length 6.9x"
    return lines, index + 1


def _asf_unknown_child(lines):
    index = next(n for n, line in enumerate(lines) if line.strip() == "lhumerus lradius")
    lines[index] = "    lhumerus lradius elbow2"
    return lines, index + 1


def _asf_no_hierarchy(lines):
    return lines[: next(n for n, line in enumerate(lines) if line.startswith(":hierarchy"))], None


ASF_DAMAGE = {"truncated": _asf_truncated, "bad_length": _asf_bad_length,
              "unknown_child": _asf_unknown_child, "no_hierarchy": _asf_no_hierarchy}


@pytest.mark.parametrize("damage", sorted(ASF_DAMAGE))
def test_damaged_asf(tmp_path, damage):
    lines, line = ASF_DAMAGE[damage](_lines(ASF))
    asf = tmp_path / "07.asf"
    asf.write_text("\n".join(lines) + "\n")
    (tmp_path / "07_01.amc").write_text(AMC.read_text())
    with pytest.raises(MocapFormatError) as caught:
        load_motion(tmp_path / "07_01.amc")
    _check(caught.value, asf, line)


def _amc_line(lines, bone, frame):
    hits = [n for n, line in enumerate(lines) if line.split()[:1] == [bone]]
    return hits[frame]


def _amc_unknown_joint(lines):
    index = _amc_line(lines, "rtibia", 5)
    lines[index] = lines[index].replace("rtibia", "rknee")
    return lines, index + 1


def _amc_drop_value(lines):
    index = _amc_line(lines, "lfemur", 9)
    lines[index] = " ".join(lines[index].split()[:-1])
    return lines, index + 1


def _amc_abc(lines):
    index = _amc_line(lines, "root", 3)
    lines[index] = lines[index].replace(lines[index].split()[2], "abc")
    return lines, index + 1


def _amc_truncated(lines):
    index = _amc_line(lines, "thorax", 40)
    start = max(n for n in range(index) if lines[n].strip().isdigit())
    return lines[: index + 1], start + 1


def _amc_header_only(lines):
    return [line for line in lines if line.startswith((":", "#"))], None


AMC_DAMAGE = {"unknown_joint": _amc_unknown_joint, "drop_value": _amc_drop_value,
              "abc": _amc_abc, "truncated": _amc_truncated, "header_only": _amc_header_only}


@pytest.mark.parametrize("damage", sorted(AMC_DAMAGE))
def test_damaged_amc(tmp_path, damage):
    lines, line = AMC_DAMAGE[damage](_lines(AMC))
    amc = tmp_path / "07_01.amc"
    amc.write_text("\n".join(lines) + "\n")
    with pytest.raises(MocapFormatError) as caught:
        load_motion(amc, asf=ASF)
    _check(caught.value, amc, line)


def test_undamaged_copies_still_load(tmp_path):
    # the corpus is built by editing text: make sure the untouched round trip reads back the same
    for name, source in BVH_SOURCES.items():
        copy = tmp_path / f"{name}.bvh"
        copy.write_text("\n".join(_lines(source)) + "\n")
        np.testing.assert_array_equal(load_motion(copy).positions, load_motion(source).positions)
    amc = tmp_path / "07_01.amc"
    amc.write_text("\n".join(_lines(AMC)) + "\n")
    assert load_motion(amc, asf=ASF).num_frames == 316
    with pytest.raises(FileNotFoundError, match="pass load_motion"):
        load_motion(amc)  # no 07.asf beside it


def _garbage(kind: str) -> bytes:
    if kind == "random bytes":
        return np.random.default_rng(7).integers(0, 256, 4000, dtype=np.uint8).tobytes()
    return b"Dear diary,\nthis is a letter, not motion capture.\n"


def _one_clean_line(error: Exception, path: Path) -> str:
    message = str(error)
    assert "\n" not in message and str(path) in message
    # nothing of the file's bytes comes back: printable ASCII only (the paths here are ASCII)
    assert message.isascii() and message.isprintable(), repr(message)
    return message


@pytest.mark.parametrize("garbage", ["random bytes", "a letter"])
def test_garbage_files_get_one_line_naming_them(tmp_path, garbage):
    expected = {"random bytes": "holds binary data, not text", "a letter": "not"}[garbage]
    bvh, asf, amc = (tmp_path / f"garbage.{suffix}" for suffix in ("bvh", "asf", "amc"))
    for path in (bvh, asf, amc):
        path.write_bytes(_garbage(garbage))
    with pytest.raises(MocapFormatError) as caught:
        load_motion(bvh)
    message = _one_clean_line(caught.value, bvh)
    assert expected in message and "BVH" in message, message
    with pytest.raises(MocapFormatError) as caught:
        load_motion(AMC, asf=asf)  # a garbage skeleton
    message = _one_clean_line(caught.value, asf)
    assert expected in message and "ASF" in message, message
    with pytest.raises(MocapFormatError) as caught:
        load_motion(amc, asf=ASF)  # garbage motion for a good skeleton
    message = _one_clean_line(caught.value, amc)
    assert expected in message and "AMC" in message, message


def test_a_few_stray_bytes_in_a_comment_do_not_make_a_file_binary(tmp_path):
    lines = _lines(BVH_SOURCES["cmu"])
    path = tmp_path / "bom.bvh"
    path.write_bytes(b"\xef\xbb\xbf" + "\n".join(lines).encode() + b"\n")  # with a UTF-8 BOM
    np.testing.assert_array_equal(load_motion(path).positions,
                                  load_motion(BVH_SOURCES["cmu"]).positions)
    amc = tmp_path / "07_01.amc"
    amc.write_bytes(b"# recorded by caf\xe9 \x01\n" + AMC.read_bytes())  # Latin-1 and a control
    assert load_motion(amc, asf=ASF).num_frames == 316
