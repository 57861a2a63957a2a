"""The linear-combination tracker ships eq. 9's P, Q and the step ω chosen on validation
(``python -m papers.ong2002.evaluation``), and every layer that builds one uses the same."""

import inspect

from jaxtrack import _defaults
from jaxtrack.experiments import linear_combination as lc
from jaxtrack.trackers.linear_combination import linear_combination_tracker, nearest_neighbour

VALIDATED = {"contour_tolerance": 64.0, "hands_tolerance": 16.0, "step": 0.03}


def _default(function, name):
    return inspect.signature(function).parameters[name].default


def test_the_tracker_and_the_experiments_ship_the_validated_p_q_and_step():
    fitness = _default(linear_combination_tracker, "fitness")
    assert float(fitness.contour_tolerance) == VALIDATED["contour_tolerance"]
    assert float(fitness.hands_tolerance) == VALIDATED["hands_tolerance"]
    assert _default(linear_combination_tracker, "step") == VALIDATED["step"]
    assert _default(nearest_neighbour, "fitness") == fitness
    assert lc.DEFAULT_FITNESS == fitness and lc.DEFAULT_STEP == VALIDATED["step"]
    for function in (lc.run_method, lc.evaluate, lc.multi_view, lc.track):
        assert _default(function, "fitness") is lc.DEFAULT_FITNESS, function.__name__
        assert _default(function, "step") == lc.DEFAULT_STEP, function.__name__
    assert _default(lc.run_method, "brownian_step") == lc.DEFAULT_STEP


def test_the_registry_records_them_as_chosen_on_validation_by_the_paper_folder_command():
    entries = {entry.name.split(" ")[0]: entry for entry in _defaults.DEFAULTS
               if entry.group == "Linear combinations"}
    for symbol, value in (("P", 64.0), ("Q", 16.0), ("ω", 0.03)):
        entry = entries[symbol]
        assert entry.value == value and entry.split == "validation"
        assert entry.command.startswith("python -m papers.ong2002.evaluation")
    assert not _defaults.drift([entries[symbol] for symbol in ("P", "Q", "ω")])
    assert entries["view"].command == entries["skeleton"].command == (
        "python -m papers.ong2002.view_selection")
