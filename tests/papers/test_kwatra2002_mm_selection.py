"""The reduced search on actor mm: its tie rule and the transition smoothing it varies."""

import numpy as np
import pytest

from jaxtrack.priors.postures import NUM_POSTURES, fit_posture_model, transition_counts
from papers.kwatra2002.mm_selection import beats, choose, with_pseudocount


def test_ties_keep_the_current_value_else_take_the_cheapest_tied_one():
    noise = np.array([30.0, -20.0, 10.0, -40.0, 20.0])  # shared by the keys of every value
    assert beats(900 + noise + [1, -1, 2, 0, -2], 1000 + noise)
    assert not beats(990 + np.array([60.0, -50.0, 40.0, -70.0, 30.0]), 1000 + noise)
    base = 1000 + noise
    # the current value that the best does not beat stays
    assert choose({0.5: base, 5.0: base - [50, -45, 40, -30, 20], 25.0: base + 200}, 0.5,
                  "pseudocount") == 0.5
    # a clear winner replaces it
    assert choose({0.5: base, 5.0: base - 100 + [1, -1, 2, 0, -2], 25.0: base + 200}, 0.5,
                  "pseudocount") == 5.0
    # current beaten: the cheaper of the values tied with the best, not the lowest
    assert choose({250: base - 95 + [30, -30, 20, -25, 5], 500: base,
                   1000: base - 100 + [1, -1, 2, 0, -2]}, 500, "particles") == 250
    assert choose({"dynamics": base, "posterior": base - 100 + [1, -1, 2, 0, -2]}, "dynamics",
                  "part_proposal") == "posterior"


def test_the_transition_smoothing_is_what_a_refit_with_that_pseudocount_gives():
    rng = np.random.default_rng(0)
    runs = [np.repeat([0, 2, 1], 6), np.repeat([2, 3, 2, 4], 5), np.repeat([0, 2, 4], 4),
            np.repeat([3, 2, 0], 5)]
    features = [rng.normal(size=(len(labels), 3)) + labels[:, None] for labels in runs]
    fitted = fit_posture_model(features, runs, pseudocount=0.5)
    description = {"pseudocount": 0.5, "sequences": len(runs),
                   "transition_counts": transition_counts(runs).tolist()}
    for pseudocount in (0.1, 25.0):
        refit = fit_posture_model(features, runs, pseudocount=pseudocount)
        changed = with_pseudocount(fitted, description, pseudocount)
        np.testing.assert_allclose(np.exp(changed.log_transition), np.exp(refit.log_transition),
                                   atol=1e-12)
        np.testing.assert_allclose(np.exp(changed.log_initial), np.exp(refit.log_initial),
                                   atol=1e-9)
        np.testing.assert_array_equal(changed.means, fitted.means)
    assert np.exp(with_pseudocount(fitted, description, 25.0).log_transition).min() > 0.05
    assert changed.log_transition.shape == (NUM_POSTURES, NUM_POSTURES)
    with pytest.raises(ValueError, match="pseudocount must be"):
        with_pseudocount(fitted, description, -1.0)


def test_bad_arguments_are_refused_in_one_line(tmp_path, capsys):
    from papers.kwatra2002.mm_selection import main

    assert main(["test", "--validation-file", str(tmp_path / "none.json"),
                 "--out", str(tmp_path / "test.json")]) == 2
    message = capsys.readouterr().err.strip()
    assert "none.json" in message and len(message.splitlines()) == 1
    (tmp_path / "unfinished.json").write_text('{"rows": []}')
    assert main(["test", "--validation-file", str(tmp_path / "unfinished.json"),
                 "--out", str(tmp_path / "test.json")]) == 2
    assert "run the validation stage to its end" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["validation", "--out", str(tmp_path / "out.txt")])
    assert "must end in .json" in capsys.readouterr().err
