"""Sequence files: round trip, damaged and foreign files, atomic writes."""

import json
import zipfile
from functools import cache

import numpy as np
import pytest

from jaxtrack.body.render import frontal_camera, render_motion
from jaxtrack.body.sequence import (
    FORMAT_VERSION,
    SequenceFormatError,
    load_sequence,
    save_sequence,
)
from jaxtrack.data import load_clip


@cache
def sequence():
    motion = load_clip("cmu_amc/07_01").resample(20.0).select(0, 6)
    return render_motion(motion, frontal_camera(motion, (96, 72)), background="clutter",
                         occluders=1, seed=5, progress=False)


def test_round_trip_keeps_arrays_and_metadata(tmp_path):
    original = sequence()
    written = save_sequence(tmp_path / "walk.npz", original)
    loaded = load_sequence(written)
    for name in ("images", "silhouettes", "markers_2d", "joints_3d", "visibility"):
        assert np.array_equal(getattr(loaded, name), getattr(original, name)), name
        assert getattr(loaded, name).dtype == getattr(original, name).dtype, name
    assert loaded.marker_names == original.marker_names
    assert (loaded.fps, loaded.source, loaded.seed) == (original.fps, original.source, 5)
    assert loaded.settings == json.loads(json.dumps(original.settings))
    assert loaded.camera.image_size == original.camera.image_size == (96, 72)
    for field in ("focal_length", "principal_point", "rotation", "translation", "distortion"):
        assert np.array_equal(np.asarray(getattr(loaded.camera, field)),
                              np.asarray(getattr(original.camera, field))), field
    with np.load(written) as contents:
        metadata = json.loads(str(contents["metadata"]))
    assert metadata["format"] == "jaxtrack.sequence"
    assert metadata["format_version"] == FORMAT_VERSION
    assert metadata["image_size"] == [96, 72]


def test_missing_truncated_and_foreign_files_raise_naming_the_file(tmp_path):
    good = save_sequence(tmp_path / "good.npz", sequence())
    with pytest.raises(SequenceFormatError, match="absent.npz"):
        load_sequence(tmp_path / "absent.npz")
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(SequenceFormatError, match="truncated.npz"):
        load_sequence(truncated)
    text = tmp_path / "text.npz"
    text.write_text("not an archive")
    with pytest.raises(SequenceFormatError, match="text.npz"):
        load_sequence(text)


def rewrite(source, target, change):
    """Copy an .npz, letting `change(arrays, metadata)` edit its contents."""
    with np.load(source) as contents:
        arrays = {name: contents[name] for name in contents.files}
    metadata = json.loads(str(arrays["metadata"]))
    change(arrays, metadata)
    arrays["metadata"] = np.array(json.dumps(metadata))
    np.savez(target, **arrays)
    return target


def test_wrong_format_version_or_missing_arrays_raise(tmp_path):
    good = save_sequence(tmp_path / "good.npz", sequence())
    newer = rewrite(good, tmp_path / "newer.npz",
                    lambda arrays, metadata: metadata.update(format_version=FORMAT_VERSION + 1))
    with pytest.raises(SequenceFormatError, match=r"newer.npz.*version 2"):
        load_sequence(newer)
    other = rewrite(good, tmp_path / "other.npz",
                    lambda arrays, metadata: metadata.update(format="jaxtrack.gplvm"))
    with pytest.raises(SequenceFormatError, match=r"other.npz.*jaxtrack.gplvm"):
        load_sequence(other)
    partial = rewrite(good, tmp_path / "partial.npz",
                      lambda arrays, metadata: arrays.pop("visibility"))
    with pytest.raises(SequenceFormatError, match=r"partial.npz.*visibility"):
        load_sequence(partial)
    with zipfile.ZipFile(tmp_path / "plain.npz", "w") as archive:
        archive.writestr("images.npy", b"")
    with pytest.raises(SequenceFormatError, match="plain.npz"):
        load_sequence(tmp_path / "plain.npz")


def test_failed_write_leaves_no_partial_file_and_keeps_the_old_one(tmp_path, monkeypatch):
    target = save_sequence(tmp_path / "seq.npz", sequence())
    before = target.read_bytes()

    def fail_midway(file, **arrays):
        file.write(b"PK\x03\x04 half an archive")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", fail_midway)
    with pytest.raises(OSError, match="disk full"):
        save_sequence(target, sequence())
    with pytest.raises(OSError, match="disk full"):
        save_sequence(tmp_path / "new.npz", sequence())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["seq.npz"]
    assert target.read_bytes() == before
