"""The registry of defaults (``jaxtrack._defaults``): it matches the code, no default was chosen
on a test subject, and ``docs/defaults.md`` is the registry as rendered now."""

import dataclasses
from pathlib import Path

import pytest

from jaxtrack import _defaults
from jaxtrack._defaults import DEFAULTS, Default

PAGE = Path(__file__).resolve().parents[1] / "docs" / "defaults.md"


def test_every_recorded_value_is_the_codes():
    assert _defaults.drift() == []


def test_no_default_was_chosen_on_a_test_subject():
    assert _defaults.provenance_problems() == []
    assert {entry.split for entry in DEFAULTS} <= set(_defaults.PROVENANCES)


@pytest.mark.parametrize(("change", "refusal"), [
    (dict(split="test"), "chosen on a test subject"),
    (dict(split="held-out take"), "is not one of"),
    (dict(command="python -m benchmarks.tracking --split test --methods latent"),
     "runs on the test split"),
    (dict(command="python -m benchmarks.tracking --split=test"), "runs on the test split"),
    (dict(command="jaxtrack evaluate --test cmu_1006_wave_hello_2 --seed 0"),
     "names the test clip"),
    (dict(command="python -m benchmarks.gplvm --held-out cmu_1006"), "names the test clip"),
    (dict(command="python -m benchmarks.mixed_state --clips cmu_posture_bvh/139_16"),
     "names the test clip"),
    (dict(command="python -m benchmarks.tracking --clips 131_01"), "names the test clip"),
    (dict(date="27 November"), "is not YYYY-MM-DD"),
])
def test_a_test_split_or_test_clip_is_refused(change, refusal):
    good = Default("example", "jaxtrack.trackers.latent:DEFAULT_JUMP_PROBABILITY", 0.2,
                   "validation", "python -m benchmarks.tracking --split validation",
                   "2026-11-26")
    assert _defaults.provenance_problems([good]) == []
    problems = _defaults.provenance_problems([dataclasses.replace(good, **change)])
    assert len(problems) == 1 and refusal in problems[0]


def test_validation_clips_and_split_names_are_not_taken_for_test_clips():
    entry = Default("example", "jaxtrack.trackers.latent:DEFAULT_JUMP_PROBABILITY", 0.2,
                    "validation", "python -m benchmarks.tracking --split validation --clips "
                    "bandai/dataset-2_walk_normal_001 cmu_amc/02_01 --seeds 1006 --views 131",
                    "2026-11-26")
    assert _defaults.provenance_problems([entry]) == []


def test_a_value_the_code_does_not_have_is_reported():
    entry = DEFAULTS[0]
    assert _defaults.drift([dataclasses.replace(entry, value=entry.value + 1)])[0].startswith(
        f"{entry.name}: the registry says")
    # a bool is not an int, a list not a tuple
    flag = next(entry for entry in DEFAULTS if entry.value is True)
    assert _defaults.drift([dataclasses.replace(flag, value=1)])
    scales = next(entry for entry in DEFAULTS if isinstance(entry.value, tuple) and entry.value)
    assert _defaults.drift([dataclasses.replace(scales, value=list(scales.value))])
    for where in ("jaxtrack.trackers.latent:NO_SUCH_NAME",
                  "jaxtrack.trackers.latent:latent_tracker(no_such_argument)",
                  "jaxtrack.trackers.latent:latent_tracker(prior)",
                  "jaxtrack.trackers.latent:latent_tracker(engine).no_such_field",
                  "no colon"):
        assert len(_defaults.drift([dataclasses.replace(entry, where=where)])) == 1


def test_the_linear_combination_tracker_ships_the_validated_p_q_and_omega():
    """Validation chose P, Q, ω = 64 / 16 / 0.03 (papers/ong2002): the library ships them."""
    by_where = {entry.where.rsplit(":", 1)[-1]: entry for entry in DEFAULTS}
    for where, validated in (("linear_combination_tracker(fitness).contour_tolerance", 64.0),
                             ("linear_combination_tracker(fitness).hands_tolerance", 16.0),
                             ("linear_combination_tracker(step)", 0.03)):
        entry = by_where[where]
        assert entry.split == "validation" and entry.value == validated
        assert _defaults.code_value(entry.where) == validated


def test_the_page_is_the_registry_rendered(tmp_path):
    assert PAGE.read_text(encoding="utf-8") == _defaults.render_markdown() + "\n", (
        "docs/defaults.md is out of date: run python -m jaxtrack._defaults --markdown "
        "docs/defaults.md")
    assert _defaults.main(["--check", str(PAGE)]) == 0
    written = tmp_path / "defaults.md"
    assert _defaults.main(["--markdown", str(written)]) == 0
    assert written.read_text(encoding="utf-8") == PAGE.read_text(encoding="utf-8")
    assert _defaults.main(["--check", str(tmp_path / "missing.md")]) == 1
