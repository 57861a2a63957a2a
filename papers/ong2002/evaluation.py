"""Ong & Gong's tracker on real motion: settings chosen on validation subjects, then 3-D skeleton
error on test subjects against the two baselines, and the error surface over clusters × samples.

Splits by subject (``jaxtrack.data.splits``): the model is trained on training subjects'
gestures, eq. 9's tolerances P, Q and the propagation step ω are chosen on a validation
subject's wave (Bandai-Namco), and the test subject's two waves (AnimatedDrawings cmu_1006) are
only scored (P, Q and ω by the best particle's skeleton, the paper's estimate; the test rows
give both filters' best-particle and weighted-mean skeletons). Every clip is rendered through
Pose2Sim cameras (``--views``) over the real-photo background. The error surface
(``--surface``) repeats the test (and a training clip) over a grid of cluster counts and sample
counts, as the paper's Fig. 10 and 12; ``--multi-view`` tracks each test clip in every view and
selects a view per frame (§5.5–5.7) by the library's rule and skeleton estimate
(``DEFAULT_VIEW_SELECTION``, ``DEFAULT_SKELETON_ESTIMATE``; ``papers.ong2002.view_selection``
compares them with the paper's).

    python -m papers.ong2002.evaluation [--frames 90] [--surface] [--multi-view]
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from pathlib import Path

import numpy as np

from benchmarks._common import device_description, print_table, write_json
from jaxtrack.experiments.linear_combination import TEST_CLIPS as TEST
from jaxtrack.experiments.linear_combination import TRAIN_CLIPS as TRAIN
from jaxtrack.experiments.linear_combination import VALIDATION_CLIPS as VALIDATION

RESULTS = Path(__file__).parent / "results"
TRAINING_CONSTANT = "mean training skeleton (a constant)"
ORACLE_CONSTANT = "mean test skeleton (an oracle constant)"


def _score(trained, sequences, method, **options) -> float:
    from jaxtrack.experiments import linear_combination as lc

    errors = []
    for sequence in sequences:
        run = lc.run_method(method, trained, sequence.observations, **options)
        errors.append(lc.skeleton_error(run["skeleton"], sequence.skeleton).mean())
    return float(np.mean(errors))


P_GRID = (4.0, 16.0, 64.0)
Q_GRID = (16.0, 64.0, 256.0)
STEP_GRID = (0.03, 0.1, 0.3)
"""Eq. 9's P and Q (px²) and the step ω tried on the validation subject."""


def choose_on_validation(trained, validation: list, *, particles: int = 300,
                         iterations: int = 5) -> tuple[list[dict], dict, dict]:
    """Choose P and Q over :data:`P_GRID` × :data:`Q_GRID` (ω = 0.1), then ω over
    :data:`STEP_GRID` per filter with the chosen P and Q, each by the best particle's mean 3-D
    error on the validation sequences.

    Returns:
        ``(sweep, {"P": P, "Q": Q}, {"linear-combination": ω, "global-pca": ω})``; ``sweep``
        holds one row per setting tried.
    """
    import jax.numpy as jnp

    from jaxtrack.likelihoods.contour_normals import FitnessSettings

    engine = dict(particles=particles, iterations=iterations)
    sweep = []
    for contour_tolerance, hands_tolerance in itertools.product(P_GRID, Q_GRID):
        fitness = FitnessSettings(contour_tolerance=jnp.asarray(contour_tolerance),
                                  hands_tolerance=jnp.asarray(hands_tolerance))
        error = _score(trained, validation, "linear-combination", fitness=fitness,
                       step=jnp.asarray(0.1), **engine)
        sweep.append({"P": contour_tolerance, "Q": hands_tolerance, "step": 0.1,
                      "error_m": error})
        print(f"validation P={contour_tolerance:g} Q={hands_tolerance:g}: {error:.4f} m",
              flush=True)
    best = min(sweep, key=lambda row: row["error_m"])
    fitness = FitnessSettings(contour_tolerance=jnp.asarray(best["P"]),
                              hands_tolerance=jnp.asarray(best["Q"]))
    steps = {}
    for method in ("linear-combination", "global-pca"):
        scores = {}
        for step in STEP_GRID:
            scores[step] = _score(trained, validation, method, fitness=fitness,
                                  step=jnp.asarray(step), brownian_step=jnp.asarray(step),
                                  **engine)
            print(f"validation {method} step={step:g}: {scores[step]:.4f} m", flush=True)
        steps[method] = min(scores, key=scores.get)
        sweep += [{"method": method, "P": best["P"], "Q": best["Q"], "step": step,
                   "error_m": error} for step, error in scores.items()]
    return sweep, {"P": best["P"], "Q": best["Q"]}, steps


def test_rows(trained, test: list, *, fitness, steps: dict, particles: int = 300,
              iterations: int = 5) -> list[dict]:
    """The test table: each method (``lc.METHODS``) with each of its skeleton estimates, and two
    constant skeletons, scored on the rendered test sequences.

    Args:
        trained: the trained model (``lc.train``).
        test: the test subject's rendered sequences (``keep_observations=True``).
        fitness: eq. 9's settings.
        steps: ω per filter, ``{"linear-combination": ω, "global-pca": ω}``.
        particles, iterations: samples per iteration and iterations per frame.

    Returns:
        One row per method and estimate: ``method``, ``estimate``, ``step``, ``error_m`` (the
        mean over sequences of the mean 3-D error), ``worst_m``, ``aligned_m`` (after a
        similarity alignment per frame), ``sequences``.
    """
    import jax.numpy as jnp

    from jaxtrack.experiments import linear_combination as lc

    engine = dict(particles=particles, iterations=iterations)
    # (the filters' two skeleton estimates: the best particle's and the weighted mean's)
    rows = []
    for method in lc.METHODS:
        step = steps.get(method, 0.0)
        per_estimate = {}
        for sequence in test:
            run = lc.run_method(method, trained, sequence.observations, fitness=fitness,
                                step=jnp.asarray(step), brownian_step=jnp.asarray(step),
                                **engine)
            for estimate, key in lc.SKELETON_ESTIMATES.items():
                if key in run:
                    errors = per_estimate.setdefault(estimate, ([], []))
                    errors[0].append(lc.skeleton_error(run[key], sequence.skeleton).mean())
                    errors[1].append(lc.aligned_skeleton_error(run[key],
                                                               sequence.skeleton).mean())
        for estimate, (per_sequence, aligned) in per_estimate.items():
            rows.append({"method": method, "estimate": estimate if len(per_estimate) > 1
                         else "-", "step": step, "error_m": float(np.mean(per_sequence)),
                         "worst_m": float(np.max(per_sequence)),
                         "aligned_m": float(np.mean(aligned)), "sequences": len(per_sequence)})
    # two constants: the training skeletons' mean (what a tracker that learned nothing of the
    # pose would report) and the test clips' own mean (an oracle: it knows the test poses)
    layout = trained.model.layout
    training_mean = trained.vectors[:, layout.skeleton_slice].reshape(
        len(trained.vectors), -1, 3).mean(axis=0)
    test_mean = np.concatenate([s.skeleton for s in test]).mean(axis=0)
    for name, constant in ((TRAINING_CONSTANT, training_mean), (ORACLE_CONSTANT, test_mean)):
        held = [np.broadcast_to(constant, s.skeleton.shape) for s in test]
        errors = [lc.skeleton_error(h, s.skeleton).mean() for h, s in zip(held, test,
                                                                           strict=True)]
        rows.append({"method": name, "estimate": "-", "error_m": float(np.mean(errors)),
                     "worst_m": float(np.max(errors)), "aligned_m": float(np.mean(
                         [lc.aligned_skeleton_error(h, s.skeleton).mean()
                          for h, s in zip(held, test, strict=True)])),
                     "sequences": len(test)})
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(prog="python -m papers.ong2002.evaluation",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=90, help="frames per clip (30 fps)")
    parser.add_argument("--views", type=int, nargs="+", default=[0, 1, 2, 3])
    parser.add_argument("--clusters", type=int, default=20)
    parser.add_argument("--particles", type=int, default=300)
    parser.add_argument("--iterations", type=int, default=5)
    parser.add_argument("--surface", action="store_true", help="also the clusters × samples "
                                                                "error surface")
    parser.add_argument("--multi-view", action="store_true", help="also view selection over "
                                                                   "the four cameras")
    parser.add_argument("--out", default=str(RESULTS / "linear_combination_evaluation.json"))
    arguments = parser.parse_args(argv)

    import jax.numpy as jnp

    from jaxtrack.experiments import linear_combination as lc
    from jaxtrack.likelihoods.contour_normals import FitnessSettings

    views = tuple(arguments.views)
    tick = time.perf_counter()
    trained = lc.train(list(TRAIN), views=views, num_clusters=arguments.clusters)
    print(f"trained on {len(trained.vectors)} vectors in {time.perf_counter() - tick:.0f} s: "
          f"{trained.model.num_components} components "
          f"({trained.description['explained_variance']:.2f} of the variance), "
          f"{trained.model.num_clusters} clusters", flush=True)
    render = dict(views=views, max_frames=arguments.frames, keep_observations=True, seed=7)
    validation = [s for clip in VALIDATION for s in lc.render_hybrid_sequences(clip, **render)]
    test = [s for clip in TEST for s in lc.render_hybrid_sequences(clip, **render)]
    engine = dict(particles=arguments.particles, iterations=arguments.iterations)

    # validation: P, Q on a grid (JAX scalars: one compilation), then ω per filter
    sweep, best, steps = choose_on_validation(trained, validation, **engine)
    fitness = FitnessSettings(contour_tolerance=jnp.asarray(best["P"]),
                              hands_tolerance=jnp.asarray(best["Q"]))
    shipped = {"P": float(lc.DEFAULT_FITNESS.contour_tolerance),
               "Q": float(lc.DEFAULT_FITNESS.hands_tolerance), "step": lc.DEFAULT_STEP}
    chosen_is_shipped = (best["P"] == shipped["P"] and best["Q"] == shipped["Q"]
                         and steps["linear-combination"] == shipped["step"])
    print(f"chosen on validation: P={best['P']:g} Q={best['Q']:g} ω={steps}; the library ships "
          f"P={shipped['P']:g} Q={shipped['Q']:g} ω={shipped['step']:g} "
          f"({'the same' if chosen_is_shipped else 'NOT the same'})", flush=True)

    # test subjects: the tracker and both baselines with the settings chosen above
    rows = test_rows(trained, test, fitness=fitness, steps=steps, **engine)
    print(f"device: {device_description()}")
    print(f"test subjects ({', '.join(TEST)}), views {views}, {arguments.frames} frames, "
          f"P={best['P']:g} Q={best['Q']:g}")
    print_table(rows, [("method", "method", "s"), ("estimate", "skeleton", "s"),
                       ("step", "ω", "g"),
                       ("error_m", "3-D error m", ".4f"), ("worst_m", "worst seq. m", ".4f"),
                       ("aligned_m", "after alignment m", ".4f")])

    selection = []
    if arguments.multi_view:
        from jaxtrack.priors.linear_combinations import training_ambiguity

        ambiguities = training_ambiguity(trained.vectors, trained.model.layout)
        for clip in TEST:
            result = lc.multi_view(trained, clip, views=views, max_frames=arguments.frames,
                                   fitness=fitness, step=jnp.asarray(steps["linear-combination"]),
                                   ambiguities=ambiguities, **engine)
            selection.append({key: result[key] for key in (
                "clip", "selected_m", "best_m", "worst_m", "single_view_m", "selected_is_best")})
            print(json.dumps(selection[-1]), flush=True)

    surface = []
    if arguments.surface:  # a 3 x 3 corner; papers.ong2002.surface: the grid
        from papers.ong2002.surface import surface as error_surface

        surface = error_surface((10, 40, 100), (20, 100, 300), views=views,
                                frames=arguments.frames, fitness=fitness,
                                step=steps["linear-combination"],
                                iterations=arguments.iterations)
    write_json(arguments.out, {"device": device_description(), "train": TRAIN,
                               "validation": VALIDATION, "test": TEST, "views": views,
                               "frames": arguments.frames, "trained": trained.description,
                               "sweep": sweep, "chosen": {"P": best["P"], "Q": best["Q"],
                                                          "steps": steps},
                               "shipped": shipped, "chosen_is_shipped": chosen_is_shipped,
                               "test_rows": rows, "view_selection": selection,
                               "surface": surface})


if __name__ == "__main__":
    main()
