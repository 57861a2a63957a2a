"""Kwatra et al.'s mixed-state tracker on real posture changes: settings chosen on validation
clips, then the paper's Table 1 metrics on the test clips.

1. A posture model is trained on ``experiments.mixed_state.TRAINING_CLIPS`` for each of
   ``--posture-models`` (cached beside ``--out``; by default two: the paper's one Gaussian per
   posture, as the library's defaults have it, and the mixture that
   ``papers.kwatra2002.posture_classifier`` chose by the classifier alone), and each is scored
   on the validation clips
   (``experiments.mixed_state.VALIDATION_CLIPS``, all of validation subjects of
   ``jaxtrack.data.splits``: CMU 77's half-crouch, CMU 02's walk, HDM05 actor mm's lie-down,
   squat and crouch).
2. With each model, the part likelihood's cutoff δ (``PartDistances.cutoff``, ``--cutoff``:
   how far, in squared standard deviations, a hypothesis still pulls a part), the
   re-detection probability (``MixedStateModel.redetect_probability``, the chance per
   particle and frame that its parts are re-drawn about its posture's hypotheses,
   ``--redetect``) and whether a particle that changes posture keeps its parts or
   has them re-drawn about the new posture's hypotheses (``MixedStateModel.redraw_on_switch``,
   ``--switch``) are chosen together with the posture model by the smoothed estimate's mean
   squared error over all parts on the validation clips: the posture model is the tracker's,
   and is chosen by what the tracker does with it. (Until 2026-11-27 the posture model was
   chosen first, by the instantaneous posture error; the classifier that error prefers made
   the tracker worse on validation.)
3. The test clips (``experiments.mixed_state.TEST_CLIPS``, all of test subjects: CMU 139,
   CMU 131, HDM05 actor tr) are scored once with the chosen settings, with 95 % bootstrap
   intervals over clips, for the instantaneous (extended
   Ghost), filtered, smoothed and fixed-lag estimates, and the two-pass smoother (backward
   simulation with ``--backward-paths`` paths, ``trackers.mixed_state.smooth_backward``) for
   comparison with the paper's ancestry tracing, with its run time; with
   ``--pose2sim-cameras`` also seen through those real Pose2Sim cameras (their calibration,
   elevation and portrait frames at a third, 363 × 640:
   ``experiments.mixed_state.render_posture_sequence``), a second table.

    python -m papers.kwatra2002.mixed_state_evaluation [--frames 150] [--particles 500]

Prints the tables and writes ``papers/kwatra2002/results/mixed_state_evaluation.json``.
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
             "max_head": overall[kind]["max_head_error"]}
            for kind in (*KINDS, "backward") if kind in overall]


_COLUMNS = [("estimate", "estimate", "s"), ("mse_head", "MSE head", ".1f"),
            ("mse_hands", "MSE hands", ".1f"), ("mse_feet", "MSE feet", ".1f"),
            ("mse_all", "MSE all", ".1f"), ("posture_error", "posture error %", ".1f"),
            ("max_head", "max head px", ".1f")]


VIEWS = {"level": (), "level+pose2sim": (0, 1, 2, 3)}
"""A posture model's training views: the level azimuths alone, or also the Pose2Sim cameras."""


def posture_model_spec(text: str) -> tuple[int, str, float, str]:
    """``"K,COVARIANCE,RIDGE,VIEWS"`` (e.g. ``2,pooled,1,level+pose2sim``) as a tuple, or a
    ValueError that says what is wrong."""
    from jaxtrack.priors.postures import COVARIANCES

    parts = text.split(",")
    if len(parts) != 4:
        raise ValueError(f"{text!r} is not K,COVARIANCE,RIDGE,VIEWS")
    components, covariance, ridge, views = parts
    try:
        components, ridge = int(components), float(ridge)
    except ValueError:
        raise ValueError(f"{text!r}: K must be a whole number and RIDGE a number") from None
    if components < 1 or not (np.isfinite(ridge) and ridge > 0):
        raise ValueError(f"{text!r}: K must be >= 1 and RIDGE positive")
    if covariance not in COVARIANCES or views not in VIEWS:
        raise ValueError(f"{text!r}: COVARIANCE must be one of {', '.join(COVARIANCES)} and "
                         f"VIEWS one of {', '.join(VIEWS)}")
    return components, covariance, ridge, views


def spec_text(spec: tuple[int, str, float, str]) -> str:
    components, covariance, ridge, views = spec
    return f"{components},{covariance},{ridge:g},{views}"


def default_spec() -> tuple[int, str, float, str]:
    """The library's posture model (``experiments.mixed_state``'s defaults) as a spec."""
    from jaxtrack.experiments import mixed_state as ms

    views = next(name for name, cameras in VIEWS.items()
                 if cameras == tuple(ms.TRAINING_POSE2SIM_CAMERAS))
    return (ms.DEFAULT_COMPONENTS, ms.DEFAULT_COVARIANCE, ms.DEFAULT_REGULARISATION, views)


def model_path(folder: Path, spec: tuple[int, str, float, str]) -> Path:
    """Where :func:`trained_models` caches the posture model of ``spec``."""
    components, covariance, ridge, views = spec
    return folder / (f"mixed_state_posture_model_k{components}_{covariance}_ridge{ridge:g}_"
                     f"{views}.npz")


def trained_models(folder: Path, specs) -> dict:
    """The posture model trained on the training clips for each spec of ``specs`` (see
    :func:`posture_model_spec`), cached in ``folder`` (the clips rendered once per set of
    views for all of them)."""
    from jaxtrack.experiments import mixed_state as ms
    from jaxtrack.priors.postures import load_posture_model, save_posture_model

    paths = {spec: model_path(folder, spec) for spec in specs}
    models = {spec: load_posture_model(path).model for spec, path in paths.items()
              if path.is_file()}
    missing = [spec for spec in specs if spec not in models]
    for views in dict.fromkeys(spec[3] for spec in missing):
        features, labels, rendering = ms.training_features(pose2sim_cameras=VIEWS[views])
        for spec in [spec for spec in missing if spec[3] == views]:
            components, covariance, ridge, _ = spec
            models[spec], description = ms.fit(features, labels, regularisation=ridge,
                                               components=components, covariance=covariance,
                                               **rendering)
            save_posture_model(paths[spec], models[spec], description=description)
    return {spec: models[spec] for spec in specs}


def labelled_features(sequences, num_bins: int):
    """The features and true postures of every frame with a silhouette, all sequences pooled."""
    from jaxtrack.experiments.mixed_state import labelled_features as of_sequence

    pairs = [of_sequence(sequence, num_bins) for sequence in sequences]
    return (np.concatenate([values for values, _ in pairs]),
            np.concatenate([names for _, names in pairs]))


def instantaneous_posture_error(model, features, labels) -> float:
    """The extended Ghost posture's error rate over ``labelled_features``' frames."""
    return float(np.mean(np.asarray(model.classify(features)) != labels))


def clip_intervals(sequences: dict, clips, kinds=KINDS, seed: int = 0,
                   resamples: int = 2000) -> dict:
    """95 % bootstrap intervals over clips (all views of a clip drawn together) of the
    frame-pooled MSE over all parts and the posture error, per estimate.

    Args:
        sequences: ``evaluate``'s ``"sequences"``: per rendered view (named
            ``<clip stem>_...``) a score per estimate, with its ``frames``.
        clips: the catalogue clips rendered.

    Returns:
        ``{kind: {"mse_all_95": [low, high], "posture_error_95": [low, high]}}``."""
    stems = [clip.split("/")[-1] for clip in clips]
    groups = {stem: [name for name in sequences if name.startswith(stem + "_")]
              for stem in stems}
    if any(not names for names in groups.values()):
        raise ValueError(f"no rendered view of clips {[s for s, n in groups.items() if not n]}")
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, len(stems), size=(resamples, len(stems)))
    out = {}
    for kind in kinds:
        sums = {"mse_all": np.zeros(len(stems)), "posture_error": np.zeros(len(stems))}
        counts = np.zeros(len(stems))
        for index, stem in enumerate(stems):
            for name in groups[stem]:
                scored = sequences[name][kind]
                if not scored["frames"]:
                    continue
                counts[index] += scored["frames"]
                sums["mse_all"][index] += scored["mse"]["all"] * scored["frames"]
                sums["posture_error"][index] += scored["posture_error"] * scored["frames"]
        out[kind] = {}
        for measure, values in sums.items():
            means = values[draws].sum(axis=1) / np.maximum(counts[draws].sum(axis=1), 1)
            out[kind][f"{measure}_95"] = [float(np.quantile(means, 0.025)),
                                          float(np.quantile(means, 0.975))]
    return out


CLASSIFIERS_CHOICE = (2, "pooled", 1.0, "level+pose2sim")
"""The posture model ``python -m papers.kwatra2002.posture_classifier`` chose by the instantaneous
posture error alone (2026-11-27): a default candidate here beside the library's."""


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=150, help="frames per clip (30 fps)")
    parser.add_argument("--particles", type=int, default=500)
    parser.add_argument("--posture-models", nargs="+", default=None, metavar="K,COV,RIDGE,VIEWS",
                        help="posture models to choose among, e.g. 1,per-posture,0.2,level or "
                             "2,pooled,1,level+pose2sim (default: the library's and the one "
                             "papers.kwatra2002.posture_classifier chose)")
    parser.add_argument("--redetect", type=float, nargs="+", default=[0.0, 0.02])
    parser.add_argument("--cutoff", type=float, nargs="+", default=[9.0, 25.0, 100.0],
                        help="the part likelihood's cutoffs delta to choose among")
    parser.add_argument("--switch", nargs="+", choices=("keep", "redraw"),
                        default=["keep", "redraw"],
                        help="what a particle that changes posture does with its parts")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--backward-paths", type=int, default=500,
                        help="paths of the two-pass smoother scored beside the others on the "
                             "test clips (0: not scored)")
    parser.add_argument("--azimuths", type=float, nargs="+", default=None, metavar="DEGREES",
                        help="views of the validation and test clips (default: the five of "
                        "experiments.mixed_state.VIEW_AZIMUTHS; 90 -90: the paper's side views)")
    parser.add_argument("--pose2sim-cameras", type=int, nargs="*", default=[], metavar="INDEX",
                        help="also score the test clips through these Pose2Sim cameras (0-3)")
    parser.add_argument("--skip-validation", action="store_true",
                        help="score the test clips with the one setting given (one value each "
                             "of --posture-models, --cutoff, --redetect and --switch), without "
                             "the validation clips: a held-out score with no setting chosen")
    parser.add_argument("--out", default=str(RESULTS / "mixed_state_evaluation.json"))
    args = parser.parse_args(argv)
    from jaxtrack.cli._common import UserError, pose2sim_cameras

    try:
        pose2sim_cameras(args.pose2sim_cameras, (), "--pose2sim-cameras")
    except UserError as error:
        parser.error(str(error))
    for name, values, low, high in (("--cutoff", args.cutoff, 0.0, None),
                                    ("--redetect", args.redetect, None, 1.0)):
        for value in values:
            if not np.isfinite(value) or (low is not None and value <= low) or (
                    high is not None and not 0.0 <= value <= high):
                bound = f"above {low:g}" if low is not None else f"in [0, {high:g}]"
                parser.error(f"{name} values must be finite and {bound}, got {value:g}")
    try:
        specs = (list(dict.fromkeys([default_spec(), CLASSIFIERS_CHOICE]))
                 if args.posture_models is None
                 else list(dict.fromkeys(posture_model_spec(text)
                                         for text in args.posture_models)))
    except ValueError as error:
        parser.error(f"--posture-models: {error}")
    if args.skip_validation and (len(specs) > 1 or len(args.cutoff) > 1
                                 or len(args.redetect) > 1 or len(args.switch) > 1):
        parser.error("--skip-validation scores one setting: give one value each of "
                     "--posture-models, --cutoff, --redetect and --switch")
    if args.backward_paths < 0:
        parser.error(f"--backward-paths must be 0 or more, got {args.backward_paths}")
    backward_paths = args.backward_paths or None
    for name in ("frames", "particles"):
        if getattr(args, name) < (2 if name == "frames" else 1):
            parser.error(f"--{name} must be at least {2 if name == 'frames' else 1}, got "
                         f"{getattr(args, name)}")
    from jaxtrack.experiments import mixed_state as ms

    begin = time.perf_counter()
    models = trained_models(Path(args.out).parent, specs)
    train_seconds = time.perf_counter() - begin
    azimuths = ms.VIEW_AZIMUTHS if args.azimuths is None else tuple(
        float(np.radians(value)) for value in args.azimuths)
    posture_errors, validation = {}, {}
    if args.skip_validation:
        spec, cutoff, chosen, chosen_switch = specs[0], args.cutoff[0], args.redetect[0], \
            args.switch[0]
    else:
        # the evaluation's own rendering of the validation clips, once for every setting
        sequences = ms.render_sequences(ms.VALIDATION_CLIPS, azimuths, ("clutter",), (640, 480),
                                        args.frames, args.seed)
        features, labels = labelled_features(sequences, num_bins=16)
        posture_errors = {spec: instantaneous_posture_error(model, features, labels)
                          for spec, model in models.items()}
        for spec, error in posture_errors.items():
            print(f"validation, posture model {spec_text(spec)}: instantaneous posture error "
                  f"{100 * error:.1f} %")
        validation = {}
        for spec, cutoff, switch, value in itertools.product(specs, args.cutoff, args.switch,
                                                             args.redetect):
            result = ms.evaluate(models[spec], ms.VALIDATION_CLIPS, azimuths=azimuths,
                                 backgrounds=("clutter",),
                                 num_particles=args.particles, max_frames=args.frames,
                                 seed=args.seed, redetect_probability=value,
                                 redraw_on_switch=switch == "redraw", part_cutoff=cutoff,
                                 sequences=sequences)
            validation[(spec, cutoff, value, switch)] = result["overall"]
            print(f"validation, posture model {spec_text(spec)}, cutoff {cutoff:g}, redetect "
                  f"{value:g}, {switch} on a switch: smoothed MSE all "
                  f"{result['overall']['smoothed']['mse']['all']:.1f}", flush=True)
        spec, cutoff, chosen, chosen_switch = min(
            validation, key=lambda key: validation[key]["smoothed"]["mse"]["all"])
    posture_model = models[spec]
    components, covariance, ridge, views = spec
    begin = time.perf_counter()
    test = ms.evaluate(posture_model, ms.TEST_CLIPS, azimuths=azimuths, backgrounds=("clutter",),
                       num_particles=args.particles, max_frames=args.frames, seed=args.seed,
                       redetect_probability=chosen,
                       redraw_on_switch=chosen_switch == "redraw", part_cutoff=cutoff,
                       backward_paths=backward_paths)
    test_seconds = time.perf_counter() - begin
    intervals = clip_intervals(test["sequences"], ms.TEST_CLIPS,
                               [kind for kind in (*KINDS, "backward") if kind in test["overall"]])
    through_cameras = None
    if args.pose2sim_cameras:
        through_cameras = ms.evaluate(posture_model, ms.TEST_CLIPS, azimuths=(),
                                      pose2sim_cameras=args.pose2sim_cameras,
                                      backgrounds=("clutter",), num_particles=args.particles,
                                      max_frames=args.frames, seed=args.seed,
                                      redetect_probability=chosen,
                                      redraw_on_switch=chosen_switch == "redraw",
                                      part_cutoff=cutoff, backward_paths=backward_paths)
    print(f"device: {device_description()}")
    if validation:
        print(f"validation clips {', '.join(ms.VALIDATION_CLIPS)}; instantaneous posture error "
              + ", ".join(f"{100 * error:.1f} % with {spec_text(key)}"
                          for key, error in posture_errors.items())
              + "; smoothed MSE all (px², 640 x 480) by posture model, part cutoff, re-detection "
                "and switch rule:")
        print_table([{"model": spec_text(key), "cutoff": delta, "redetect": value,
                      "switch": switch, "mse": scores["smoothed"]["mse"]["all"],
                      "instantaneous": scores["instantaneous"]["mse"]["all"],
                      "posture_error": 100 * scores["smoothed"]["posture_error"]}
                     for (key, delta, value, switch), scores in validation.items()],
                    [("model", "posture model", "s"), ("cutoff", "cutoff", "g"),
                     ("redetect", "redetect", "g"),
                     ("switch", "on a switch", "s"),
                     ("mse", "smoothed MSE all", ".1f"),
                     ("instantaneous", "instantaneous MSE all", ".1f"),
                     ("posture_error", "posture error %", ".1f")])
    print(f"\ntest clips {', '.join(ms.TEST_CLIPS)}, posture model {spec_text(spec)}, cutoff "
          f"{cutoff:g}, redetect {chosen:g}, {chosen_switch} on a switch, "
          f"{args.particles} particles, {args.frames} frames per clip, {len(azimuths)} views, "
          f"clutter; "
          f"{test_seconds:.0f} s")
    print_table(_rows(test["overall"]), _COLUMNS)
    print("95 % bootstrap intervals over the test clips (all views of a clip together): "
          + "; ".join(f"{kind} MSE all {low:.0f}-{high:.0f}, posture error "
                      f"{100 * values['posture_error_95'][0]:.1f}-"
                      f"{100 * values['posture_error_95'][1]:.1f} %"
                      for kind, values in intervals.items()
                      for low, high in [values["mse_all_95"]]))
    if backward_paths is not None:
        runs = test["sequences"].values()
        print(f"run time over the {len(runs)} test sequences: filter + ancestry tracing "
              f"{sum(run['seconds'] for run in runs):.1f} s, backward simulation "
              f"({backward_paths} paths) {sum(run['backward_seconds'] for run in runs):.1f} s")
    if through_cameras is not None:
        print(f"\nthe test clips through Pose2Sim cameras {args.pose2sim_cameras} (0-based; "
              f"363 x 640), the same settings")
        print_table(_rows(through_cameras["overall"]), _COLUMNS)
    write_json(args.out, {"benchmark": "mixed_state_evaluation", "device": device_description(),
                          "arguments": vars(args), "train_seconds": train_seconds,
                          "validation_posture_error": [
                              {"posture_model": spec_text(key),
                               "instantaneous_posture_error": error}
                              for key, error in posture_errors.items()],
                          "chosen_posture_model": spec_text(spec),
                          "chosen_posture_model_file": model_path(Path(args.out).parent,
                                                                  spec).name,
                          "chosen_regularisation": ridge, "chosen_components": components,
                          "chosen_covariance": covariance, "chosen_training_views": views,
                          "validation": [{"posture_model": spec_text(key),
                                          "part_cutoff": delta, "redetect_probability": value,
                                          "on_switch": switch, **scores}
                                         for (key, delta, value, switch), scores
                                         in validation.items()],
                          "chosen_part_cutoff": cutoff,
                          "chosen_redetect_probability": chosen,
                          "chosen_on_switch": chosen_switch, "test": test,
                          "test_intervals_over_clips": intervals,
                          "test_seconds": test_seconds,
                          "test_through_pose2sim_cameras": through_cameras})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
