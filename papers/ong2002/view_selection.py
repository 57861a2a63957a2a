"""View selection (Ong & Gong §5.5–5.7) measured: which per-frame rule picks the view whose 3-D
skeleton is best, and whether fitness and ambiguity can tell at all.

    python -m papers.ong2002.view_selection              # 3 validation clips, then the test clips
    python -m papers.ong2002.view_selection --frames 30  # a shorter run
    python -m papers.ong2002.view_selection --train-clips CLIP ... --clusters 40 --out other.json

Each clip is rendered through the four Pose2Sim cameras over the real-photo background and
tracked in each view on its own (``jaxtrack.experiments.linear_combination.multi_view``: the
model of ``jaxtrack train --method linear-combination``'s training subjects, the library's
eq. 9 P = 64, Q = 16 and ω = 0.03, as ``papers.ong2002.evaluation`` chose them on validation).
Per frame a rule picks one view; its 3-D skeleton error is compared with the best view of the
frame (an oracle) and the worst. The rules:

- ``paper``: greatest fitness × 1/ambiguity (eq. 14; ``select_views``' defaults);
- ``fitness``: greatest fitness alone;
- ``ambiguity``: least ambiguity alone;
- ``consensus``: the view whose 3-D skeleton, turned into the world's axes through the
  calibration, lies closest to the other views' (the median distance to theirs): a view that
  agrees with the others is more likely right, where a wrong one is wrong in its own way;
- ``spread``: the least spread of the view's particles' 3-D skeletons about their weighted
  mean (``LinearCombinationEstimate.skeleton_spread``): the filter's own ambiguity of the frame,
  read off its particles where eq. 14 reads it off the nearest training vector;
- ``fitness/spread``: the greatest fitness × 1/spread, the paper's product with the spread in
  place of eq. 14's ambiguity;
- each of these averaged over ±5 frames (``... ±5``), which ignores one-frame flukes;
- for reference, not rules: the one view best over the whole clip, known in hindsight; and,
  not a selection at all, the views' skeletons averaged in the world's axes (``fused``).
- a bound, not a rule: the best weighting of the four signals above (log fitness, −log
  ambiguity, −log spread, −consensus distance, each over ±5 frames) found by a grid search on
  the validation clips themselves (:func:`linear_bound`). No rule built from these signals by
  a weighted sum does better on validation; the weights are then applied to the test clips.

Every rule is scored with each of the tracker's two 3-D skeleton estimates: the best-fitness
particle's (the paper's) and the particles' weighted mean
(``jaxtrack.experiments.linear_combination.SKELETON_ESTIMATES``), one table each. The estimate
and rule with the lowest mean error on the validation clips (the validation subject's three
Bandai-Namco gestures) are the ones to use (with the best particle alone, before the weighted
mean was scored, it chose ``fitness ±5``,
``jaxtrack.experiments.linear_combination.DEFAULT_VIEW_SELECTION``); the test clips (the test
subject's two waves) are scored once with every rule, for the tables. Also reported per clip:
the mean over frames of the Spearman rank correlation, across the four views, between each
view's 3-D error and its fitness (a good predictor: strongly negative), its ambiguity and its
spread (each: strongly positive).

The paper's targets: the selected view ≥ 30 % below the worst and within 10 % of the oracle.
Writes ``papers/ong2002/results/view_selection.json`` and prints the markdown tables.
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np

from benchmarks._common import device_description, run_header
from jaxtrack._files import write_json_atomically

RESULTS = Path(__file__).parent / "results"
VALIDATION = ("bandai/dataset-2_wave-right-hand_normal_001",
              "bandai/dataset-2_wave-left-hand_normal_001",
              "bandai/dataset-2_raise-up-right-hand_normal_001")
"""The validation subject's gestures (the first is ``linear_combination.VALIDATION_CLIPS``)."""
RULES = {"paper": (1.0, 1.0, "ambiguity"), "fitness": (1.0, 0.0, "ambiguity"),
         "ambiguity": (0.0, 1.0, "ambiguity"), "spread": (0.0, 1.0, "spread"),
         "fitness/spread": (1.0, 1.0, "spread")}
"""Rule → (weight of log fitness, weight of −log uncertainty, which uncertainty: eq. 14's
``"ambiguity"`` or the particles' skeleton ``"spread"``)."""
ESTIMATE_NAMES = {"best": "best particle's skeleton (the paper's estimate)",
                  "mean": "weighted mean skeleton"}
WINDOW = 5
RULE_NAMES = tuple(rule + suffix for rule in (*RULES, "consensus")
                   for suffix in ("", f" ±{WINDOW}"))
"""The rules a choice is made among (not the hindsight oracle reported beside them)."""


def rule_scores(log_fitness: np.ndarray, uncertainty: dict[str, np.ndarray], found: np.ndarray,
                rule: str, window: int = 0) -> np.ndarray:
    """``(time, views)`` the score each view gets from ``rule`` (:data:`RULES`) averaged over
    ±``window`` frames (``jaxtrack.priors.linear_combinations.view_scores``); −inf where the
    view did not observe the frame. ``uncertainty`` maps ``"ambiguity"`` and ``"spread"`` to
    their ``(time, views)`` values."""
    from jaxtrack.priors.linear_combinations import view_scores

    fitness_weight, uncertainty_weight, measure = RULES[rule]
    return view_scores(log_fitness, uncertainty[measure], found, fitness_weight=fitness_weight,
                       ambiguity_weight=uncertainty_weight, window=window)


def consensus(skeletons_world: np.ndarray, found: np.ndarray) -> np.ndarray:
    """``(time, views)`` each view's median distance (metres, the mean over vertices) from its
    3-D skeleton to those of the other views that observed the frame, all in the world's axes;
    0 where no other view observed it, NaN where the view itself did not."""
    skeletons = np.asarray(skeletons_world, np.float64)
    found = np.asarray(found, bool)
    distance = np.linalg.norm(skeletons[:, :, None] - skeletons[:, None, :], axis=-1).mean(-1)
    others = found[:, None, :] & ~np.eye(found.shape[1], dtype=bool)[None]
    with warnings.catch_warnings():  # frames where no other view observed: all-NaN rows
        warnings.simplefilter("ignore", RuntimeWarning)
        median = np.nanmedian(np.where(others, distance, np.nan), axis=2)
    return np.where(found, np.where(others.any(axis=2), median, 0.0), np.nan)


def _windowed(values: np.ndarray, found: np.ndarray, window: int) -> np.ndarray:
    """``(time, views)`` values averaged over ±``window`` frames as the rules' scores are
    (``view_scores`` with the values as the log fitness and no ambiguity); −inf where the view
    did not observe the frame or the value is not finite."""
    from jaxtrack.priors.linear_combinations import view_scores

    return view_scores(values, np.zeros_like(values), found, fitness_weight=1.0,
                       ambiguity_weight=0.0, window=window)


def consensus_scores(skeletons_world: np.ndarray, found: np.ndarray,
                     window: int = 0) -> np.ndarray:
    """``(time, views)`` scores of the ``consensus`` rule: minus :func:`consensus`, averaged
    over ±``window`` frames as the other rules are; −inf where the view did not observe."""
    closeness = -consensus(skeletons_world, found)
    return _windowed(np.where(np.isfinite(closeness), closeness, -np.inf), found, window)


def fused_error(skeletons_world: np.ndarray, truth_world: np.ndarray,
                found: np.ndarray) -> float:
    """Mean 3-D error (metres) of the observing views' skeletons averaged in the world's axes
    (frames no view observed: every view's)."""
    skeletons, found = np.asarray(skeletons_world, np.float64), np.asarray(found, bool)
    weights = np.where(found.any(axis=1, keepdims=True), found, True) * 1.0
    fused = np.einsum("tv,tvjk->tjk", weights, skeletons) / weights.sum(axis=1)[:, None, None]
    return float(np.linalg.norm(fused - np.asarray(truth_world), axis=-1).mean())


def torso_normal(skeletons: np.ndarray) -> np.ndarray:
    """``(..., 3)`` unit normals of the torso's front, from ``(..., 12, 3)`` skeletons
    (``UPPER_BODY_12`` order) in the world's axes (y up): (right − left shoulder) points to
    the person's right, (neck − pelvis) up, and up × right forward."""
    skeletons = np.asarray(skeletons, np.float64)
    across = skeletons[..., 4, :] - skeletons[..., 8, :]
    up = skeletons[..., 1, :] - skeletons[..., 3, :]
    normal = np.cross(up, across)
    return normal / np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-12)


def facing(skeletons_world: np.ndarray, truth_world: np.ndarray) -> dict:
    """How often each view's 3-D skeleton faces the wrong way, and what that costs.

    A frame's skeleton faces the wrong way when its torso's front (:func:`torso_normal`) lies
    more than 90° from the true one's: the front-or-back question a silhouette leaves open.
    Returns per view the share of such frames (``flipped``), the mean 3-D error (metres) of
    those frames and of the others, and, a diagnostic not a method (it reads the truth), the
    mean error per view and of the per-frame best view had every flipped skeleton been turned
    by 180° about the vertical through the neck (the skeletons are neck-relative)."""
    skeletons = np.asarray(skeletons_world, np.float64)
    truth = np.asarray(truth_world, np.float64)
    flipped = np.einsum("tvk,tk->tv", torso_normal(skeletons), torso_normal(truth)) < 0
    errors = np.linalg.norm(skeletons - truth[:, None], axis=-1).mean(-1)
    turned = np.where(flipped[..., None, None], skeletons * np.array([-1.0, 1.0, -1.0]),
                      skeletons)
    turned_errors = np.linalg.norm(turned - truth[:, None], axis=-1).mean(-1)
    mean = lambda values: float(values.mean()) if values.size else None  # noqa: E731
    return {"flipped": flipped.mean(axis=0).tolist(),
            "flipped_error_m": mean(errors[flipped]), "other_error_m": mean(errors[~flipped]),
            "turned_single_view_m": turned_errors.mean(axis=0).tolist(),
            "turned_oracle_m": float(turned_errors.min(axis=1).mean())}


SIGNALS = ("log fitness", "−log ambiguity", "−log spread", "−consensus distance")
BOUND_GRID = (-2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0)


def signals(result: dict, estimate: str, window: int = WINDOW) -> np.ndarray:
    """``(time, views, 4)`` the :data:`SIGNALS` of a ``multi_view`` result for the skeleton
    ``estimate``, each averaged over ±``window`` frames and centred on its mean over the views
    of each frame (−inf where the view did not observe the frame)."""
    found = np.asarray(result["found"], bool)
    ambiguity = np.maximum(np.asarray(result["ambiguity"], np.float64), 0.0)
    spread = np.asarray(result["skeleton_spread_m"], np.float64)
    raw = (np.asarray(result["log_fitness"], np.float64), -np.log(ambiguity + 1e-3),
           -np.log(spread + 1e-3))
    stacked = np.stack([*(_windowed(values, found, window) for values in raw),
                        consensus_scores(result["estimates"][estimate]["skeletons_world"],
                                         found, window)], -1)
    finite = np.where(np.isfinite(stacked), stacked, np.nan)
    with warnings.catch_warnings():  # frames no view observed: all-NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        centred = finite - np.nanmean(finite, axis=1, keepdims=True)
    return np.where(np.isfinite(centred), centred, -np.inf)


def _selected(features: np.ndarray, errors: np.ndarray, weights: np.ndarray) -> float:
    unseen = np.any(np.isneginf(features), axis=-1)  # the view did not observe the frame
    scores = np.where(unseen, -np.inf, np.nan_to_num(features, neginf=0.0) @ weights)
    return selection_errors(errors, scores)["selected_m"]


def linear_bound(clips: list[tuple[np.ndarray, np.ndarray]], grid=BOUND_GRID) -> dict:
    """The weights (one per :data:`SIGNALS`, each from ``grid``, not all 0) whose weighted sum
    of the signals selects views of the least mean error over ``clips`` (pairs of
    :func:`signals` and the ``(time, views)`` errors): the best any such rule does on these
    clips, found on them. Returns ``{"weights", "selected_m", "oracle_m", "worst_m"}``, means
    over clips."""
    from itertools import product

    best_error, best_weights = np.inf, None
    for weights in product(grid, repeat=len(SIGNALS)):
        if not any(weights):
            continue
        weights = np.asarray(weights, np.float64)
        error = np.mean([_selected(features, errors, weights) for features, errors in clips])
        if error < best_error - 1e-12:
            best_error, best_weights = error, weights
    return {"weights": best_weights.tolist(), **scored_with(clips, best_weights)}


def scored_with(clips: list[tuple[np.ndarray, np.ndarray]], weights) -> dict:
    """Mean over ``clips`` of the selected, oracle and worst errors of the rule ``weights``."""
    weights = np.asarray(weights, np.float64)
    return {"selected_m": float(np.mean([_selected(f, e, weights) for f, e in clips])),
            "oracle_m": float(np.mean([e.min(axis=1).mean() for _, e in clips])),
            "worst_m": float(np.mean([e.max(axis=1).mean() for _, e in clips]))}


def selection_errors(errors: np.ndarray, scores: np.ndarray) -> dict:
    """The mean 3-D error of the view of greatest score per frame, of the best and of the worst
    view, in metres."""
    chosen = np.argmax(scores, axis=1)
    return {"selected_m": float(errors[np.arange(len(errors)), chosen].mean()),
            "oracle_m": float(errors.min(axis=1).mean()),
            "worst_m": float(errors.max(axis=1).mean())}


def predictor_correlations(errors: np.ndarray, found: np.ndarray, **predictors: np.ndarray
                           ) -> dict:
    """Mean over the frames every view observed of the Spearman correlation, across views,
    of the 3-D error with each ``(time, views)`` predictor: ``{"error_vs_NAME": mean}`` (None
    where no frame's predictor differed between views)."""
    from scipy.stats import spearmanr

    correlations = {name: [] for name in predictors}
    for t in np.flatnonzero(np.all(found, axis=1)):
        if np.ptp(errors[t]) == 0:
            continue
        for name, values in predictors.items():
            if np.ptp(values[t]) > 0:
                correlations[name].append(spearmanr(errors[t], values[t])[0])
    return {f"error_vs_{name}": float(np.mean(values)) if values else None
            for name, values in correlations.items()}


def evaluate_clip(result: dict, estimate: str = "best") -> dict:
    """Every rule's errors and the predictors' correlations on one ``multi_view`` result, for
    the 3-D skeleton ``estimate`` (``"best"``, the best particle's; ``"mean"``, the weighted
    mean's: ``jaxtrack.experiments.linear_combination.SKELETON_ESTIMATES``)."""
    chosen = result["estimates"][estimate]
    errors = np.asarray(chosen["errors_m"], np.float64)
    log_fitness = np.asarray(result["log_fitness"], np.float64)
    ambiguity = np.asarray(result["ambiguity"], np.float64)
    found = np.asarray(result["found"], bool)
    spread = np.asarray(result["skeleton_spread_m"], np.float64)
    uncertainty = {"ambiguity": ambiguity, "spread": spread}
    rules = {}
    world = np.asarray(chosen["skeletons_world"], np.float64)
    for rule in (*RULES, "consensus"):
        for window in (0, WINDOW):
            name = rule + (f" ±{window}" if window else "")
            scores = (consensus_scores(world, found, window) if rule == "consensus" else
                      rule_scores(log_fitness, uncertainty, found, rule, window))
            rules[name] = selection_errors(errors, scores)
    # a second oracle: the one view that is best over the whole clip, known in hindsight
    best_view = np.argmin(errors.mean(axis=0))
    rules["best single view (hindsight)"] = selection_errors(
        errors, np.broadcast_to(np.arange(errors.shape[1]) == best_view, errors.shape))
    rules["fused (not a selection)"] = {
        **selection_errors(errors, np.zeros_like(errors)),
        "selected_m": fused_error(world, result["truth_world"], found)}
    return {"clip": result["clip"], "estimate": estimate, "frames": len(errors),
            "rules": rules, "single_view_m": errors.mean(axis=0).tolist(),
            "facing": facing(world, result["truth_world"]),
            **predictor_correlations(errors, found, fitness=log_fitness, ambiguity=ambiguity,
                                     spread=spread)}


def summarise(clips: list[dict]) -> dict:
    """Per rule the mean over clips of the selected, oracle and worst errors and the two
    targets' ratios."""
    rows = {}
    for rule in clips[0]["rules"]:
        selected, oracle, worst = (float(np.mean([clip["rules"][rule][key] for clip in clips]))
                                   for key in ("selected_m", "oracle_m", "worst_m"))
        rows[rule] = {"selected_m": selected, "oracle_m": oracle, "worst_m": worst,
                      "below_worst": 1 - selected / worst, "above_oracle": selected / oracle - 1}
    return rows


def facing_means(clips: list[dict]) -> dict:
    """Means over clips (and views) of :func:`facing`'s figures beside the untouched ones."""
    mean = lambda values: float(np.mean(values))  # noqa: E731
    return {"flipped": mean([clip["facing"]["flipped"] for clip in clips]),
            "single_view_m": mean([clip["single_view_m"] for clip in clips]),
            "turned_single_view_m": mean([clip["facing"]["turned_single_view_m"]
                                          for clip in clips]),
            "oracle_m": mean([clip["rules"]["paper"]["oracle_m"] for clip in clips]),
            "turned_oracle_m": mean([clip["facing"]["turned_oracle_m"] for clip in clips])}


def table(validation: dict, test: dict, chosen: str | None) -> str:
    lines = ["| rule | validation: selected / oracle / worst (mm) | below worst | above oracle "
             "| test: selected / oracle / worst (mm) | below worst | above oracle |",
             "|" + "---|" * 7]
    for rule in validation:
        cells = []
        for rows in (validation, test):
            row = rows[rule]
            cells += [f"{1e3 * row['selected_m']:.0f} / {1e3 * row['oracle_m']:.0f} / "
                      f"{1e3 * row['worst_m']:.0f}", f"{100 * row['below_worst']:.0f} %",
                      f"{100 * row['above_oracle']:.0f} %"]
        name = f"**{rule}** (chosen)" if rule == chosen else rule
        lines.append("| " + " | ".join([name, *cells]) + " |")
    return "\n".join(lines)


def _percentages(shares) -> str:
    return "/".join(f"{100 * share:.0f}" for share in shares) + " %"


def _millimetres(metres) -> str:
    return "—" if metres is None else f"{1e3 * metres:.0f} mm"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m papers.ong2002.view_selection",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=90, help="frames per clip (30 fps)")
    parser.add_argument("--out", type=Path, default=RESULTS / "view_selection.json")
    parser.add_argument("--train-clips", nargs="+", metavar="CLIP", default=None,
                        help="training subjects' clips to train the model on (default: "
                             "jaxtrack.experiments.linear_combination.TRAIN_CLIPS)")
    parser.add_argument("--clusters", type=int, default=20, help="k-means clusters (20)")
    args = parser.parse_args(argv)
    if args.frames < 2 * WINDOW + 1:
        parser.error(f"--frames must be at least {2 * WINDOW + 1}, got {args.frames}")

    import jax.numpy as jnp

    from jaxtrack.data import resolve_clip
    from jaxtrack.data.splits import check_disjoint
    from jaxtrack.experiments import linear_combination as lc
    from jaxtrack.likelihoods.contour_normals import FitnessSettings
    from jaxtrack.priors.linear_combinations import training_ambiguity

    started = time.perf_counter()
    views = (0, 1, 2, 3)
    train_clips = list(args.train_clips or lc.TRAIN_CLIPS)
    try:
        if args.clusters < 1:
            raise ValueError(f"--clusters must be a positive integer, got {args.clusters}")
        # the split is read from the clips' names: refused before any file is looked up
        check_disjoint(train_clips, [*VALIDATION, *lc.TEST_CLIPS])
        for clip in train_clips:
            resolve_clip(clip)
    except (ValueError, OSError) as error:
        parser.error(" ".join(str(error).split()))
    trained = lc.train(train_clips, views=views, num_clusters=args.clusters)
    ambiguities = training_ambiguity(trained.vectors, trained.model.layout)
    # the library's P, Q and ω (64, 16, 0.03), chosen on validation by papers.ong2002.evaluation
    fitness = FitnessSettings(contour_tolerance=jnp.asarray(lc.DEFAULT_FITNESS.contour_tolerance),
                              hands_tolerance=jnp.asarray(lc.DEFAULT_FITNESS.hands_tolerance))
    print(f"trained on {len(trained.vectors)} vectors ({time.perf_counter() - started:.0f} s); "
          f"{device_description()}", flush=True)
    results = {estimate: {} for estimate in lc.SKELETON_ESTIMATES}
    features = {estimate: {} for estimate in lc.SKELETON_ESTIMATES}  # (signals, errors) per clip
    for split, clips in (("validation", VALIDATION), ("test", lc.TEST_CLIPS)):
        for clip in clips:
            result = lc.multi_view(trained, clip, views=views, max_frames=args.frames,
                                   fitness=fitness, step=jnp.asarray(lc.DEFAULT_STEP),
                                   ambiguities=ambiguities)
            for estimate, by_split in features.items():
                by_split.setdefault(split, []).append(
                    (signals(result, estimate), np.asarray(
                        result["estimates"][estimate]["errors_m"], np.float64)))
            for estimate, by_split in results.items():
                row = evaluate_clip(result, estimate)
                by_split.setdefault(split, []).append(row)
                paper = row["rules"]["paper"]
                print(f"  {split} {clip}, {estimate}: paper {1e3 * paper['selected_m']:.0f} mm, "
                      f"oracle {1e3 * paper['oracle_m']:.0f}, worst "
                      f"{1e3 * paper['worst_m']:.0f}; error vs fitness "
                      f"{row['error_vs_fitness']:+.2f}, vs ambiguity "
                      f"{row['error_vs_ambiguity']:+.2f}, vs spread "
                      f"{row['error_vs_spread']:+.2f}", flush=True)
                turn = row["facing"]
                print(f"    facing the wrong way in {_percentages(turn['flipped'])} of frames "
                      f"(views {views}): {_millimetres(turn['flipped_error_m'])} there, "
                      f"{_millimetres(turn['other_error_m'])} elsewhere; turned: each view "
                      f"{_millimetres(np.mean(turn['turned_single_view_m']))} against "
                      f"{_millimetres(np.mean(row['single_view_m']))}, the best view "
                      f"{_millimetres(turn['turned_oracle_m'])} against "
                      f"{_millimetres(paper['oracle_m'])}", flush=True)
    summaries = {estimate: {split: summarise(rows) for split, rows in by_split.items()}
                 for estimate, by_split in results.items()}
    facing_summary = {estimate: {split: facing_means(rows) for split, rows in by_split.items()}
                      for estimate, by_split in results.items()}
    # the estimate and the rule together, on validation
    chosen_estimate, chosen = min(
        ((estimate, rule) for estimate in summaries for rule in RULE_NAMES),
        key=lambda pair: summaries[pair[0]]["validation"][pair[1]]["selected_m"])
    text = "\n\n".join(
        f"{ESTIMATE_NAMES[estimate]}:\n\n" + table(
            summary["validation"], summary["test"], chosen if estimate == chosen_estimate
            else None) for estimate, summary in summaries.items())
    print(text)
    for estimate, by_split in facing_summary.items():
        for split, means in by_split.items():
            print(f"{split}, {ESTIMATE_NAMES[estimate]}: facing the wrong way in "
                  f"{100 * means['flipped']:.0f} % of frames and views; each view "
                  f"{_millimetres(means['single_view_m'])}, turned "
                  f"{_millimetres(means['turned_single_view_m'])}; the best view "
                  f"{_millimetres(means['oracle_m'])}, turned "
                  f"{_millimetres(means['turned_oracle_m'])}")
    bounds = {}
    for estimate, by_split in features.items():
        bound = linear_bound(by_split["validation"])
        weights = bound.pop("weights")
        bounds[estimate] = {"signals": list(SIGNALS), "weights": weights, "validation": bound,
                            "test": scored_with(by_split["test"], weights)}
        for split in ("validation", "test"):
            row = bounds[estimate][split]
            print(f"{split}, {ESTIMATE_NAMES[estimate]}: the best weighted sum of the signals, "
                  f"fitted on validation (a bound, not a rule; weights {weights}): "
                  f"{_millimetres(row['selected_m'])} (oracle {_millimetres(row['oracle_m'])}, "
                  f"worst {_millimetres(row['worst_m'])}), "
                  f"{100 * (1 - row['selected_m'] / row['worst_m']):.0f} % below the worst, "
                  f"{100 * (row['selected_m'] / row['oracle_m'] - 1):.0f} % above the oracle")
    header = run_header("papers.ong2002.view_selection", argv, started)
    write_json_atomically(args.out, {
        **header, "frames": args.frames,
        "settings": {"P": float(lc.DEFAULT_FITNESS.contour_tolerance),
                     "Q": float(lc.DEFAULT_FITNESS.hands_tolerance), "step": lc.DEFAULT_STEP,
                     "clusters": args.clusters,
                     "particles": 300, "iterations": 5, "views": list(views),
                     "train_clips": train_clips},
        "chosen_on_validation": {"estimate": chosen_estimate, "rule": chosen},
        "summaries": summaries, "facing": facing_summary, "linear_bound": bounds,
        "clips": results, "table": text})
    print(f"chose {chosen!r} with the {ESTIMATE_NAMES[chosen_estimate]} on validation; wrote "
          f"{args.out} in {header['seconds']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
