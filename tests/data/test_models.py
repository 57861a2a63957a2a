"""The trained models bundled with jaxtrack (``jaxtrack.data.models``): present, small, readable
by their loaders, and described truthfully: trained on training subjects only, on data that may
go into the wheel, with the command that remakes them."""

import hashlib
import json

import numpy as np
import pytest

from jaxtrack.data import models
from jaxtrack.data.splits import split_of, subject_of

NOT_SHIPPABLE = ("CC BY-NC", "CC BY-SA", "LGPL")
MAX_TOTAL_BYTES = 4_000_000


@pytest.mark.parametrize("name", sorted(models.RECIPES))
def test_each_model_names_only_training_subjects_and_shippable_sources(name):
    description = models.describe(name)
    clips = description["clips"] + description["laid_down"]
    assert clips, description
    for clip in clips:
        assert split_of(clip) == "training", clip
        assert description["subjects"][subject_of(clip)] == "training", clip
        licence = description["licences"][clip]
        assert licence == models.source_licence(clip), clip
        assert licence in models.SHIPPABLE_LICENCES, (clip, licence)
    assert set(description["subjects"]) == {subject_of(clip) for clip in clips}
    assert all(licence in models.SHIPPABLE_LICENCES
               for licence in description["also_reads"].values())
    text = json.dumps(description)
    for licence in NOT_SHIPPABLE:
        assert licence not in text, licence
    for source in ("bandai", "deepmimic", "hdm05"):
        assert source not in text.lower(), source


@pytest.mark.parametrize("name", sorted(models.RECIPES))
def test_each_description_matches_its_file_and_its_recipe(name):
    description = models.describe(name)
    recipe = models.RECIPES[name]
    file = models.models_folder() / recipe.file_name
    assert description["file"] == file.name and description["bytes"] == file.stat().st_size
    assert description["sha256"] == hashlib.sha256(file.read_bytes()).hexdigest()
    assert description["command"] == recipe.command()
    assert description["clips"] == list(recipe.clips)
    assert description["laid_down"] == list(recipe.laid_down)
    assert description["date"][:4].isdigit()
    # what the training itself saved in the file: the same clips, so the description cannot
    # name other data than the model learnt from
    with np.load(file) as saved:
        trained = json.loads(str(saved["metadata"]))["description"]
    assert description["trained"] == trained
    if name == "latent":  # a GPLVM records its clips sorted, under its settings
        assert trained["settings"]["clips"] == sorted(recipe.clips)
    else:
        assert trained["clips"] == list(recipe.clips)
        assert trained.get("laid_down", []) == list(recipe.laid_down)


def test_the_models_are_small_and_load_with_their_loaders():
    from jaxtrack.experiments.linear_combination import TRAIN_CLIPS, load
    from jaxtrack.priors.postures import load_posture_model
    from jaxtrack.priors.train import load_prior

    files = [models.default_model(method) for method in models.METHODS]
    assert sum(file.stat().st_size for file in set(files)) < MAX_TOTAL_BYTES
    prior = load_prior(models.default_model("latent"))
    assert prior.training_states is not None  # the baselines learn their dynamics from them
    assert models.default_model("condensation") == models.default_model("mht") == \
        models.default_model("latent")
    trained = load(models.default_model("linear-combination"))
    assert trained.model.layout.num_skeleton == len(trained.description["skeleton"])
    assert list(models.RECIPES["linear_combination"].clips) == list(TRAIN_CLIPS)
    postures = load_posture_model(models.default_model("mixed-state"))
    assert all(count >= 2 for count in postures.description["label_counts"].values())


def test_an_unknown_method_and_a_missing_model_are_one_line_errors(monkeypatch, tmp_path):
    with pytest.raises(ValueError, match="no bundled model for 'pose'"):
        models.default_model("pose")
    monkeypatch.setattr(models, "models_folder", lambda: tmp_path)
    with pytest.raises(FileNotFoundError) as error:
        models.default_model("mixed-state")
    assert "\n" not in str(error.value)
    assert "jaxtrack train --method mixed-state" in str(error.value)


@pytest.mark.parametrize("clip, reason", [
    ("animateddrawings/history_c119d6b/cmu_1006_wave_hello_1", "test subject"),
    ("cmu_amc/02_01", "validation subject"),
    ("deepmimic_getup_bvh/crawl", "LGPL-3.0"),
    ("hdm05_cut/squat1Reps/HDM_bd_squat1Reps_001_120", "CC BY-SA 3.0"),
    ("bandai/dataset-2_walk_normal_001", "CC BY-NC 4.0"),
])
def test_rebuilding_refuses_held_out_subjects_and_unshippable_data(monkeypatch, tmp_path, clip,
                                                                  reason):
    bad = models.Recipe("bad", "latent", ("animateddrawings/fair1_wave_hello", clip))
    monkeypatch.setitem(models.RECIPES, "bad", bad)
    with pytest.raises(ValueError, match=reason):
        models.rebuild(["bad"], tmp_path)  # refused before any training
    assert list(tmp_path.iterdir()) == []
