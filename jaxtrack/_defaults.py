"""Where every user-facing default comes from: one registry, checked against the code.

Each :class:`Default` names a value a user meets without asking for it (a particle count, a
noise scale, a likelihood weight, a rule), where it lives in the code, and how it was chosen:
the split of :mod:`jaxtrack.data.splits` it was chosen on (``"training"``, ``"validation"``),
``"paper"`` for a value taken from the paper a tracker implements, or ``"none recorded"`` where
no record says; the command that chose it and the date, where recorded. A default is never
chosen on ``"test"``: :func:`provenance_problems` refuses that split and any command that names
a test clip or ``--split test``.

``where`` is ``"module:NAME"`` (a module attribute), ``"module:function(argument)"`` (an
argument's default, read with :func:`inspect.signature`; a class gives its ``__init__``'s), and
either may go on with ``.field`` (an attribute of that value, e.g. an ``Engine``'s
``num_particles``). :func:`code_value` reads it from the live code and :func:`drift` lists the
entries whose recorded value the code no longer has.

``python -m jaxtrack._defaults --markdown docs/defaults.md`` writes the registry as the
documentation page; ``--check`` exits 1 (naming each entry) if the registry and the code, or the
page and the registry, disagree.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import inspect
import os
import re
import sys
import tempfile
from collections.abc import Iterable, Sequence
from typing import Any

__all__ = ["DEFAULTS", "Default", "PROVENANCES", "code_value", "drift", "provenance_problems",
           "render_markdown", "test_clip_names"]

PROVENANCES = ("training", "validation", "paper", "none recorded")
"""What a default's ``split`` may say. ``"test"`` is not among them: a default chosen on a test
subject would make every test score a validation score."""

NONE = "none recorded"


@dataclasses.dataclass(frozen=True)
class Default:
    """One default and its provenance.

    Attributes:
        name: what a user calls it (an option name, a symbol).
        where: the code that holds it (module docstring: ``module:NAME``,
            ``module:function(argument)``, optionally ``.field``).
        value: the value the code has.
        split: one of :data:`PROVENANCES`.
        command: the command whose run chose it; ``"none recorded"`` where none is.
        date: the day of that run (YYYY-MM-DD); ``"none recorded"`` where none is.
        note: what else a reader must know (the record it comes from, a better value found).
        group: the section of the documentation page.
        first_on_test: first tuned on a clip of a test subject and only kept on validation by
            the keep-unless-beaten rule (docs/trackers.md): to be chosen again on validation.
    """

    name: str
    where: str
    value: Any
    split: str
    command: str = NONE
    date: str = NONE
    note: str = ""
    group: str = ""
    first_on_test: bool = False


# -- the records these entries quote ------------------------------------------------------------

_KEPT_2026_11_26 = ("python -m papers.tian2005.tracking --split validation --methods latent "
                    "--estimates refined --likelihoods limbs+edges --seeds 2 --set NAME=VALUE "
                    "--out benchmarks/results/tracking/defaults/NAME=VALUE")


def _kept(name: str) -> str:
    """The 2026-11-26 run on validation that compared ``name`` with its neighbours."""
    return _KEPT_2026_11_26.replace("NAME", name)


_KEPT_NOTE = ("Compared one at a time with its neighbours on the validation subject (12 runs "
              "each) and kept by the rule fixed before the runs: change only if another value "
              "lowers the mean error by more than the default's 95 % half-width or loses fewer "
              "runs (docs/trackers.md, \"Why the defaults are what they are\").")
_SWEEP = ("python -m papers.tian2005.tracking --split validation --clips wide --views 1 "
          "--seeds 1 --max-frames 100 --likelihoods limbs+edges --methods {method} --estimates "
          "{estimate} {sets} --out benchmarks/results/tracking/defaults/{method}/{tag}")
_SWEEP_NOTE = ("Chosen by `python -m papers.tian2005.defaults_sweep` (grid and rule fixed before "
               "the runs): the value of lowest mean error, in % of the torso over 9 runs (the "
               "frontal view of each of the validation subject's nine gesture clips, 100 frames, "
               "seed 0), another value tying with it when above by less than the 95 % half-width "
               "of the paired differences, ties going to the {end} (docs/trackers.md, \"Why the "
               "defaults are what they are\"). ")


def _swept(method: str, **settings: str) -> str:
    """The command of the 2026-11-29 sweep on validation (``VALUE``: the value compared)."""
    estimate = "refined" if method == "latent" else "own"
    return _SWEEP.format(method=method, estimate=estimate,
                         sets=" ".join(f"--set {name}={value}" for name, value in settings.items()),
                         tag=",".join(f"{name}={value}" for name, value in settings.items()))


_MIXED_STATE = "python -m papers.kwatra2002.mixed_state_evaluation"
_MIXED_STATE_NOTE = ("Smoothed MSE over all parts on the validation clips (docs/mixed-state.md; "
                     "the docstring of the code quotes the numbers).")
_MM = "python -m papers.kwatra2002.mm_selection validation"
_MM_NOTE = ("Kept by the coordinate search on HDM05 actor mm's validation takes (both side "
            "views, 150 frames, 500 particles; smoothed MSE over all parts, mean of filter keys "
            "1-5; a value replaces the library's only if it is lower beyond twice the standard "
            "error of the paired differences): the library's {library} px², {others}; every "
            "difference within Monte Carlo error (papers/kwatra2002/README.md).")
_ARM_NOTE = ("On the Bandai validation splits, prior trained on other Bandai takes "
             "(docs/trackers.md, \"Why the defaults are what they are\"; "
             "the measurement log, git show 561ec54:docs/measurement-log.md); the record "
             "gives no command line, the date is that of the commit that set the value.")
_LC_VALIDATED = "python -m papers.ong2002.evaluation --frames 60 --multi-view"
_LC_NOTE = ("Chosen on the validation subject's wave (Bandai-Namco, four Pose2Sim views, 60 "
            "frames) over {grid} by the best particle's 3-D error, for both filters; the same "
            "choice on 2026-11-27 (docs/linear-combination.md). Shipped since 2026-11-29 (before: "
            "{shipped}, of no recorded origin). The experiments layer's DEFAULT_FITNESS and "
            "DEFAULT_STEP hold the same values.")
_VIEWS = ("python -m papers.ong2002.view_selection")
_GPLVM = ("python -m benchmarks.gplvm --validation")

_LATENT = "jaxtrack.trackers.latent:latent_tracker"
_EPS_COMMAND = _swept("latent", jump_probability="VALUE", refine_steps="10", edge_weight="1",
                      edge_tolerance="45")
_STEPS_COMMAND = _swept("latent", jump_probability="0.05", refine_steps="VALUE", edge_weight="1",
                        edge_tolerance="45")
_MHT = "jaxtrack.trackers.mht:mht_tracker"
_LC = "jaxtrack.trackers.linear_combination:linear_combination_tracker"
_LCV = "jaxtrack.trackers.linear_combination_views:linear_combination_views_tracker"
_FITNESS = "jaxtrack.likelihoods.contour_normals:FitnessSettings"
_MIXED = "jaxtrack.trackers.mixed_state:MixedStateModel"
_EDGES = "jaxtrack.likelihoods.edges"

DEFAULTS: tuple[Default, ...] = (
    # ---- particle counts ----------------------------------------------------------------------
    Default("latent tracker particles", f"{_LATENT}(engine).num_particles", 200, NONE,
            note="The protocol's count (jaxtrack.experiments.protocol.DEFAULT_PARTICLES). "
            "`python -m papers.tian2005.particle_sweep` measures other counts on the "
            "test take only (papers/tian2005/history.md); no choice on validation is recorded.",
            group="Particle counts"),
    Default("CONDENSATION particles", "jaxtrack.trackers.condensation:condensation_tracker"
            "(engine).num_particles", 1000, NONE,
            note="The protocol's count for the baseline; no choice is recorded.",
            group="Particle counts"),
    Default("MHT modes", f"{_MHT}(num_modes)", 10, NONE,
            note="10 against 50 modes is measured on the protocol's held-out take "
            "(the measurement log, git show 561ec54:docs/measurement-log.md); no choice on "
            "validation is recorded.",
            group="Particle counts"),
    Default("linear-combination particles", f"{_LC}(engine).num_particles", 300, "paper",
            note="Ong & Gong 2002: up to 300 samples.", group="Particle counts"),
    Default("mixed-state particles (command line)", "jaxtrack.cli._mixed_state:DEFAULT_PARTICLES",
            500, "validation", _MM, "2026-11-29",
            _MM_NOTE.format(library="13 795", others="250 particles 14 184, 1 000 particles "
                            "13 437"), group="Particle counts"),
    # ---- latent tracker -----------------------------------------------------------------------
    Default("jump_probability ε", "jaxtrack.trackers.latent:DEFAULT_JUMP_PROBABILITY", 0.05,
            "validation", _EPS_COMMAND, "2026-11-29",
            "Grid {0.05, 0.2, 0.5}, mean ± 95 % half-width (runs lost): 0.05: 8.5 ± 6.5 % (1/9), "
            "0.2: 9.0 ± 7.2 % (1/9), 0.5: 8.0 ± 6.0 % (1/9); all three tie, so the fewest jumps. "
            + _SWEEP_NOTE.format(end="fewer jumps (0: Tian et al.'s plain walk)")
            + "Before: 0.2, first tuned on cmu_1006_wave_hello_2 (a test subject's clip).",
            "Latent tracker"),
    Default("jump_probability ε (argument)", f"{_LATENT}(jump_probability)", 0.05, "validation",
            _EPS_COMMAND, "2026-11-29", "The same value as DEFAULT_JUMP_PROBABILITY.",
            "Latent tracker"),
    Default("mode_radius", f"{_LATENT}(mode_radius)", 3.0, NONE, group="Latent tracker"),
    Default("initial_spread", f"{_LATENT}(initial_spread)", 1.0, NONE, group="Latent tracker"),
    Default("subject_lengths", f"{_LATENT}(subject_lengths)", True, "validation",
            "python -m papers.tian2005.tracking --split validation --clips wide --seeds 2 "
            "--views 3 "
            "--methods latent --estimates own refined --likelihoods limbs+edges "
            "[--set subject_lengths=1]", "2026-11-28",
            "All nine of the validation subject's gesture clips, 54 runs per value: on loses "
            "fewer runs (9/54 against 11/54 refined), which passes the rule.",
            "Latent tracker"),
    Default("partitioned", f"{_LATENT}(partitioned)", False, "validation",
            "python -m papers.tian2005.tracking --split validation [--prior gestures --parts] "
            "[--set partitioned=1] --methods latent condensation --estimates own refined "
            "--likelihoods limbs+edges --seeds 5 --views 3 --no-real-video", "2026-11-27",
            "45 runs per cell: partitioned sampling lowers the own estimate (11.8 against "
            "17.3 %) but with the refinement it is worse than the shipped tracker (7.0 against "
            "5.7 %), so it stays off (papers/tian2005/history.md).", "Latent tracker"),
    Default("latent velocity (second-order walk)", f"{_LATENT}(velocity)", None, "validation",
            "python -m papers.tian2005.tracking --split validation --prior gestures --parts "
            "--methods latent --estimates own --likelihoods limbs+edges --seeds 5 --views 3 "
            "--set partitioned=1 [--set latent_velocity=1]", "2026-11-27",
            "None (the paper's random walk): the second-order walk moved no estimate beyond "
            "its interval (papers/tian2005/history.md).", "Latent tracker"),
    Default("cycles per frame", "jaxtrack.trackers._options:Engine(iterations_per_frame)", 1,
            "validation", "python -m papers.tian2005.tracking --split validation --methods latent "
            "condensation --estimates own --likelihoods limbs+edges --seeds 5 --views 3 "
            "[--set iterations=3]", "2026-11-27",
            "Three cycles moved neither tracker beyond its interval (latent 21.0 against 20.8 %, "
            "CONDENSATION 14.1 against 13.6 %); the linear-combination tracker replaces it by "
            "its own `iterations` (papers/tian2005/history.md).", "Latent tracker"),
    # ---- refinement ---------------------------------------------------------------------------
    Default("refinement steps", "jaxtrack.trackers._options:DEFAULT_REFINE_STEPS", 3,
            "validation", _STEPS_COMMAND, "2026-11-29",
            "Grid {3, 10, 30}, mean ± 95 % half-width (runs lost): 3: 10.4 ± 8.2 % (2/9), "
            "10: 8.5 ± 6.5 % (1/9), 30: 8.7 ± 6.9 % (1/9); all three tie, so the cheapest, "
            "though its mean is the highest. " + _SWEEP_NOTE.format(end="fewer steps")
            + "Before: 10, first tuned on cmu_1006_wave_hello_2 (a test subject's clip).",
            "Refinement"),
    Default("refinement steps (argument)", "jaxtrack.trackers._options:Refinement(steps)", 3,
            "validation", _STEPS_COMMAND, "2026-11-29",
            "The same value as DEFAULT_REFINE_STEPS.", "Refinement"),
    Default("refinement prior_std", "jaxtrack.trackers._options:Refinement(prior_std)", 40.0,
            NONE, group="Refinement"),
    Default("arm search grid", "jaxtrack.trackers._options:DEFAULT_ARM_GRID", 7, "validation",
            date="2026-11-24", note="7 × 7 over 5 × 5, 48 runs (commit 750823e). " + _ARM_NOTE,
            group="Refinement"),
    Default("arm search span", "jaxtrack.trackers._options:DEFAULT_ARM_SPAN", 0.6, "validation",
            date="2026-11-23", note="±0.6 against ±0.9 and ±1.2 rad, 8 runs (commit 535f57f). "
            "The idea was found on the protocol's held-out take (a test clip); the span was "
            "then chosen on validation. " + _ARM_NOTE, group="Refinement"),
    Default("arm search margin", "jaxtrack.trackers._options:DEFAULT_ARM_MARGIN", 2.0,
            "validation", date="2026-11-24",
            note="Only 2 nats was tried, against no margin (commit 01a7ab2). " + _ARM_NOTE,
            group="Refinement"),
    Default("arm search momentum", "jaxtrack.trackers._options:DEFAULT_ARM_MOMENTUM", 1.0,
            "validation", date="2026-11-24", note="Against 0 and 0.5, 48 runs (commit "
            "ecf5f52). " + _ARM_NOTE, group="Refinement"),
    # ---- likelihood ---------------------------------------------------------------------------
    Default("likelihood kind", "jaxtrack.likelihoods.appearance:DEFAULT_LIKELIHOOD",
            "limbs+edges", NONE, group="Likelihood"),
    Default("sharpness λ of the strips", "jaxtrack.likelihoods.limbs:DEFAULT_LIMB_SHARPNESS",
            4.0, NONE, note="Argued in docs/likelihoods.md, \"Limb strips\" (weights spread "
            "too evenly against too few effective particles); no run that chose it is "
            "recorded.", group="Likelihood"),
    Default("sharpness λ of eq. 7's patches", "jaxtrack.likelihoods.ncc:DEFAULT_NCC_SHARPNESS",
            1.0, "paper", note="Tian et al. 2005, eq. 7 as written: exp(−Σ (1 − NCC)).",
            group="Likelihood"),
    Default("strip half width", "jaxtrack.likelihoods.limbs:DEFAULT_STRIP_WIDTH", 0.1, NONE,
            group="Likelihood"),
    Default("edge_weight κ", f"{_EDGES}:DEFAULT_EDGE_WEIGHT", 1.0, "validation",
            _swept("latent", jump_probability="0.05", refine_steps="3", edge_weight="VALUE",
                   edge_tolerance="45"), "2026-11-29",
            "Grid {0.25, 1, 4}, mean ± 95 % half-width (runs lost): 0.25: 12.4 ± 9.2 % (2/9), "
            "1: 10.4 ± 8.2 % (2/9), 4: 12.7 ± 5.5 % (2/9); all three tie and neither end is "
            "simpler, so the lowest mean. " + _SWEEP_NOTE.format(end="lowest mean (no end is "
            "simpler)") + "First tuned against 0.5 and 2 on cmu_1006's waves (a test subject's "
            "clips).", "Likelihood"),
    Default("edge_tolerance", f"{_EDGES}:DEFAULT_EDGE_TOLERANCE", 45.0, "validation",
            _swept("latent", jump_probability="0.05", refine_steps="3", edge_weight="1",
                   edge_tolerance="VALUE"), "2026-11-29",
            "Grid {20°, 45°, 90°}, mean ± 95 % half-width (runs lost): 20°: 10.6 ± 8.9 % (2/9), "
            "45°: 10.4 ± 8.2 % (2/9), 90°: 10.9 ± 9.4 % (2/9); all three tie and neither end is "
            "simpler, so the lowest mean. " + _SWEEP_NOTE.format(end="lowest mean (no end is "
            "simpler)") + "First tuned (fewest runs lost) on cmu_1006's waves (a test subject's "
            "clips).", "Likelihood"),
    Default("edge scale σ", f"{_EDGES}:DEFAULT_EDGE_SCALE", 0.025, NONE, group="Likelihood"),
    Default("foreground_weight μ", f"{_EDGES}:DEFAULT_FOREGROUND_WEIGHT", 2.0, "validation",
            _kept("foreground_weight"), "2026-11-26",
            "First chosen on the Bandai validation splits (commit 23021bf, "
            "papers/tian2005/history.md); kept against 1 (3.50 ± 1.53 %) and 4 "
            "(3.88 ± 1.81 %). " + _KEPT_NOTE,
            "Likelihood"),
    Default("foreground threshold", f"{_EDGES}:DEFAULT_FOREGROUND_THRESHOLD", 20 / 255, NONE,
            group="Likelihood"),
    Default("keypoint weight η", f"{_EDGES}:CAUCHY_KEYPOINT_WEIGHT", 1.5, "validation",
            "python -m papers.tian2005.keypoint_term --estimates refined "
            "--keypoint-weights 1.5 5 15",
            "2026-11-27", "3/2 is the bivariate Cauchy density's exponent; kept against 5 and "
            "15 by the refined trackers' mean error (papers/tian2005/history.md).", "Likelihood"),
    Default("keypoint scales τ_j", f"{_EDGES}:KEYPOINT_SCALES",
            (0.082, 0.037, 0.018, 0.051, 0.051, 0.027, 0.039, 0.028, 0.049, 0.029, 0.033, 0.047),
            "validation", "python -m papers.tian2005.keypoint_term", "2026-11-27",
            "Fitted, not tuned: MediaPipe Pose's median error per marker over √3, on 3 Bandai "
            "clips × 2 views × 2 backgrounds, 60 frames each.", "Likelihood"),
    # ---- MHT ----------------------------------------------------------------------------------
    Default("MHT velocity_weight", f"{_MHT}(velocity_weight)", 0.0, "validation",
            _swept("mht", edge_weight="1", edge_tolerance="45", velocity_weight="VALUE",
                   prior_scale="4", prune_below="1"), "2026-11-29",
            "Grid {0, 0.5, 1}, MHT's own estimate (10 modes), mean ± 95 % half-width (runs lost): "
            "0: 17.1 ± 8.6 % (4/9), 0.5: 14.9 ± 8.1 % (2/9), 1: 31.4 ± 11.2 % (8/9); 0 ties "
            "with 0.5, so constant position. "
            + _SWEEP_NOTE.format(end="simpler prediction (0: constant position)")
            + "Before: 0.5, first tuned on the bundled wave clip, whose take the record does not "
            "name (fair1_wave_hello, training, or one of cmu_1006's two, test).", "MHT"),
    Default("MHT prior_scale", f"{_MHT}(prior_scale)", 4.0, "validation",
            _swept("mht", edge_weight="1", edge_tolerance="45", velocity_weight="0",
                   prior_scale="VALUE", prune_below="1"), "2026-11-29",
            "Grid {1, 4, 16}, MHT's own estimate, mean ± 95 % half-width (runs lost): 1: "
            "20.2 ± 8.2 % (5/9), 4: 17.1 ± 8.6 % (4/9), 16: 18.4 ± 9.1 % (4/9); neither end is "
            "simpler, so the lowest mean. " + _SWEEP_NOTE.format(end="lowest mean (no end is "
            "simpler)") + "First tuned on the bundled wave clip, as velocity_weight.", "MHT"),
    Default("MHT prune_below", f"{_MHT}(prune_below)", 1.0, "validation",
            _swept("mht", edge_weight="1", edge_tolerance="45", velocity_weight="0",
                   prior_scale="4", prune_below="VALUE"), "2026-11-29",
            "Grid {0.25, 1, 4}, MHT's own estimate, mean ± 95 % half-width (runs lost): 0.25: "
            "19.6 ± 11.6 % (5/9), 1: 17.1 ± 8.6 % (4/9), 4: 19.0 ± 9.6 % (4/9); neither end is "
            "simpler, so the lowest mean. " + _SWEEP_NOTE.format(end="lowest mean (no end is "
            "simpler)") + "First tuned on the bundled wave clip, as velocity_weight.", "MHT"),
    Default("MHT refill_spread", f"{_MHT}(refill_spread)", 2.0, NONE, group="MHT"),
    Default("MHT max_steps", f"{_MHT}(max_steps)", 10, NONE, group="MHT"),
    # ---- linear combinations ------------------------------------------------------------------
    Default("P (contour tolerance, px²)", f"{_LC}(fitness).contour_tolerance", 64.0,
            "validation", _LC_VALIDATED, "2026-11-26",
            _LC_NOTE.format(grid="P ∈ {4, 16, 64} × Q ∈ {16, 64, 256}", shipped="16"),
            "Linear combinations"),
    Default("Q (hands tolerance, px²)", f"{_LC}(fitness).hands_tolerance", 16.0,
            "validation", _LC_VALIDATED, "2026-11-26",
            _LC_NOTE.format(grid="P ∈ {4, 16, 64} × Q ∈ {16, 64, 256}", shipped="64"),
            "Linear combinations"),
    Default("ω (step inside a cluster)", f"{_LC}(step)", 0.03, "validation", _LC_VALIDATED,
            "2026-11-26", _LC_NOTE.format(grid="ω ∈ {0.03, 0.1, 0.3} with P = 64, Q = 16",
                                          shipped="0.1"), "Linear combinations"),
    Default("jump_spread", f"{_LC}(jump_spread)", 0.3, NONE, group="Linear combinations"),
    Default("views: neck step (m per cycle)", f"{_LCV}(translation_step)", 0.01, NONE,
            group="Linear combinations"),
    Default("views: turn step (rad per cycle)", f"{_LCV}(yaw_step)", 0.03, NONE,
            group="Linear combinations"),
    Default("views: log-size step (per cycle)", f"{_LCV}(scale_step)", 0.005, NONE,
            group="Linear combinations"),
    Default("iterations per frame", f"{_LC}(iterations)", 5, "paper",
            note="Ong & Gong 2002: 5 CONDENSATION cycles per frame.",
            group="Linear combinations"),
    Default("contour weight O", f"{_FITNESS}(contour_weight)", 0.5, "paper",
            note="Ong & Gong 2002, eq. 9.", group="Linear combinations"),
    Default("hands weight R", f"{_FITNESS}(hands_weight)", 0.5, "paper",
            note="Ong & Gong 2002, eq. 9.", group="Linear combinations"),
    Default("P (FitnessSettings field)", f"{_FITNESS}(contour_tolerance)", 64.0, "validation",
            _LC_VALIDATED, "2026-11-26", "The same value as the tracker's P: FitnessSettings() "
            "alone gives the validated settings (before 2026-11-29: 16).",
            "Linear combinations"),
    Default("Q (FitnessSettings field)", f"{_FITNESS}(hands_tolerance)", 16.0, "validation",
            _LC_VALIDATED, "2026-11-26", "The same value as the tracker's Q (before 2026-11-29: "
            "64).", "Linear combinations"),
    Default("normal search range L", f"{_FITNESS}(search_range)", 10, NONE,
            group="Linear combinations"),
    Default("edge threshold", f"{_FITNESS}(edge_threshold)", 0.05, NONE,
            group="Linear combinations"),
    Default("clusters", "jaxtrack.experiments.linear_combination:train(num_clusters)", 20, NONE,
            note="`python -m papers.ong2002` measures clusters × samples (Fig. 10, 12; "
            "papers/ong2002/README.md), on a training clip and the test subject: no choice on "
            "validation is recorded.",
            group="Linear combinations"),
    Default("view rule", "jaxtrack.experiments.linear_combination:DEFAULT_VIEW_SELECTION",
            "ambiguity", "validation", _VIEWS, "2026-11-27",
            "The validation subject's three Bandai gestures through the four Pose2Sim cameras, "
            "90 frames each (docs/linear-combination.md).", "Linear combinations"),
    Default("skeleton estimate", "jaxtrack.experiments.linear_combination:"
            "DEFAULT_SKELETON_ESTIMATE", "mean", "validation", _VIEWS, "2026-11-27",
            "The same run: the weighted mean 22–42 mm closer than the best particle with every "
            "rule.", "Linear combinations"),
    # ---- mixed state --------------------------------------------------------------------------
    Default("σ_x (position noise, px)", f"{_MIXED}(position_std)", 3.0, NONE,
            group="Mixed state"),
    Default("σ_v (velocity noise, px)", f"{_MIXED}(velocity_std)", 2.0, NONE,
            group="Mixed state"),
    Default("σ_init (px)", f"{_MIXED}(initial_std)", 20.0, NONE, group="Mixed state"),
    Default("σ_v,init (px)", f"{_MIXED}(initial_velocity_std)", 2.0, NONE, group="Mixed state"),
    Default("redetect_probability", f"{_MIXED}(redetect_probability)", 0.0, "validation",
            _MIXED_STATE, "2026-11-27", "0 against 0.02 (5 482 against 6 068 px²). "
            + _MIXED_STATE_NOTE, "Mixed state"),
    Default("redraw_on_switch", f"{_MIXED}(redraw_on_switch)", True, "validation",
            _MIXED_STATE, "2026-11-27", "Re-drawn against kept at δ = 9, 25 and 100. "
            + _MIXED_STATE_NOTE, "Mixed state"),
    Default("part proposal", f"{_MIXED}(part_proposal)", "dynamics", "validation", _MM,
            "2026-11-29", _MM_NOTE.format(library="13 795", others="'posterior' 13 815")
            + " The paper's (§3.2: the parts drawn from the prediction). 'posterior' (the "
            "prediction times the part likelihood, reweighted exactly) averages white "
            "hypothesis noise that the paper's does not (python -m papers.kwatra2002.diagnosis "
            "--synthetic) but scored worse on HDM05 actor bd's held-out validation takes, "
            "2026-11-29: smoothed MSE 6 496 against 6 053 px² (python -m papers.kwatra2002 "
            "--json papers/kwatra2002/results/kwatra2002.json --validation "
            "--skip-paper-setting).", group="Mixed state"),
    Default("keypoint confidence (--keypoints)",
            "jaxtrack.trackers.mixed_state:KEYPOINT_CONFIDENCE", 0.5, NONE,
            note="The least confidence of a detector's keypoint that replaces the silhouette's "
            "part hypothesis; MediaPipe's drawing threshold, as the detection baselines'; not "
            "chosen by a score.", group="Mixed state"),
    Default("part cutoff δ", "jaxtrack.likelihoods.part_distances:PartDistances(cutoff)", 25.0,
            "validation", _MM, "2026-11-29",
            _MM_NOTE.format(library="13 795", others="δ = 9 14 038, δ = 100 13 401")
            + f" First chosen on 2026-11-27 against 9 and 100 ({_MIXED_STATE}) on the earlier "
            "validation clips. " + _MIXED_STATE_NOTE, "Mixed state"),
    Default("part standard deviations (px)",
            "jaxtrack.likelihoods.part_distances:PartDistances(standard_deviations)",
            (8.0, 12.0, 12.0, 10.0, 10.0), "validation", _MM, "2026-11-29",
            _MM_NOTE.format(library="13 795", others="all doubled 13 004"),
            group="Mixed state"),
    Default("log k", "jaxtrack.likelihoods.part_distances:PartDistances(log_k)", 0.0, NONE,
            group="Mixed state"),
    Default("fixed lag (command line)", "jaxtrack.cli._mixed_state:DEFAULT_LAG", 10, NONE,
            group="Mixed state"),
    Default("histogram bins (command line)", "jaxtrack.cli._mixed_state:DEFAULT_BINS", 16, NONE,
            group="Mixed state"),
    Default("posture covariance ridge λ", "jaxtrack.experiments.mixed_state:"
            "DEFAULT_REGULARISATION", 0.2, "validation", _MIXED_STATE, "2026-11-27",
            "Chosen with the posture model's other settings by the tracker's smoothed MSE "
            "(5 482 px²); among ridges of the one-Gaussian model also the lowest instantaneous "
            "posture error on the level validation clips (23.4 % against 23.6 % at 0.05).",
            "Posture model"),
    Default("posture covariance ridge λ (argument)",
            "jaxtrack.priors.postures:fit_posture_model(regularisation)", 0.2, "validation",
            _MIXED_STATE, "2026-11-27", "The same value as DEFAULT_REGULARISATION.",
            "Posture model"),
    Default("posture covariance", "jaxtrack.experiments.mixed_state:DEFAULT_COVARIANCE",
            "per-posture", "validation", _MIXED_STATE, "2026-11-27",
            "The paper's one Gaussian per posture with its own covariance: 5 482 px² against "
            "5 670 px² for the model the classifier alone prefers.", "Posture model"),
    Default("Gaussians per posture", "jaxtrack.experiments.mixed_state:DEFAULT_COMPONENTS", 1,
            "validation", _MIXED_STATE, "2026-11-27", "The same run; 1 is the paper's.",
            "Posture model"),
    Default("training cameras", "jaxtrack.experiments.mixed_state:TRAINING_POSE2SIM_CAMERAS",
            (), "validation", _MIXED_STATE, "2026-11-27",
            "Level views only, the same run.", "Posture model"),
    Default("transition pseudocount α",
            "jaxtrack.priors.postures:fit_posture_model(pseudocount)", 0.5, "validation", _MM,
            "2026-11-29", _MM_NOTE.format(library="13 795", others="α = 5 13 374, α = 25 13 248")
            + " T and the first-frame prior re-estimated from the library posture model's "
            "training counts.", group="Posture model"),
    # ---- GPLVM --------------------------------------------------------------------------------
    Default("GPLVM outer iterations T", "jaxtrack.priors.gplvm._fit:fit_gplvm(iterations)", 2,
            "validation", _GPLVM, "2026-11-26",
            "The lowest held-out error of T ∈ {1, 2, 3} × steps ∈ {75, 150, 300} on the "
            "validation subject's three Bandai clips (docs/gplvm.md).", "GPLVM prior"),
    Default("GPLVM active steps", "jaxtrack.priors.gplvm._fit:fit_gplvm(active_steps)", 150,
            "validation", _GPLVM, "2026-11-26", "Re-chosen with T (docs/gplvm.md).",
            "GPLVM prior"),
    # ---- baselines on detections ----------------------------------------------------------------
    Default("Butterworth order", "jaxtrack.vision.smoothing:BUTTERWORTH_ORDER", 4, "paper",
            note="Pose2Sim's Config.toml, [filtering.butterworth] order = 4: 2 per pass, "
            "forward and backward (its filtering.py).", group="Baselines on detections"),
    Default("Butterworth cutoff (Hz)", "jaxtrack.vision.smoothing:BUTTERWORTH_CUTOFF", 6.0,
            "paper", note="Pose2Sim's Config.toml, [filtering.butterworth] cut_off_frequency.",
            group="Baselines on detections"),
    Default("one-euro f_c,min (Hz)", "jaxtrack.vision.smoothing:ONE_EURO_MIN_CUTOFF", 1.0,
            "paper", note="Casiez, Roussel & Vogel 2012's starting point.",
            group="Baselines on detections"),
    Default("one-euro β", "jaxtrack.vision.smoothing:ONE_EURO_BETA", 0.0, "paper",
            note="Casiez, Roussel & Vogel 2012's starting point (then raised for the motion).",
            group="Baselines on detections"),
    Default("one-euro f_c,d (Hz)", "jaxtrack.vision.smoothing:ONE_EURO_DERIVATIVE_CUTOFF", 1.0,
            "paper", note="Casiez, Roussel & Vogel 2012.", group="Baselines on detections"),
    Default("Kalman row's visibility threshold",
            "jaxtrack.experiments.detections_evaluation:MIN_CONFIDENCE", 0.5, NONE,
            note="MediaPipe's own drawing threshold; the evaluation also reports the row "
            "without it (docs/detections.md).", group="Baselines on detections"),
    # ---- jaxtrack track with detections -----------------------------------------------------
    Default("--fit-iterations", "jaxtrack.cli._detector:FIT_ITERATIONS", 15, NONE,
            note="Adam steps of the detection density's fit on the video; chosen for its cost "
            "(each is a filter run forward and backward), not by a score.",
            group="jaxtrack track with detections"),
    Default("fit particles", "jaxtrack.cli._detector:FIT_PARTICLES", 200, NONE,
            note="Particles per filter run of the fit (fewer where the tracker has fewer); "
            "chosen for its cost.", group="jaxtrack track with detections"),
    Default("fit learning rate", "jaxtrack.cli._detector:FIT_LEARNING_RATE", 0.1, NONE,
            note="Adam's step in the logarithms of the fitted parameters; chosen so that 15 "
            "steps can move a scale by a factor of about 4.",
            group="jaxtrack track with detections"),
    Default("--detector person gate", "jaxtrack.cli._detector:GATE", 0.5, NONE,
            note="As jaxtrack.vision.detections.follow_person's gate: a detection further "
            "than this times the person's keypoint box diagonal is detected again around the "
            "person.", group="jaxtrack track with detections"),
    Default("--detector smallest person", "jaxtrack.cli._detector:MIN_SIZE", 0.05, NONE,
            note="The gate's box diagonal is at least this fraction of the frame's.",
            group="jaxtrack track with detections"),
)


# -- the checks ---------------------------------------------------------------------------------

_WHERE = re.compile(r"^(?P<module>[\w.]+):(?P<name>\w+)(?:\((?P<argument>\w+)\))?"
                    r"(?P<fields>(?:\.\w+)*)$")


def code_value(where: str) -> Any:
    """The value the live code has at ``where`` (module docstring's forms).

    Raises:
        ValueError: ``where`` is malformed, or names a module, attribute or argument that is not
            there (or an argument without a default).
    """
    match = _WHERE.match(where)
    if match is None:
        raise ValueError(f"where {where!r} is not 'module:NAME', 'module:function(argument)', "
                         "optionally followed by '.field'")
    try:
        value = getattr(importlib.import_module(match["module"]), match["name"])
    except (ImportError, AttributeError) as error:
        raise ValueError(f"where {where!r}: {error}") from None
    if match["argument"]:
        parameters = inspect.signature(value).parameters
        parameter = parameters.get(match["argument"])
        if parameter is None or parameter.default is inspect.Parameter.empty:
            raise ValueError(f"where {where!r}: {match['name']} has no argument "
                             f"{match['argument']!r} with a default")
        value = parameter.default
    for field in filter(None, match["fields"].split(".")):
        if not hasattr(value, field):
            raise ValueError(f"where {where!r}: {value!r} has no attribute {field!r}")
        value = getattr(value, field)
    return value


def _same(recorded: Any, live: Any) -> bool:
    """Equal values of the same kind (True is not 1, (1,) is not [1])."""
    if isinstance(recorded, bool) or isinstance(live, bool):
        return type(recorded) is type(live) and recorded == live
    if isinstance(recorded, tuple | list) or isinstance(live, tuple | list):
        return (type(recorded) is type(live) and len(recorded) == len(live)
                and all(_same(a, b) for a, b in zip(recorded, live, strict=True)))
    if isinstance(recorded, int | float) and isinstance(live, int | float):
        return float(recorded) == float(live)
    return type(recorded) is type(live) and recorded == live


def drift(entries: Iterable[Default] = DEFAULTS) -> list[str]:
    """One line per entry whose recorded value is not the code's (empty: none drifted)."""
    problems = []
    for entry in entries:
        try:
            live = code_value(entry.where)
        except ValueError as error:
            problems.append(f"{entry.name}: {error}")
            continue
        if not _same(entry.value, live):
            problems.append(f"{entry.name}: the registry says {entry.value!r} but {entry.where} "
                            f"is {live!r}; update jaxtrack/_defaults.py (and its provenance)")
    return problems


def test_clip_names() -> tuple[str, ...]:
    """Names by which a command can point at a test subject: every test clip's catalogue name
    and file name, and each test subject's person name where it is a name of its own (not a
    bare number like CMU's ``131``, nor a short word like Pose2Sim's ``man``)."""
    from jaxtrack.data.splits import SUBJECTS

    names = set()
    for subject, (split, clips) in SUBJECTS.items():
        if split != "test":
            continue
        person = subject.split(":", 1)[1]
        if not person.isdigit() and len(person) >= 4:
            names.add(person)
        for clip in clips:
            names.update((clip, clip.rsplit("/", 1)[-1]))
    return tuple(sorted(names))


test_clip_names.__test__ = False  # a helper, not a pytest test


def _names_test_clip(command: str, names: Sequence[str]) -> str | None:
    for name in names:
        if re.search(rf"(?<![A-Za-z0-9]){re.escape(name)}(?![A-Za-z0-9])", command):
            return name
    return None


def provenance_problems(entries: Iterable[Default] = DEFAULTS) -> list[str]:
    """One line per entry whose provenance is refused: a split that is not in
    :data:`PROVENANCES` (``"test"`` above all), a command that names a test clip or
    ``--split test``, a date that is not YYYY-MM-DD, a name used twice."""
    names = test_clip_names()
    problems, seen = [], set()
    for entry in entries:
        if entry.name in seen:
            problems.append(f"{entry.name}: two entries have this name")
        seen.add(entry.name)
        if entry.split == "test":
            problems.append(f"{entry.name}: chosen on a test subject; a default must be chosen "
                            "on validation (jaxtrack.data.splits)")
        elif entry.split not in PROVENANCES:
            problems.append(f"{entry.name}: split {entry.split!r} is not one of {PROVENANCES}")
        if re.search(r"--split[= ]+test(?![\w-])", entry.command):
            problems.append(f"{entry.name}: its command runs on the test split: "
                            f"{entry.command!r}")
        clip = _names_test_clip(entry.command, names)
        if clip is not None:
            problems.append(f"{entry.name}: its command names the test clip {clip!r}: "
                            f"{entry.command!r}")
        if entry.date != NONE and not re.fullmatch(r"\d{4}-\d{2}-\d{2}", entry.date):
            problems.append(f"{entry.name}: date {entry.date!r} is not YYYY-MM-DD")
    return problems


# -- the documentation page ---------------------------------------------------------------------

def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _value(value: Any) -> str:
    if isinstance(value, float) and value == 20 / 255:
        return "20/255"
    if isinstance(value, tuple):
        return "(" + ", ".join(_value(item) for item in value) + (",)" if len(value) == 1
                                                                     else ")")
    return repr(value) if isinstance(value, str) else str(value)


def render_markdown(entries: Sequence[Default] = DEFAULTS) -> str:
    """The documentation page of ``entries`` (``docs/defaults.md``)."""
    lines = [
        "# Where the defaults come from",
        "",
        "<!-- Written by `python -m jaxtrack._defaults --markdown docs/defaults.md` from "
        "jaxtrack/_defaults.py; edit that file, not this one. -->",
        "",
        "Every default a user meets without asking for it, with the split of "
        "`jaxtrack.data.splits` it was chosen on (*validation*; *paper* for a value taken from "
        "the paper a tracker implements; *none recorded* where no record says), the command "
        "whose run chose it and the day. No default may be chosen on a test subject: "
        "`tests/test_defaults.py` refuses the split `test` and any command naming a test clip "
        "or `--split test`, and checks every value below against the code.",
        "",
    ]
    on_test = [entry for entry in entries if entry.first_on_test]
    unrecorded = [entry for entry in entries if entry.split == NONE]
    lines += [
        f"Of {len(entries)} defaults, {sum(e.split == 'validation' for e in entries)} were "
        f"chosen (or kept) on validation, {sum(e.split == 'paper' for e in entries)} come from "
        f"a paper and {len(unrecorded)} have no recorded provenance.",
        "",
    ]
    if on_test:  # none left since 2026-11-29; a new one brings the paragraph back
        lines += [
            "**To be chosen again on validation.** These were first tuned on a clip of a test "
            "subject (cmu_1006) and are on validation only because no neighbouring value beat "
            "them there by the keep-unless-beaten rule (docs/trackers.md): "
            + ", ".join(f"`{entry.name}`" for entry in on_test) + ".",
            "",
        ]
    groups = list(dict.fromkeys(entry.group or "Other" for entry in entries))
    for group in groups:
        lines += [f"## {group}", "", "| default | value | chosen on | by | date | note |",
                  "|---|---|---|---|---|---|"]
        for entry in entries:
            if (entry.group or "Other") != group:
                continue
            name = f"{_cell(entry.name)}<br>`{_cell(entry.where)}`"
            command = NONE if entry.command == NONE else f"`{_cell(entry.command)}`"
            split = entry.split + (" (first tuned on a test clip)" if entry.first_on_test
                                   else "")
            lines.append(f"| {name} | `{_cell(_value(entry.value))}` | {split} | {command} | "
                         f"{entry.date} | {_cell(entry.note)} |")
        lines.append("")
    return "\n".join(lines)


def _write_atomically(path: str, text: str) -> None:
    folder = os.path.dirname(os.path.abspath(path))
    descriptor, temporary = tempfile.mkstemp(dir=folder, prefix=".defaults-", suffix=".md")
    try:
        with os.fdopen(descriptor, "w", encoding="utf-8") as file:
            file.write(text)
        os.replace(temporary, path)
    except BaseException:
        os.unlink(temporary)
        raise


def main(argv: Sequence[str] | None = None) -> int:
    """``--markdown PATH`` writes the page; ``--check [PATH]`` checks registry, code and page."""
    parser = argparse.ArgumentParser(prog="python -m jaxtrack._defaults",
                                     description=main.__doc__)
    parser.add_argument("--markdown", metavar="PATH", help="write the documentation page here")
    parser.add_argument("--check", metavar="PATH", nargs="?", const="docs/defaults.md",
                        help="check the registry against the code and the page at PATH")
    args = parser.parse_args(argv)
    if args.markdown is None and args.check is None:
        parser.error("give --markdown PATH or --check [PATH]")
    problems = drift() + provenance_problems()
    if args.check is not None:
        try:
            with open(args.check, encoding="utf-8") as file:
                if file.read() != render_markdown() + "\n":
                    problems.append(f"{args.check} is out of date: run python -m "
                                    f"jaxtrack._defaults --markdown {args.check}")
        except OSError as error:
            problems.append(f"cannot read {args.check}: {error.strerror}")
    if problems:
        print("\n".join(problems), file=sys.stderr)
        return 1
    if args.markdown is not None:
        try:
            _write_atomically(args.markdown, render_markdown() + "\n")
        except OSError as error:
            print(f"cannot write {args.markdown}: {error.strerror}; give a writable path",
                  file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
