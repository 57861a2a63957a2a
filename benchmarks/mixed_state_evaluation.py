"""Kwatra et al.'s mixed-state tracker on real posture changes: settings chosen on validation
clips, then the paper's Table 1 metrics on the test clips.

1. The posture model is trained on ``experiments.mixed_state.TRAINING_CLIPS`` with each
   number of Gaussians per posture of ``--components`` and covariance ridge of
   ``--regularisation`` (by default the library's, which ``benchmarks.posture_classifier``
   chose; cached beside ``--out``), and where several are given the pair is chosen by the
   instantaneous (extended Ghost) posture error on the validation clips
   (``experiments.mixed_state.VALIDATION_CLIPS``: subject 77's half-crouch and subject 02's
   walk, validation subjects of ``jaxtrack.data.splits``, and held-out clips of the training
   subjects who sit and lie down: 75_17 and DeepMimic's roll).
2. With that model, the part likelihood's cutoff δ (``PartDistances.cutoff``, ``--cutoff``:
   how far, in squared standard deviations, a hypothesis still pulls a part), the
   re-detection probability (``MixedStateModel.redetect_probability``, the chance per
   particle and frame that its parts are re-drawn about its posture's hypotheses,
   ``--redetect``) and whether a particle that changes posture keeps its parts or
   has them re-drawn about the new posture's hypotheses (``MixedStateModel.redraw_on_switch``,
   ``--switch``) are chosen together by the smoothed estimate's mean squared error over all
   parts on the validation clips.
3. The test clips are scored once with the chosen settings, for the instantaneous (extended
   Ghost), filtered, smoothed and fixed-lag estimates; with ``--pose2sim-cameras`` also seen
   through those real Pose2Sim cameras (their calibration, elevation and portrait frames at a
   third, 363 × 640: ``experiments.mixed_state.render_posture_sequence``), a second table.

    python -m benchmarks.mixed_state_evaluation [--frames 150] [--particles 500]

Prints the tables and writes ``benchmarks/results/mixed_state_evaluation.json``.
"""

from __future__ import annotations

import argparse
import itertools
import time
from pathlib import Path

import numpy as np

from benchmarks._common import device_description, print_table, write_json

RESULTS = Path(__file__).parent / "results"
KINDS = ("instantaneous", "filtered", "smoothed", "fixed_lag")


def _rows(overall: dict) -> list[dict]:
    return [{"estimate": kind, **{f"mse_{part}": overall[kind]["mse"][part]
                                  for part in ("head", "hands", "feet", "all")},
             "posture_error": 100 * overall[kind]["posture_error"],
             "max_head": overall[kind]["max_head_error"]} for kind in KINDS]


_COLUMNS = [("estimate", "estimate", "s"), ("mse_head", "MSE head", ".1f"),
            ("mse_hands", "MSE hands", ".1f"), ("mse_feet", "MSE feet", ".1f"),
            ("mse_all", "MSE all", ".1f"), ("posture_error", "posture error %", ".1f"),
            ("max_head", "max head px", ".1f")]


def model_path(folder: Path, components: int, ridge: float) -> Path:
    """Where :func:`trained_models` caches the model of ``components`` and ``ridge``."""
    return folder / f"mixed_state_posture_model_k{components}_ridge{ridge:g}.npz"


def trained_models(folder: Path, settings) -> dict:
    """The posture model trained on the training clips with each ``(components, ridge)`` of
    ``settings``, cached in ``folder`` (the clips rendered once for all of them)."""
    from jaxtrack.experiments import mixed_state as ms
    from jaxtrack.priors.postures import load_posture_model, save_posture_model

    paths = {pair: model_path(folder, *pair) for pair in settings}
    models = {pair: load_posture_model(path).model for pair, path in paths.items()
              if path.is_file()}
    missing = [pair for pair in settings if pair not in models]
    if missing:
        features, labels, rendering = ms.training_features()
        for components, ridge in missing:
            models[components, ridge], description = ms.fit(
                features, labels, regularisation=ridge, components=components, **rendering)
            save_posture_model(paths[components, ridge], models[components, ridge],
                               description=description)
    return {pair: models[pair] for pair in settings}


def labelled_features(sequences, num_bins: int):
    """The features and true postures of every frame with a silhouette, all sequences pooled."""
    from jaxtrack.experiments.mixed_state import labelled_features as of_sequence

    pairs = [of_sequence(sequence, num_bins) for sequence in sequences]
    return (np.concatenate([values for values, _ in pairs]),
            np.concatenate([names for _, names in pairs]))


def instantaneous_posture_error(model, features, labels) -> float:
    """The extended Ghost posture's error rate over ``labelled_features``' frames."""
    return float(np.mean(np.asarray(model.classify(features)) != labels))


def main(argv=None) -> int:
    from jaxtrack.experiments.mixed_state import DEFAULT_COMPONENTS, DEFAULT_REGULARISATION

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=150, help="frames per clip (30 fps)")
    parser.add_argument("--particles", type=int, default=500)
    parser.add_argument("--regularisation", type=float, nargs="+",
                        default=[DEFAULT_REGULARISATION],
                        help="the posture model's covariance ridges to choose among (default: "
                             "the library's)")
    parser.add_argument("--components", type=int, nargs="+", default=[DEFAULT_COMPONENTS],
                        help="Gaussians per posture to choose among (default: the library's)")
    parser.add_argument("--redetect", type=float, nargs="+", default=[0.0, 0.02])
    parser.add_argument("--cutoff", type=float, nargs="+", default=[9.0, 25.0, 100.0],
                        help="the part likelihood's cutoffs delta to choose among")
    parser.add_argument("--switch", nargs="+", choices=("keep", "redraw"),
                        default=["keep", "redraw"],
                        help="what a particle that changes posture does with its parts")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--azimuths", type=float, nargs="+", default=None, metavar="DEGREES",
                        help="views of the validation and test clips (default: the five of "
                        "experiments.mixed_state.VIEW_AZIMUTHS; 90 -90: the paper's side views)")
    parser.add_argument("--pose2sim-cameras", type=int, nargs="*", default=[], metavar="INDEX",
                        help="also score the test clips through these Pose2Sim cameras (0-3)")
    parser.add_argument("--out", default=str(RESULTS / "mixed_state_evaluation.json"))
    args = parser.parse_args(argv)
    if any(not 0 <= camera <= 3 for camera in args.pose2sim_cameras) or len(
            set(args.pose2sim_cameras)) != len(args.pose2sim_cameras):
        parser.error(f"--pose2sim-cameras must be distinct indices 0-3, got "
                     f"{args.pose2sim_cameras}")
    for name, values, low, high in (("--regularisation", args.regularisation, 0.0, None),
                                    ("--cutoff", args.cutoff, 0.0, None),
                                    ("--redetect", args.redetect, None, 1.0)):
        for value in values:
            if not np.isfinite(value) or (low is not None and value <= low) or (
                    high is not None and not 0.0 <= value <= high):
                bound = f"above {low:g}" if low is not None else f"in [0, {high:g}]"
                parser.error(f"{name} values must be finite and {bound}, got {value:g}")
    if any(value < 1 for value in args.components):
        parser.error(f"--components must be whole numbers >= 1, got {args.components}")
    for name in ("frames", "particles"):
        if getattr(args, name) < (2 if name == "frames" else 1):
            parser.error(f"--{name} must be at least {2 if name == 'frames' else 1}, got "
                         f"{getattr(args, name)}")
    from jaxtrack.experiments import mixed_state as ms

    begin = time.perf_counter()
    models = trained_models(Path(args.out).parent,
                            list(itertools.product(args.components, args.regularisation)))
    train_seconds = time.perf_counter() - begin
    azimuths = ms.VIEW_AZIMUTHS if args.azimuths is None else tuple(
        float(np.radians(value)) for value in args.azimuths)
    # the evaluation's own rendering of the validation clips, once for every setting
    sequences = ms.render_sequences(ms.VALIDATION_CLIPS, azimuths, ("clutter",), (640, 480),
                                    args.frames, args.seed)
    features, labels = labelled_features(sequences, num_bins=16)
    posture_errors = {pair: instantaneous_posture_error(model, features, labels)
                      for pair, model in models.items()}
    for (components, ridge), error in posture_errors.items():
        print(f"validation, {components} Gaussians per posture, regularisation {ridge:g}: "
              f"instantaneous posture error {100 * error:.1f} %")
    components, ridge = min(posture_errors, key=posture_errors.get)
    posture_model = models[components, ridge]
    validation = {}
    for cutoff, switch, value in itertools.product(args.cutoff, args.switch, args.redetect):
        result = ms.evaluate(posture_model, ms.VALIDATION_CLIPS, azimuths=azimuths,
                             backgrounds=("clutter",),
                             num_particles=args.particles, max_frames=args.frames,
                             seed=args.seed, redetect_probability=value,
                             redraw_on_switch=switch == "redraw", part_cutoff=cutoff,
                             sequences=sequences)
        validation[(cutoff, value, switch)] = result["overall"]
        print(f"validation, cutoff {cutoff:g}, redetect {value:g}, {switch} on a switch: "
              f"smoothed MSE all {result['overall']['smoothed']['mse']['all']:.1f}")
    cutoff, chosen, chosen_switch = min(
        validation, key=lambda key: validation[key]["smoothed"]["mse"]["all"])
    begin = time.perf_counter()
    test = ms.evaluate(posture_model, ms.TEST_CLIPS, azimuths=azimuths, backgrounds=("clutter",),
                       num_particles=args.particles, max_frames=args.frames, seed=args.seed,
                       redetect_probability=chosen,
                       redraw_on_switch=chosen_switch == "redraw", part_cutoff=cutoff)
    test_seconds = time.perf_counter() - begin
    through_cameras = None
    if args.pose2sim_cameras:
        through_cameras = ms.evaluate(posture_model, ms.TEST_CLIPS, azimuths=(),
                                      pose2sim_cameras=args.pose2sim_cameras,
                                      backgrounds=("clutter",), num_particles=args.particles,
                                      max_frames=args.frames, seed=args.seed,
                                      redetect_probability=chosen,
                                      redraw_on_switch=chosen_switch == "redraw",
                                      part_cutoff=cutoff)
    print(f"device: {device_description()}")
    print(f"validation clips {', '.join(ms.VALIDATION_CLIPS)}; posture model {components} "
          f"Gaussians per posture, regularisation {ridge:g} (instantaneous posture error "
          + ", ".join(f"{100 * error:.1f} % at {k}, {value:g}"
                      for (k, value), error in posture_errors.items())
          + "); smoothed MSE all (px², 640 x 480) by part cutoff, re-detection and switch rule:")
    print_table([{"cutoff": delta, "redetect": value, "switch": switch,
                  "mse": scores["smoothed"]["mse"]["all"],
                  "posture_error": 100 * scores["smoothed"]["posture_error"]}
                 for (delta, value, switch), scores in validation.items()],
                [("cutoff", "cutoff", "g"), ("redetect", "redetect", "g"),
                 ("switch", "on a switch", "s"),
                 ("mse", "smoothed MSE all", ".1f"),
                 ("posture_error", "posture error %", ".1f")])
    print(f"\ntest clips {', '.join(ms.TEST_CLIPS)}, {components} Gaussians per posture, "
          f"regularisation {ridge:g}, cutoff "
          f"{cutoff:g}, redetect {chosen:g}, {chosen_switch} on a switch, "
          f"{args.particles} particles, {args.frames} frames per clip, {len(azimuths)} views, "
          f"clutter; "
          f"{test_seconds:.0f} s")
    print_table(_rows(test["overall"]), _COLUMNS)
    if through_cameras is not None:
        print(f"\nthe test clips through Pose2Sim cameras {args.pose2sim_cameras} (0-based; "
              f"363 x 640), the same settings")
        print_table(_rows(through_cameras["overall"]), _COLUMNS)
    write_json(args.out, {"benchmark": "mixed_state_evaluation", "device": device_description(),
                          "arguments": vars(args), "train_seconds": train_seconds,
                          "validation_posture_error": [
                              {"components": k, "regularisation": value,
                               "instantaneous_posture_error": error}
                              for (k, value), error in posture_errors.items()],
                          "chosen_regularisation": ridge, "chosen_components": components,
                          "validation": [{"part_cutoff": delta, "redetect_probability": value,
                                          "on_switch": switch, **scores}
                                         for (delta, value, switch), scores
                                         in validation.items()],
                          "chosen_part_cutoff": cutoff,
                          "chosen_redetect_probability": chosen,
                          "chosen_on_switch": chosen_switch, "test": test,
                          "test_seconds": test_seconds,
                          "test_through_pose2sim_cameras": through_cameras})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
