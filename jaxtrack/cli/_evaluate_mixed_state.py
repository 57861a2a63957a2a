"""``jaxtrack evaluate --method mixed-state``: trains (cached beside ``--json`` as
``posture_cache.npz``), renders the test clips, filters, smooths and scores them
(:func:`jaxtrack.experiments.mixed_state.evaluate`): the paper's Table 1 on stdout, its Fig. 2/4
and the smoothed posture confusion with ``--plots``. A bad argument is a one-line
:class:`UserError`, raised before anything is computed or written.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from jaxtrack.cli._common import (
    at_least,
    check_clips,
    check_held_out,
    check_json_and_plots,
    check_memory,
    check_seed,
    finite_json,
    pose2sim_cameras,
)
from jaxtrack.cli._mixed_state import (
    BASE_BYTES,
    CACHE_NAME,
    DEFAULT_BINS,
    DEFAULT_LAG,
    DEFAULT_PARTICLES,
    HISTORY_BYTES,
    PIXEL_BYTES,
    refuse_other_methods,
)
from jaxtrack.cli._train_mixed_state import (
    azimuth_radians,
    check_clip_files,
    fit_posture_model,
    matches,
    model_summary,
    parse_image_size,
    read_saved_model,
    refuse_test_subjects,
    training_settings,
    write_json,
)

__all__ = ["evaluate"]


def _plots(folder: Path, overall: dict, confusion, lag: int, title: str, frames: int
           ) -> list[Path]:
    """Fig. 2/4 (the fraction of frames within ε pixels per part, one curve per estimate) and
    the smoothed posture's confusion matrix, in ``folder``."""
    from jaxtrack.evaluation import (
        MIXED_STATE_ESTIMATES,
        MIXED_STATE_PARTS,
        mixed_state_label,
        plot_confusion,
        plot_fraction_within_per_part,
    )

    folder.mkdir(parents=True, exist_ok=True)
    curves = {mixed_state_label(kind, lag): overall[kind]["within"]
              for kind in MIXED_STATE_ESTIMATES}
    names = [name.replace("_", " ") for name in _posture_names()]
    return [plot_fraction_within_per_part(curves, folder / "fraction_within.png",
                                          parts=MIXED_STATE_PARTS, title=title),
            plot_confusion(confusion, names, folder / "posture_confusion.png",
                           xlabel="smoothed estimate", ylabel="true posture",
                           colour_label="fraction of the true posture's frames",
                           title=f"smoothed posture, {frames} frames")]


def evaluate(args: argparse.Namespace) -> int:
    """``jaxtrack evaluate --method mixed-state``: Table 1 on the held-out clips."""
    from jaxtrack.experiments.mixed_state import TEST_CLIPS, TRAINING_CLIPS

    started = time.perf_counter()
    refuse_other_methods(args, "evaluate")
    train_clips = list(TRAINING_CLIPS) if args.train is None else list(args.train)
    test_clips = list(TEST_CLIPS) if args.test is None else list(args.test)
    # the arguments first, then the clips they name (found in the data folders)
    particles = at_least(args.particles, 1, "--particles", DEFAULT_PARTICLES)
    check_seed(args.seed)
    max_frames = at_least(args.max_frames, 2, "--max-frames", None)
    train_max_frames = at_least(args.train_max_frames, 2, "--train-max-frames", None)
    lag = at_least(args.lag, 0, "--lag", DEFAULT_LAG)
    bins = at_least(args.bins, 1, "--bins", DEFAULT_BINS)
    azimuths = azimuth_radians(args.azimuths)
    cameras = pose2sim_cameras(args.cameras, ())
    size = parse_image_size(args.size)
    train_sources = check_clips(train_clips, "--train")
    test_sources = check_clips(test_clips, "--test")
    check_held_out(train_sources, test_sources)
    refuse_test_subjects(train_clips, train_sources, "--train")
    backgrounds = list(dict.fromkeys(args.backgrounds))
    folder = check_json_and_plots(args)
    cache = folder / CACHE_NAME
    saved = read_saved_model(cache, "the posture model cached beside --json:",
                              "delete it (it is retrained and rewritten) or write --json "
                              "elsewhere")
    frames_bound = max_frames or 300  # the default clips have at most 192 frames at 30 fps
    check_memory(int(BASE_BYTES + frames_bound * (particles * HISTORY_BYTES
                                                   + size[0] * size[1] * PIXEL_BYTES)),
                 f"tracking {size[0]}x{size[1]} sequences with {particles} particles",
                 "--particles/--size")
    check_clip_files(train_sources + test_sources, "--train/--test")
    settings = training_settings(train_clips, train_sources, azimuths, size, bins,
                                  train_max_frames, args.seed)
    # every argument checked: only now is anything computed or written
    from jaxtrack.evaluation import mixed_state_table
    from jaxtrack.experiments.mixed_state import evaluate as evaluate_model
    from jaxtrack.priors.postures import save_posture_model

    if saved is not None and matches(saved.description, settings):
        model, description = saved.model, saved.description
        print(f"{model_summary(description)}: reused {cache}")
    else:
        model, description = fit_posture_model(settings, "--train", "--train-max-frames")
        folder.mkdir(parents=True, exist_ok=True)
        save_posture_model(cache, model, description=description)
        print(f"{model_summary(description)} -> {cache} ({description['seconds']:.1f} s)")
    begin = time.perf_counter()
    results = evaluate_model(model, test_clips, azimuths=azimuths, backgrounds=backgrounds,
                             image_size=size, num_bins=bins, num_particles=particles, lag=lag,
                             max_frames=max_frames, seed=args.seed, pose2sim_cameras=cameras)
    evaluate_seconds = time.perf_counter() - begin
    overall = finite_json(results["overall"])
    frames = overall["smoothed"]["frames"]
    sizes = ([f"{size[0]}x{size[1]}"] if azimuths else []) + (
        [f"{len(cameras)} Pose2Sim camera(s) at a third of 1088x1920"] if cameras else [])
    title = (f"mixed-state, {len(results['sequences'])} sequences, {frames} frames at "
             f"{' and '.join(sizes)}, N={particles}")
    plots = []
    if args.plots is not None:
        plots = _plots(args.plots, overall, results["smoothed_confusion"], lag, title, frames)
    record = finite_json({
        "method": "mixed-state", "train": train_clips, "test": test_clips,
        "particles": particles, "lag": lag, "seed": args.seed, "max_frames": max_frames,
        "pose2sim_cameras": list(cameras),
        "posture_model": description, "posture_names": _posture_names(),
        "overall": results["overall"], "sequences": results["sequences"],
        "smoothed_confusion": results["smoothed_confusion"], "settings": results["settings"],
        "seconds": {"evaluate": evaluate_seconds, "total": time.perf_counter() - started}})
    json_path = write_json(args.json, record)
    print(f"{title}; MSE in px² at each sequence's size")
    print(mixed_state_table(overall, lag))
    for path in (*plots, json_path):
        print(f"wrote {path}")
    return 0


def _posture_names() -> list[str]:
    from jaxtrack.priors.postures import POSTURE_NAMES

    return list(POSTURE_NAMES)




# --- track ------------------------------------------------------------------------------------
