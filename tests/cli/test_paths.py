"""The commands take a user's own motion files (a BVH path, an ASF/AMC pair) wherever they take
a catalogue clip, and refuse bad arguments with one line and exit status 2 before doing or
writing anything."""

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

import jaxtrack.priors.train
from jaxtrack.cli import main
from jaxtrack.data import bundled_folder, load_clip, shared_folder
from jaxtrack.priors.train import load_prior, train_prior

BUNDLED = bundled_folder()
WAVE_BVH = BUNDLED / "animateddrawings_bvh" / "fair1_wave_hello.bvh"
HELD_OUT_BVH = (BUNDLED / "animateddrawings_bvh" / "history_c119d6b"
                / "cmu_1006_wave_hello_1.bvh")
TINY = dict(views=1, fps=10.0, active_size=8, iterations=1, active_steps=5, progress=False)


def _short_bvh(source: Path, target: Path, frames: int) -> Path:
    """The first ``frames`` frames of a real BVH file, under another name."""
    lines = source.read_text().splitlines()
    motion = lines.index("MOTION")
    header = lines[:motion + 1] + [f"Frames: {frames}", lines[motion + 2]]
    target.write_text("\n".join(header + lines[motion + 3:motion + 3 + frames]) + "\n")
    return target


def _short_amc(source: Path, target: Path, frames: int) -> Path:
    """The first ``frames`` frames of a real AMC file (a frame starts with its number)."""
    kept, count = [], 0
    for line in source.read_text().splitlines():
        if line.strip().isdigit():
            count += 1
            if count > frames:
                break
        kept.append(line)
    target.write_text("\n".join(kept) + "\n")
    return target


def _asf_amc_folder() -> Path:
    shared = shared_folder()
    if shared is not None and (shared / "cmu_asfamc_walk" / "07.asf").is_file():
        return shared / "cmu_asfamc_walk"
    return BUNDLED / "cmu_asfamc_walk"


@pytest.fixture
def own_files(tmp_path):
    """A user's files outside the package: a BVH under another name, an AMC with its ASF beside
    it under other names (found as the only .asf of the folder), and an AMC whose ASF is in
    another folder."""
    folder = _asf_amc_folder()
    walk = tmp_path / "walk"
    walk.mkdir()
    shutil.copy(folder / "07.asf", walk / "subject.asf")
    _short_amc(folder / "07_01.amc", walk / "my_walk.amc", 120)
    lonely = tmp_path / "lonely"
    lonely.mkdir()
    _short_amc(folder / "07_01.amc", lonely / "07_01.amc", 120)
    # every training below sees 20 poses, so that the fit compiles once for all of them
    return {
        "bvh": _short_bvh(WAVE_BVH, tmp_path / "my wave.bvh", 240),
        "short_bvh": _short_bvh(WAVE_BVH, tmp_path / "short.bvh", 80),
        "held_out_bvh": _short_bvh(HELD_OUT_BVH, tmp_path / "other_wave.bvh", 60),
        "amc": walk / "my_walk.amc", "asf": walk / "subject.asf",
        "lonely_amc": lonely / "07_01.amc",
    }


def test_clips_load_by_path_exactly_as_by_name(tmp_path, own_files):
    copy = tmp_path / "renamed.bvh"
    shutil.copy(WAVE_BVH, copy)
    by_name = load_clip("animateddrawings/fair1_wave_hello")
    np.testing.assert_array_equal(load_clip(copy).positions, by_name.positions)
    assert load_clip(str(copy)).joint_names == by_name.joint_names
    amc = load_clip(own_files["amc"])  # its ASF: the only one in its folder
    explicit = load_clip(own_files["lonely_amc"], asf=own_files["asf"])
    np.testing.assert_array_equal(amc.positions, explicit.positions)
    assert amc.rig == "cmu_asf" and amc.num_frames == 120


def test_train_prior_keys_a_file_by_its_contents(tmp_path, own_files):
    cache = tmp_path / "prior.npz"
    bvh = str(own_files["bvh"])
    trained = train_prior([bvh], cache=cache, **TINY)
    assert trained.seconds > 0 and set(trained.labels) == {bvh}
    (identity,) = trained.description["settings"]["clips"]
    assert identity.startswith("file:my wave.bvh sha256:")
    # the same bytes under the same name elsewhere: served from the cache
    moved = tmp_path / "elsewhere"
    moved.mkdir()
    shutil.copy(bvh, moved / "my wave.bvh")
    assert train_prior([str(moved / "my wave.bvh")], cache=cache, **TINY).seconds == 0.0
    # an edited file is not (one frame replaced by the next)
    lines = own_files["bvh"].read_text().splitlines()
    first = lines.index("MOTION") + 3
    lines[first] = lines[first + 1]
    own_files["bvh"].write_text("\n".join(lines) + "\n")
    assert train_prior([bvh], cache=cache, **TINY).seconds > 0


def test_train_command_trains_on_a_bvh_path(tmp_path, own_files, capsys):
    out = tmp_path / "models" / "wave.npz"  # the folder is created
    arguments = ["train", "--clips", str(own_files["short_bvh"]), "--views", "1", "--active",
                 "8", "--iterations", "1", "--out", str(out)]
    assert main(arguments) == 0, capsys.readouterr().err
    prior = load_prior(out)
    assert set(prior.labels) == {str(own_files["short_bvh"])}
    assert prior.description["num_poses"] == 20  # 80 frames at 119.9 Hz, taken at 30 fps


@pytest.mark.slow  # trains a GPLVM per body part
def test_train_command_trains_one_gplvm_per_part_with_parts(tmp_path, own_files, capsys):
    from jaxtrack.priors.gplvm import PartsGPLVM

    out = tmp_path / "parts.npz"
    arguments = ["train", "--clips", str(own_files["short_bvh"]), "--views", "1", "--active",
                 "8", "--iterations", "1", "--parts", "--mirror", "--back-constraint", "0.5",
                 "--out", str(out)]
    assert main(arguments) == 0, capsys.readouterr().err
    assert "3 GPLVMs, one per part," in capsys.readouterr().out
    prior = load_prior(out)
    assert isinstance(prior.model, PartsGPLVM)
    assert prior.description["num_poses"] == 2 * 20  # the clip and its mirror image
    assert prior.description["settings"]["back_constraint"] == 0.5
    bad = ["train", "--clips", str(own_files["short_bvh"]), "--back-constraint", "-1",
           "--out", str(tmp_path / "bad.npz")]
    assert main(bad) == 2
    error = capsys.readouterr().err.strip()
    assert error == ("jaxtrack train: error: --back-constraint must be a positive width, "
                     "got -1 (see jaxtrack train --help)"), error
    assert not (tmp_path / "bad.npz").exists()


def test_train_command_reads_an_asf_amc_pair_with_asf(tmp_path, own_files, monkeypatch,
                                                      capsys):
    calls = []

    def small_training(clips, **options):
        calls.append((clips, options))
        return train_prior(clips, **{**options, **TINY})

    monkeypatch.setattr(jaxtrack.priors.train, "train_prior", small_training)
    out = tmp_path / "walk.npz"
    arguments = ["train", "--clips", str(own_files["lonely_amc"]), str(own_files["amc"]),
                 "--asf", str(own_files["asf"]), "--out", str(out)]
    assert main(arguments) == 0, capsys.readouterr().err
    (clips, options), = calls
    assert clips == [str(own_files["lonely_amc"]), str(own_files["amc"])]
    assert options["asf"] == own_files["asf"]
    assert load_prior(out).description["num_poses"] == 2 * 10  # 120 frames at 120 Hz, 10 fps


@pytest.mark.slow  # trains, renders and tracks
def test_evaluate_takes_a_bvh_and_an_asf_amc_pair(tmp_path, own_files, monkeypatch, capsys):
    trained = []

    def small_training(clips, **options):
        trained.append(clips)
        return train_prior(clips, **{**options, **TINY})

    monkeypatch.setattr(jaxtrack.priors.train, "train_prior", small_training)
    out = tmp_path / "results" / "deeper" / "walk.json"  # folders created, as --plots does
    arguments = ["evaluate", "--method", "condensation", "--train", str(own_files["bvh"]),
                 str(own_files["amc"]), "--test", str(own_files["held_out_bvh"]),
                 "--particles", "16", "--views", "1", "--backgrounds", "plain",
                 "--max-frames", "4", "--seed", "3", "--json", str(out)]
    assert main(arguments) == 0, capsys.readouterr().err
    assert trained == [[str(own_files["bvh"]), str(own_files["amc"])]]
    record = json.loads(out.read_text())
    assert record["train"] == [str(own_files["bvh"]), str(own_files["amc"])]
    (sequence,) = record["sequences"]
    assert sequence["sequence"] == "other_wave_view0_plain"
    assert sequence["clip"] == str(own_files["held_out_bvh"])
    assert np.isfinite(record["overall"]["mean_error_px"])
    assert (out.parent / "gplvm_cache.npz").is_file()


def _fail_if_trained(*args, **kwargs):
    raise AssertionError("the command trained before refusing its arguments")


EVALUATE = ["evaluate", "--method", "latent", "--train", "animateddrawings/fair1_wave_hello",
            "--test", "cmu_amc/07_01"]


@pytest.mark.parametrize("arguments, message", [
    (["train", "--clips", "{lonely_amc}", "--out", "{tmp}/m.npz"],
     "--clips {lonely_amc}: no ASF skeleton beside it (looked for 07.asf, 07_01.asf and for a "
     "single .asf in its folder); give the skeleton with --asf FILE.asf"),
    (EVALUATE[:-1] + ["{lonely_amc}", "--json", "{tmp}/o.json"],
     "--test {lonely_amc}: no ASF skeleton beside it"),
    (["train", "--clips", "{tmp}/missing.bvh", "--out", "{tmp}/m.npz"],
     "--clips {tmp}/missing.bvh: no motion file at {tmp}/missing.bvh"),
    (["train", "--clips", "{bvh}", "--asf", "{asf}", "--out", "{tmp}/m.npz"],
     "--asf {asf}: no .amc file is given by path for it to apply to"),
    (["train", "--clips", "{amc}", "--asf", "{tmp}/none.asf", "--out", "{tmp}/m.npz"],
     "--asf {tmp}/none.asf: no such file"),
    (["train", "--clips", "{asf}", "--out", "{tmp}/m.npz"],
     "--clips {asf}: {asf}: not a motion file"),
    (["train", "--clips", "{bvh}", "--seed", "-1", "--out", "{tmp}/m.npz"],
     "--seed must be from 0 to 4294967295 (a 32-bit seed: jax.random.key keeps only the low 32 "
     "bits), got -1"),
    (EVALUATE + ["--seed", "-1", "--json", "{tmp}/o.json"],
     "--seed must be from 0 to 4294967295 (a 32-bit seed: jax.random.key keeps only the low 32 "
     "bits), got -1"),
    (EVALUATE + ["--max-frames", "0", "--json", "{tmp}/o.json"],
     "--max-frames must be at least 2 (frame 0 starts the tracker), got 0"),
    (EVALUATE[:-1] + ["{bvh}", "--train", "./{bvh}", "--json", "{tmp}/o.json"],
     "--test clips must be held out, but {bvh} is also in --train"),
    (EVALUATE + ["--json", "{bvh}/o.json"], "cannot create folder {bvh}, {bvh} is a file"),
])
def test_bad_input_is_one_line_before_any_work(tmp_path, own_files, monkeypatch, capsys,
                                               arguments, message):
    monkeypatch.setattr(jaxtrack.priors.train, "train_prior", _fail_if_trained)
    monkeypatch.chdir(tmp_path)
    names = {name: str(file) for name, file in own_files.items()} | {"tmp": str(tmp_path)}
    names["bvh"] = Path(names["bvh"]).name  # relative to the working folder
    before = sorted(tmp_path.rglob("*"))
    code = main([argument.format(**names) for argument in arguments])
    error = capsys.readouterr().err
    assert code == 2, error
    assert message.format(**names) in error and error.count("\n") == 1
    assert sorted(tmp_path.rglob("*")) == before  # nothing written, not even a cache


def _damaged(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"PK\x03\x04 truncated")
    return path


def test_a_damaged_model_file_is_named(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(jaxtrack.priors.train, "train_prior", _fail_if_trained)
    cache = _damaged(tmp_path / "out" / "gplvm_cache.npz")
    code = main([*EVALUATE, "--json", str(tmp_path / "out" / "latent.json")])
    error = capsys.readouterr().err
    assert code == 2 and error.count("\n") == 1
    assert (f"the GPLVM cached beside --json: {cache} is damaged or not a trained prior "
            "(damaged or truncated GPLVM file") in error
    assert "delete it (it is retrained and rewritten) or write --json elsewhere" in error
    model = _damaged(tmp_path / "model.npz")
    code = main(["train", "--clips", "cmu_amc/07_01", "--out", str(model)])
    error = capsys.readouterr().err
    assert code == 2 and error.count("\n") == 1
    assert f"--out {model} is damaged or not a trained prior" in error
    assert "delete it or choose another --out to train a new one" in error
    # a readable npz that is not a GPLVM (a rendered sequence, say) is refused the same way
    np.savez(model, frames=np.zeros(3))
    assert main(["train", "--clips", "cmu_amc/07_01", "--out", str(model)]) == 2
    assert "not a jaxtrack GPLVM file" in capsys.readouterr().err
    assert sorted(path.name for path in tmp_path.rglob("*")) == [
        "gplvm_cache.npz", "model.npz", "out"]


def test_too_many_particles_are_refused_with_the_memory_they_need(tmp_path, monkeypatch,
                                                                  capsys):
    from jaxtrack.cli import _common
    from jaxtrack.cli.evaluate import tracking_bytes

    monkeypatch.setattr(jaxtrack.priors.train, "train_prior", _fail_if_trained)
    available = _common.available_memory()
    assert available is not None and 0 < available
    code = main([*EVALUATE, "--particles", "10000000", "--json", str(tmp_path / "o.json")])
    error = capsys.readouterr().err
    assert code == 2 and error.count("\n") == 1
    found = re.search(r"--particles: tracking with 10000000 particles needs about ([\d.]+) GB "
                      r"of memory but this machine has ([\d.]+) GB available; use fewer", error)
    assert found, error
    needed = float(found.group(1)) * 1e9
    assert needed == pytest.approx(tracking_bytes("latent", 10**7), rel=1e-3)
    assert float(found.group(2)) * 1e9 == pytest.approx(available, rel=0.2)
    assert list(tmp_path.iterdir()) == []
    # the estimate grows in proportion to the particles, and the default run fits
    step = tracking_bytes("latent", 2000) - tracking_bytes("latent", 1000)
    assert step > 0 and tracking_bytes("latent", 3000) - tracking_bytes("latent", 2000) == step
    assert tracking_bytes("latent", 200) < available


def test_garbage_motion_files_are_one_line_naming_the_file(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(jaxtrack.priors.train, "train_prior", _fail_if_trained)
    garbage = tmp_path / "garbage.bvh"
    garbage.write_bytes(np.random.default_rng(3).integers(0, 256, 3000, np.uint8).tobytes())
    letter = tmp_path / "letter.amc"
    letter.write_text("Dear diary,\nnot motion capture.\n")
    for arguments, message in (
            (["--clips", str(garbage)], f"{garbage}: not a BVH file: it holds binary data"),
            (["--clips", str(letter), "--asf", str(bundled_folder() / "cmu_asfamc_walk" /
                                                   "07.asf")],
             f"{letter}, line 1: 'Dear' before the first frame number (not an AMC file?)")):
        code = main(["train", *arguments, "--out", str(tmp_path / "m.npz")])
        error = capsys.readouterr().err
        assert code == 2 and message in error and error.count("\n") == 1, error
        assert error.isascii() and error.strip().isprintable(), repr(error)
