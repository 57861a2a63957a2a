"""``jaxtrack track --method mixed-state``: Kwatra, Bobick & Johnson's mixed-state tracker
over one video: silhouettes by background subtraction against the video's median background
(or ``--masks``), filter and whole-sequence smoother, then ``DIR/overlay.mp4`` and
``DIR/track.json`` (the JSON last). A bad argument is a one-line :class:`UserError`, raised
before anything is computed or written.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

from jaxtrack.cli._common import (
    UserError,
    at_least,
    check_memory,
    check_seed,
    finite_json,
    fit_mask_file,
    one_line,
    output_directory,
    outputs_or_nothing,
    read_mask_files,
)
from jaxtrack.cli._mixed_state import (
    BASE_BYTES,
    DEFAULT_PARTICLES,
    HISTORY_BYTES,
    PIXEL_BYTES,
    refuse_other_methods,
)
from jaxtrack.cli._train_mixed_state import (
    write_json,
)

__all__ = ["track"]


def _load_model(path: Path):
    """The posture model of ``--model``; anything else is a one-line error naming it."""
    from jaxtrack.priors.postures import PostureFormatError, load_posture_model

    needed = "--method mixed-state needs a posture model from jaxtrack train --method mixed-state"
    if not path.exists():
        raise UserError(f"--model {path}: no such file")
    if not path.is_file():
        raise UserError(f"--model {path}: a folder, not a model file")
    try:
        saved = load_posture_model(path)
    except (PostureFormatError, OSError) as error:
        reason = one_line(error).removeprefix(f"{path}: ").removeprefix(f"{path}:")
        if "'jaxtrack.gplvm'" in reason:
            reason = "a GPLVM pose prior (for --method latent), not a posture model"
        raise UserError(f"--model {path}: {reason}; {needed}") from None
    features = saved.model.num_features
    if features < 3 or features % 2 == 0:
        raise UserError(f"--model {path}: {features} silhouette features, not 2 x bins + 1; "
                        f"{needed}")
    return saved


def _compiled(key, model, observations, particles: int):
    """Filter and smoother compiled ahead of time, so that compilation is timed apart."""
    import jax

    from jaxtrack.trackers.mixed_state import filter_sequence, smooth

    def run_filter(key, model, observations):
        return filter_sequence(key, model, observations, particles)

    filter_jit = jax.jit(run_filter)
    compiled_filter = filter_jit.lower(key, model, observations).compile()
    shapes = jax.eval_shape(run_filter, key, model, observations)
    compiled_smooth = jax.jit(smooth).lower(shapes).compile()
    return compiled_filter, compiled_smooth


def track(args: argparse.Namespace) -> int:
    """``jaxtrack track --method mixed-state``: posture and parts through one video."""
    from jaxtrack.cli._track_image import frame_range, options_record

    started = time.perf_counter()
    record_options = options_record(args)
    refuse_other_methods(args, "track")
    if len(args.video) != 1:
        raise UserError(f"--video: --method mixed-state tracks one video, got "
                        f"{len(args.video)}")
    video_path = args.video[0]
    given_masks = read_mask_files(args.masks, 1)[0]
    masks_path = None if args.masks is None else args.masks[0]
    particles = at_least(args.particles, 1, "--particles", DEFAULT_PARTICLES)
    check_seed(args.seed)
    if args.max_size < 32:
        raise UserError(f"--max-size must be at least 32, got {args.max_size}")
    output_directory(args.out, "--out")  # probed before any frame is read
    start, stop = frame_range(args.frames)
    saved = _load_model(args.model)
    if not video_path.exists():
        raise UserError(f"--video {video_path}: no such video file")

    import jax
    import jax.random as jr
    import numpy as np

    from jaxtrack.cli._status import LOST_RULE, frame_statuses, status_counts, status_legend
    from jaxtrack.priors.postures import POSTURE_NAMES
    from jaxtrack.trackers.mixed_state import (
        MixedStateModel,
        instantaneous_estimates,
        observations_from_silhouettes,
    )
    from jaxtrack.vision import VideoError, median_background, read_video
    from jaxtrack.vision.foreground import largest_component
    from jaxtrack.vision.histograms import FRAME_OK, STATUS_NAMES, silhouettes
    from jaxtrack.vision.overlay import write_overlay_video_from_file
    from jaxtrack.vision.parts import PART_NAMES

    try:
        probe = read_video(video_path, start=start, max_frames=1)
        height, width = probe.frames.shape[1:3]
        scale = min(1.0, args.max_size / max(height, width))
        video = read_video(video_path, start=start,
                           max_frames=None if stop is None else stop - start, scale=scale)
    except VideoError as error:
        raise UserError(f"--video: {one_line(error)}") from None
    frames = video.frames
    num_frames, tracked_height, tracked_width = frames.shape[:3]
    scale = tracked_width / width  # the decoder rounds the size
    if num_frames < 3:
        raise UserError(f"--video {video_path}: {num_frames} frame(s) from frame {start}; the "
                        f"median background and tracking need at least 3")
    check_memory(int(BASE_BYTES + num_frames * (particles * HISTORY_BYTES + tracked_width
                                                 * tracked_height * PIXEL_BYTES)),
                 f"tracking {num_frames} frames of {tracked_width}x{tracked_height} with "
                 f"{particles} particles", "--particles/--max-size/--frames")
    fps = video.fps if math.isfinite(video.fps) else None
    decoded = time.perf_counter()
    print(f"{video_path}: {num_frames} frames {width}x{height}"
          + (f" at {fps:.0f} fps" if fps else "") + f", tracked at {tracked_width}x"
          f"{tracked_height}")

    if given_masks is None:
        masks = silhouettes(frames, median_background(frames))
    else:  # the person's largest blob, as silhouettes() keeps it
        masks = fit_mask_file(given_masks, masks_path, video.frame_indices,
                              (tracked_width, tracked_height))
        masks = np.stack([largest_component(mask) for mask in masks])
    num_bins = (saved.model.num_features - 1) // 2
    observations = observations_from_silhouettes(masks, num_bins=num_bins)
    status = np.asarray(observations.status)
    if not np.any(status == FRAME_OK):
        source = (f"in --masks {masks_path}" if masks_path is not None else "against the "
                  "video's median background (a static camera and a person who moves are "
                  "needed)")
        raise UserError(f"--video {video_path}: no frame has a silhouette {source}; nothing "
                        f"written")
    observed = time.perf_counter()

    model = MixedStateModel(saved.model)
    key = jr.PRNGKey(args.seed)
    compile_begin = time.perf_counter()
    compiled_filter, compiled_smooth = _compiled(key, model, observations, particles)
    compile_seconds = time.perf_counter() - compile_begin
    run_begin = time.perf_counter()
    result = compiled_filter(key, model, observations)
    smoothed = jax.block_until_ready(compiled_smooth(result))
    run_seconds = time.perf_counter() - run_begin
    instant_posture, instant_parts = instantaneous_estimates(model, observations)
    estimates = {
        "instantaneous": (np.asarray(instant_posture), np.asarray(instant_parts), None),
        "filtered": (np.asarray(result.filtered_posture), np.asarray(result.filtered_parts),
                     np.asarray(result.filtered_posture_probabilities)),
        "smoothed": (np.asarray(smoothed.posture), np.asarray(smoothed.parts),
                     np.asarray(smoothed.posture_probabilities)),
    }
    ess = np.asarray(result.ess)
    arrays = [array for values in estimates.values() for array in values if array is not None]
    if not all(np.all(np.isfinite(array)) for array in [*arrays, ess]):
        raise UserError("tracking produced non-finite values; nothing written")

    ok = status == FRAME_OK
    smoothed_posture, smoothed_parts, _ = estimates["smoothed"]
    statuses = frame_statuses(smoothed_parts, (tracked_width, tracked_height),
                              degenerate=~(ess > 0), no_person=~ok)

    def named(points) -> dict:
        return {name: [round(float(x) / scale, 2), round(float(y) / scale, 2)]
                for name, (x, y) in zip(PART_NAMES, points, strict=True)}

    per_frame = []
    for t, index in enumerate(video.frame_indices):
        entry = {"frame": int(index),
                 "time_s": float(index / video.source_fps)
                 if math.isfinite(video.source_fps) else None,
                 "status": statuses[t].value, "silhouette": STATUS_NAMES[int(status[t])],
                 "ess": round(float(ess[t]), 2),
                 "posture": {}, "posture_probability": {}, "parts": {}}
        for kind, (posture, parts, probabilities) in estimates.items():
            # the instantaneous estimate reads the frame's silhouette alone: none without one
            known = kind != "instantaneous" or ok[t]
            entry["posture"][kind] = POSTURE_NAMES[int(posture[t])] if known else None
            entry["parts"][kind] = named(parts[t]) if known else None
            if probabilities is not None:
                entry["posture_probability"][kind] = round(
                    float(probabilities[t, int(posture[t])]), 4)
        per_frame.append(entry)

    overlay_path = args.out / "overlay.mp4"
    tracked = int(ok.sum())
    counts = status_counts(statuses)
    record = {
        "method": "mixed-state", "options": record_options, "video": str(video_path),
        "model": str(args.model), "statuses": status_legend(), "lost_rule": LOST_RULE,
        "status_counts": counts,
        "size": [width, height], "tracked_size": [tracked_width, tracked_height], "fps": fps,
        "silhouettes": ("median background" if masks_path is None
                        else f"masks {masks_path}"),
        "particles": particles, "seed": args.seed, "num_bins": num_bins,
        "tracker": model.options(),
        "posture_names": list(POSTURE_NAMES), "part_names": list(PART_NAMES),
        "posture_model": saved.description,
        "frames_with_silhouette": tracked,
        "seconds": {"decode": decoded - started, "silhouettes": observed - decoded,
                    "compile": compile_seconds, "filter_and_smooth": run_seconds,
                    "per_frame": run_seconds / num_frames,
                    "total": time.perf_counter() - started},
        "frames": per_frame,
    }
    with outputs_or_nothing(args.out) as written:  # all or nothing, Ctrl-C included
        try:  # the smoothed parts, labelled with the smoothed posture, at the video's own size
            overlay = write_overlay_video_from_file(
                video_path, video.frame_indices, {"smoothed": smoothed_parts / scale},
                overlay_path, fps=fps or 30.0, marker_names=PART_NAMES,
                labels=[f"{POSTURE_NAMES[int(posture)].replace('_', ' ')}  {t + 1}/"
                        f"{num_frames} {statuses[t].value}"
                        for t, posture in enumerate(smoothed_posture)])
        except (OSError, VideoError) as error:
            raise UserError(f"cannot write {overlay_path}: {one_line(error)}") from None
        written.append(overlay)
        json_path = write_json(args.out / "track.json", finite_json(record))
        written.append(json_path)
    counts = np.bincount(estimates["smoothed"][0], minlength=len(POSTURE_NAMES))
    shown = ", ".join(f"{name} {count}" for name, count in zip(POSTURE_NAMES, counts,
                                                               strict=True) if count)
    print(f"tracked {num_frames} frames ({tracked} with a silhouette): "
          f"{1e3 * run_seconds / num_frames:.2f} ms/frame (compile {compile_seconds:.1f} s); "
          f"smoothed postures: {shown}; total {time.perf_counter() - started:.1f} s")
    print(f"  wrote {overlay}\n  wrote {json_path}")
    return 0
