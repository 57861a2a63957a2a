"""The data catalogue: bundled files are complete, licensed and unchanged; names resolve in the
documented order; a missing clip says where it was looked for."""

import hashlib
from pathlib import Path

import pytest

import jaxtrack
from jaxtrack.data import (
    COLLECTIONS,
    bundled_folder,
    clip_files,
    data_folders,
    list_clips,
    load_clip,
    path,
    shared_folder,
)

PACKAGE = Path(jaxtrack.__file__).parent
BUNDLED_CLIPS = [
    "animateddrawings/fair1_wave_hello",
    "animateddrawings/history_c119d6b/8yr_old_wave_hello",
    "animateddrawings/history_c119d6b/cmu_1006_wave_hello_1",
    "animateddrawings/history_c119d6b/cmu_1006_wave_hello_2",
    "animateddrawings/history_c119d6b/cmu_new_walk_point",
    "animateddrawings/history_c119d6b/cmu_new_walk_raise_the_roof",
    "cmu_amc/07_01",
    "cmu_amc/07_02",
    "cmu_bvh/131_01",
    "cmu_posture_bvh/64_26",
    "cmu_posture_bvh/75_19",
]


def test_bundled_clips_are_the_documented_ones():
    assert list(clip_files(bundled_folder())) == BUNDLED_CLIPS
    assert set(BUNDLED_CLIPS) <= set(list_clips())
    assert (bundled_folder() / "pose2sim_demo_singleperson" / "Calib.qca.txt").is_file()


@pytest.mark.parametrize("folder", sorted(COLLECTIONS.values()))
def test_bundled_folders_keep_source_licence_and_checksums(folder):
    root = bundled_folder() / folder
    if folder == "bandai_namco_gestures":
        assert not root.exists()  # CC BY-NC: must never reach the wheel
        root = Path(__file__).parent / folder
    assert (root / "SOURCE.txt").is_file()
    assert list(root.glob("LICENSE*")), f"{root} has no licence text"
    if folder.startswith("cmu_"):
        assert "NSF EIA-0196217" in (root / "LICENSE.CMU.txt").read_text()
    sums = (root / "SHA256SUMS").read_text().split("\n")
    checked = 0
    for line in filter(None, sums):
        digest, name = line.split(maxsplit=1)
        assert hashlib.sha256((root / name).read_bytes()).hexdigest() == digest, name
        checked += 1
    data = [p for p in root.rglob("*") if p.suffix in (".bvh", ".amc", ".asf", ".txt")
            and p.name not in ("SOURCE.txt", "LICENSE.CMU.txt")]
    assert checked == len(data)  # every data file is the verified upstream copy


def test_no_non_commercial_file_inside_the_package():
    for file in PACKAGE.rglob("*"):
        assert "dataset-2_" not in file.name and "bandai" not in file.name.lower()
        if file.is_file() and file.name.startswith("LICENSE"):
            assert "NonCommercial" not in file.read_text(errors="replace"), file


def test_clip_names_resolve_to_bundled_files_first():
    file = path("animateddrawings/fair1_wave_hello")
    assert file == bundled_folder() / "animateddrawings_bvh" / "fair1_wave_hello.bvh"
    assert path("animateddrawings_bvh/fair1_wave_hello.bvh") == file
    motion = load_clip("cmu_amc/07_02")
    assert (motion.rig, motion.num_joints, motion.num_frames) == ("cmu_asf", 31, 329)
    assert path("pose2sim/Calib.qca.txt").name == "Calib.qca.txt"
    bandai = load_clip("bandai/dataset-2_wave-right-hand_normal_001")  # tests/data or shared
    assert (bandai.rig, bandai.num_joints, bandai.fps) == ("bandai", 22, 30.0)


def test_environment_folder_is_searched(tmp_path, monkeypatch):
    folder = tmp_path / "cmu_bvh_131"
    folder.mkdir()
    text = (bundled_folder() / "cmu_bvh_131" / "131_01.bvh").read_text().splitlines()
    motion_line = text.index("MOTION")
    (folder / "short.bvh").write_text(
        "\n".join(text[:motion_line + 1] + ["Frames: 3"] + text[motion_line + 2:motion_line + 6]))
    monkeypatch.setenv("JAXTRACK_DATA", str(tmp_path))
    assert ("$JAXTRACK_DATA", tmp_path) in data_folders()
    assert load_clip("cmu_bvh/short").num_frames == 3
    assert "cmu_bvh/short" in list_clips()
    assert shared_folder() == tmp_path


def test_missing_clip_lists_where_it_looked(monkeypatch, tmp_path):
    monkeypatch.setenv("JAXTRACK_DATA", str(tmp_path))
    with pytest.raises(FileNotFoundError) as caught:
        path("animateddrawings/no_such_clip")
    message = str(caught.value)
    assert "no_such_clip" in message and str(bundled_folder()) in message
    assert "$JAXTRACK_DATA" in message and str(tmp_path) in message
    with pytest.raises(ValueError, match="collection/clip"):
        path("fair1_wave_hello")


def test_no_shared_searches_only_the_bundled_files_and_jaxtrack_data(tmp_path, monkeypatch):
    monkeypatch.delenv("JAXTRACK_DATA", raising=False)
    monkeypatch.chdir(tmp_path)
    searched = [folder for _, folder in data_folders()]
    assert (PACKAGE.parent / "tests" / "data") in searched  # a source checkout: tests/data
    monkeypatch.setenv("JAXTRACK_NO_SHARED", "1")
    assert data_folders() == [("files bundled with jaxtrack", bundled_folder())]
    assert shared_folder() is None and list_clips() == BUNDLED_CLIPS
    with pytest.raises(FileNotFoundError, match="bandai"):
        path("bandai/dataset-2_wave-right-hand_normal_001")
    monkeypatch.setenv("JAXTRACK_DATA", str(tmp_path))
    assert [folder for _, folder in data_folders()] == [bundled_folder(), tmp_path]
    monkeypatch.setenv("JAXTRACK_NO_SHARED", "0")
    assert (PACKAGE.parent / "tests" / "data") in [folder for _, folder in data_folders()]
