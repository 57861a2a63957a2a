"""``jaxtrack train|evaluate --method linear-combination``: Ong & Gong's (2002) tracker.

- ``train``: real clips rendered through the Pose2Sim cameras (``--cameras``), hybrid vectors,
  global PCA, clusters and their transition matrix, saved as one ``.npz``
  (:func:`jaxtrack.experiments.linear_combination.train`).
- ``evaluate``: the model trained on training subjects (cached beside ``--json`` as
  ``lc_cache.npz``), the tracker and its two baselines on held-out subjects' clips, 3-D
  skeleton error (:func:`jaxtrack.experiments.linear_combination.evaluate`).

``track``: ``jaxtrack.cli._track_linear_combination``. Every argument is checked before any
work; a bad one raises :class:`UserError` (one line).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from jaxtrack.cli._common import (
    UserError,
    at_least,
    check_clips,
    check_held_out,
    check_json_and_plots,
    check_seed,
    finite_json,
    load_clip_sources,
    one_line,
    output_folder,
    outputs_or_nothing,
    pose2sim_cameras,
)

__all__ = ["CACHE_NAME", "evaluate", "frame_labels", "load_model", "train"]

CACHE_NAME = "lc_cache.npz"
"""The model ``evaluate`` trains is cached beside ``--json`` under this name."""

_NUM_CAMERAS = 4  # the Pose2Sim calibration the models are trained through
_PARTICLES, _ITERATIONS, _CLUSTERS = 300, 5, 20
_ZOOM = 2  # overlay panels are drawn at twice the tracking resolution
_MARKERS = ("head", "hand", "other_hand")
_OTHER_FILES = {"jaxtrack.gplvm": "a GPLVM pose prior (the latent tracker's)",
                "jaxtrack.postures": "a posture model (the mixed-state tracker's)",
                "jaxtrack.sequence": "a rendered sequence"}
"""Other jaxtrack files, by the format name in their metadata."""


def _max_frames(value) -> int | None:
    if value is not None and value < 2:
        raise UserError(f"--max-frames must be at least 2, got {value}")
    return value


def _cameras(cameras) -> tuple[int, ...]:
    return pose2sim_cameras(cameras, tuple(range(_NUM_CAMERAS)))


def _refuse_asf(args) -> None:
    if getattr(args, "asf", None) is not None:
        raise UserError("--asf is not used by --method linear-combination: give catalogue clips, "
                        ".bvh files, or .amc files with their .asf beside them")


def _training_clips(names, option: str) -> list:
    """Resolve clips to train on and refuse test subjects (``jaxtrack.data.splits``)."""
    from jaxtrack.data.splits import UnknownSubjectError, split_of, subject_of

    sources = check_clips(names, option)
    for name in names:
        try:
            split = split_of(name)
        except UnknownSubjectError:
            continue  # a user's own file: its subject is theirs to know
        if split == "test":
            raise UserError(f"{option} {name}: subject {subject_of(name)} is a test subject "
                            f"(jaxtrack.data.splits); train on training subjects")
    load_clip_sources(sources, option)
    return sources


def load_model(path: Path, what: str, remedy: str):
    """A linear-combination model file, or a one-line :class:`UserError`."""
    from jaxtrack.experiments import linear_combination as lc
    from jaxtrack.priors.linear_combinations import LinearCombinationFormatError

    if path.exists() and not path.is_file():
        raise UserError(f"{what} {path} is a folder, not a model file; {remedy}")
    if not path.is_file():
        raise UserError(f"{what} {path}: no such file; {remedy}")
    try:
        return lc.load(path)
    except (LinearCombinationFormatError, ValueError, OSError) as error:
        reason = one_line(error).removeprefix(f"{path}: ").removeprefix(f"{path}:")
        for kind, name in _OTHER_FILES.items():
            if f"'{kind}'" in reason:
                reason = f"{name}, not a linear-combination model"
        raise UserError(f"{what} {path}: {reason}; {remedy}") from None


# ----------------------------------------------------------------------------------- train


def train(args: argparse.Namespace) -> int:
    """``jaxtrack train --method linear-combination``."""
    from jaxtrack.experiments import linear_combination as lc

    started = time.perf_counter()
    _refuse_asf(args)
    names = list(lc.TRAIN_CLIPS if args.clips is None else args.clips)
    if args.out.suffix != ".npz":
        raise UserError(f"--out {args.out}: must be a .npz path")
    folder = output_folder(args.out, "--out")
    check_seed(args.seed)
    cameras = _cameras(args.cameras)
    clusters = at_least(args.clusters, 2, "--clusters", _CLUSTERS)
    max_frames = _max_frames(args.max_frames)
    if max_frames is not None and len(names) * len(cameras) * max_frames < clusters:
        raise UserError(f"--clusters {clusters}: more clusters than the at most "
                        f"{len(names) * len(cameras) * max_frames} training frames "
                        f"(--clips x --cameras x --max-frames)")
    if args.out.is_file():  # only a model of this kind is replaced
        load_model(args.out, "--out", "delete it or choose another --out")
    _training_clips(names, "--clips")
    with outputs_or_nothing(folder):
        try:
            trained = lc.train(names, views=cameras, num_clusters=clusters,
                               max_frames=max_frames, seed=args.seed, output=args.out)
        except ValueError as error:
            option = "--clusters" if "num_clusters" in str(error) else "--clips"
            raise UserError(f"{option}: {one_line(error)}") from None
    model, description = trained.model, trained.description
    print(f"linear-combination model: {description['frames']} hybrid vectors from "
          f"{len(names)} clip(s) x {len(cameras)} camera(s), {model.num_components} components "
          f"({description['explained_variance']:.0%} of the variance), {model.num_clusters} "
          f"clusters -> {args.out} ({time.perf_counter() - started:.0f} s)")
    return 0


# -------------------------------------------------------------------------------- evaluate


def _cached_model(cache: Path, clips: list[str], cameras: tuple[int, ...], seed: int):
    """The model cached beside ``--json`` if it was trained on these clips, cameras and seed
    (its clusters and frames are its own: ``jaxtrack train --out`` may have made it); None
    when there is none or it was trained on other data. A damaged cache is refused."""
    if not cache.exists():
        return None
    trained = load_model(cache, "the model cached beside --json:",
                    "delete it (it is retrained) or write --json elsewhere")
    description = trained.description
    same = (list(description.get("clips", [])) == list(clips)
            and list(description.get("views", [])) == list(cameras)
            and description.get("seed") == seed)
    return trained if same else None


def evaluate(args: argparse.Namespace) -> int:
    """``jaxtrack evaluate --method linear-combination``."""
    from jaxtrack._files import write_json_atomically
    from jaxtrack.data.splits import check_disjoint
    from jaxtrack.evaluation import skeleton_error_table, summarise_skeleton_errors
    from jaxtrack.experiments import linear_combination as lc

    started = time.perf_counter()
    _refuse_asf(args)
    if args.allow_same_subject:
        raise UserError("--allow-same-subject is not available with --method "
                        "linear-combination: it scores held-out subjects only")
    train_clips = list(lc.TRAIN_CLIPS if args.train is None else args.train)
    test_clips = list(lc.TEST_CLIPS if args.test is None else args.test)
    train_sources = _training_clips(train_clips, "--train")
    test_sources = check_clips(test_clips, "--test")
    check_held_out(train_sources, test_sources)
    try:
        check_disjoint(train_clips, test_clips)
    except ValueError as error:
        raise UserError(f"--test: {one_line(error)}") from None
    particles = at_least(args.particles, 1, "--particles", _PARTICLES)
    iterations = at_least(args.iterations, 1, "--iterations", _ITERATIONS)
    max_frames = _max_frames(args.max_frames)
    check_seed(args.seed)
    cameras = _cameras(args.cameras)
    folder = check_json_and_plots(args)
    cache = folder / CACHE_NAME
    trained = _cached_model(cache, train_clips, cameras, args.seed)
    load_clip_sources(test_sources, "--test")
    folders = (folder,) if args.plots is None else (folder, args.plots)
    with outputs_or_nothing(*folders) as written:
        if trained is None:
            print(f"training on {len(train_clips)} clip(s) through camera(s) "
                  f"{' '.join(map(str, cameras))} -> {cache}", flush=True)
            trained = lc.train(train_clips, views=cameras, num_clusters=_CLUSTERS,
                               seed=args.seed, output=cache)
        else:
            print(f"reusing {cache} ({trained.model.num_clusters} clusters, "
                  f"{len(trained.vectors)} training vectors)", flush=True)
        results = lc.evaluate(trained, test_clips, views=cameras, particles=particles,
                              iterations=iterations, max_frames=max_frames, seed=args.seed)
        if args.plots is not None:
            _evaluation_plots(args.plots, written, results, trained, test_clips[0], cameras[0],
                              particles, iterations, max_frames, args.seed)
        summary = summarise_skeleton_errors(results)
        write_json_atomically(args.json, {
            "method": "linear-combination", "device": _device(), "train": train_clips,
            "test": test_clips,
            "cameras": list(cameras), "particles": particles, "iterations": iterations,
            "max_frames": max_frames, "seed": args.seed, "model_cache": str(cache),
            "skeleton_estimate": results["skeleton_estimate"],
            "summary": summary, "results": finite_json(results),
            "seconds": round(time.perf_counter() - started, 2)})
    print(skeleton_error_table(summary))
    print(f"{len(test_clips)} test clip(s) x {len(cameras)} camera(s), {particles} particles x "
          f"{iterations} iterations, the filters' {lc.DEFAULT_SKELETON_ESTIMATE} skeleton "
          f"(jaxtrack track's), on {_device()}; wrote {args.json} "
          f"({time.perf_counter() - started:.0f} s)")
    return 0


def _device() -> str:
    import jax

    device = jax.devices()[0]
    return f"{device.platform} ({device.device_kind})"


def _evaluation_plots(folder: Path, written: list, results: dict, trained, clip: str,
                      camera: int, particles: int, iterations: int, max_frames, seed: int
                      ) -> None:
    """Per sequence the 3-D error per frame of each method (PNG), and the tracker's estimate
    over one sequence (the first test clip through the first camera, as evaluated); each file
    is added to ``written`` once written."""
    import jax.random as jr

    from jaxtrack.evaluation import plot_errors_over_time
    from jaxtrack.experiments import linear_combination as lc
    from jaxtrack.trackers import Engine
    from jaxtrack.trackers.linear_combination import linear_combination_tracker, track_observations
    from jaxtrack.vision import write_views_video

    fps = float(trained.description.get("fps", 30.0))
    for name, entry in results["sequences"].items():
        errors_mm = {method: 1e3 * np.asarray(entry[method]["errors_m"])
                     for method in results["methods"]}
        written.append(plot_errors_over_time(errors_mm, folder / f"{name}_errors.png",
                                             title=name, fps=fps, failure_threshold=None,
                                             ylabel="3-D skeleton error (mm)"))
    # the same render and tracker settings as lc.evaluate: the overlay shows what was scored
    sequence = lc.render_hybrid_sequences(
        clip, views=(camera,), num_contour=trained.model.layout.num_contour, fps=fps,
        max_frames=max_frames, seed=seed + 7, keep_observations=True, keep_images=True)[0]
    tracker = linear_combination_tracker(trained.model, engine=Engine(particles),
                                         iterations=iterations)
    estimates = track_observations(tracker, jr.PRNGKey(seed), sequence.observations).estimates
    written.append(write_views_video(
        [sequence.images], [estimates.contour], [estimates.best_markers],
        folder / f"{sequence.name}_linear-combination.mp4", fps=fps,
        names=["linear-combination"], marker_names=_MARKERS,
        labels=[frame_labels(sequence.status)], zoom=_ZOOM))


# ----------------------------------------------------------------------------------- track


def frame_labels(status: list[str]) -> list[str]:
    """Per frame ``"3/40 no skin blobs"``: the frame's number and why it was not observed
    (the first words of its status)."""
    return [f"{t + 1}/{len(status)} {text.split(':')[0].split('(')[0].strip()}".strip()
            for t, text in enumerate(status)]
