"""``jaxtrack track --method linear-combination``: Ong & Gong's (2002) tracker over one or
several calibrated videos.

One video per calibrated camera. Each is decoded at the scale the model was
trained at (the calibrated image scaled by ``CAMERA_SCALE``), at the model's frame rate, and
cut to ``CROP_SIZE`` around the subject; its empty scene is the video's median (a static
camera); skin is the fixed chroma box or ``--skin``. The 3-D skeleton reported is the
particles' weighted mean (``--skeleton mean``, chosen on validation) or the best particle's
(``--skeleton best``, the paper's). With several views, each frame is read from the view of
least ambiguity over ±5 frames (chosen on validation with the weighted mean), of greatest
fitness over ±5 frames (``--view-selection fitness``), or of greatest fitness × 1/ambiguity
(``--view-selection paper``, §5.5–5.7). Writes
``overlay.mp4`` and, last, ``track.json``. The model fixes the tracking scale, so
``--max-size`` and the latent tracker's options are not used. Why these choices:
``docs/linear-combination.md``.

Every argument is checked before any work; a bad one raises :class:`UserError` (one line).
The record: :func:`jaxtrack.experiments.linear_combination.track_record`.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from jaxtrack.cli._common import (
    UserError,
    at_least,
    check_seed,
    finite_json,
    fit_mask_file,
    one_line,
    output_directory,
    outputs_or_nothing,
    read_mask_files,
)
from jaxtrack.cli._train_linear_combination import frame_labels, load_model

__all__ = ["track"]

_PARTICLES, _ITERATIONS = 300, 5
_ZOOM = 2  # overlay panels are drawn at twice the tracking resolution
_MARKERS = ("head", "hand", "other_hand")


def _skin(text: str | None):
    if text is None:
        return None
    try:
        values = [int(value) for value in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3 or not all(0 <= value <= 255 for value in values):
        raise UserError(f"--skin must be R,G,B (three numbers 0-255), got {text!r}")
    return tuple(values)


def _calibrated_cameras(args, count: int) -> list | None:
    """The cameras of ``--calibration`` (those of ``--cameras``), one per video, or None."""
    from jaxtrack.body import read_qca

    if args.calibration is None:
        if args.cameras is not None:
            raise UserError("--cameras picks cameras of --calibration; give --calibration")
        return None
    if not args.calibration.is_file():
        raise UserError(f"--calibration {args.calibration}: no such file")
    try:
        cameras = read_qca(args.calibration, world_up="y")
    except (ValueError, OSError, KeyError) as error:
        raise UserError(f"--calibration {args.calibration}: "
                        f"{one_line(error).removeprefix(str(args.calibration))}") from None
    chosen = list(range(len(cameras))) if args.cameras is None else list(args.cameras)
    bad = [index for index in chosen if not 0 <= index < len(cameras)]
    if bad or len(set(chosen)) != len(chosen):
        raise UserError(f"--cameras must be distinct indices 0-{len(cameras) - 1} of the "
                        f"{len(cameras)} cameras of --calibration, got "
                        f"{' '.join(map(str, args.cameras))}")
    if len(chosen) != count:
        raise UserError(f"--video: {count} video(s) but {len(chosen)} camera(s) "
                        f"({', '.join(cameras[i].name for i in chosen)}) of --calibration "
                        f"{args.calibration}; give one video per camera, in order (or pick "
                        f"the cameras with --cameras)")
    return [cameras[index] for index in chosen]


def _probe_videos(args, cameras, start: int) -> list[tuple[float, tuple[int, int], float]]:
    """Per video (checked on its first frame): the factor that brings it to the model's
    training scale (its calibrated camera's image scaled by ``CAMERA_SCALE``; without a
    calibration the video must already be a ``CROP_SIZE`` clip at that scale), its size
    ``(width, height)`` and its frame rate."""
    from jaxtrack.experiments.linear_combination import CAMERA_SCALE, CROP_SIZE
    from jaxtrack.vision import VideoError, read_video

    probes = []
    for index, path in enumerate(args.video):
        try:
            probe = read_video(path, start=start, max_frames=1)
        except VideoError as error:
            raise UserError(f"--video: {one_line(error)}") from None
        height, width = probe.frames.shape[1:3]
        size, fps = (width, height), probe.source_fps
        if cameras is None:
            if (width, height) != tuple(CROP_SIZE):
                raise UserError(
                    f"--calibration is required for --video {path} ({width}x{height}): the "
                    f"model was trained on calibrated cameras scaled by {CAMERA_SCALE:.3g} and "
                    f"cut to {CROP_SIZE[0]}x{CROP_SIZE[1]}; without a calibration a video must "
                    f"already be such a {CROP_SIZE[0]}x{CROP_SIZE[1]} clip")
            probes.append((1.0, size, fps))
            continue
        camera_width, camera_height = cameras[index].image_size
        if abs(width / height - camera_width / camera_height) > 0.02 * camera_width / camera_height:
            raise UserError(f"--video {path} is {width}x{height} but camera "
                            f"{cameras[index].name} of --calibration is {camera_width}x"
                            f"{camera_height} (another shape): give the videos in the order of "
                            f"the calibration's cameras")
        probes.append((CAMERA_SCALE * max(camera_width, camera_height) / max(width, height),
                       size, fps))
    return probes


def track(args: argparse.Namespace) -> int:
    """``jaxtrack track --method linear-combination``."""
    import jax.random as jr

    from jaxtrack.cli._track_image import frame_range, options_record
    from jaxtrack.experiments import linear_combination as lc
    from jaxtrack.trackers import Engine
    from jaxtrack.trackers.linear_combination import linear_combination_tracker, track_observations
    from jaxtrack.vision import VideoError, read_video, write_views_video

    started = time.perf_counter()
    record_options = options_record(args)
    particles = at_least(args.particles, 1, "--particles", _PARTICLES)
    iterations = at_least(args.iterations, 1, "--iterations", _ITERATIONS)
    check_seed(args.seed)
    if args.init != "face":
        raise UserError("--init is not used by --method linear-combination (it starts from the "
                        "model's clusters)")
    for name in ("coverage_weight", "keypoints", "keypoint_weight"):  # refused, not ignored
        if getattr(args, name, None) is not None:
            raise UserError(f"--{name.replace('_', '-')} does not apply to --method "
                            f"linear-combination (it is the latent tracker's likelihood's)")
    skin = _skin(args.skin)
    start, stop = frame_range(args.frames)
    output_directory(args.out, "--out")  # probed before any frame is read
    for path in args.video:
        if not path.is_file():
            raise UserError(f"--video {path}: no such file")
    given_masks = read_mask_files(args.masks, len(args.video))
    trained = load_model(args.model, "--model", "make one with jaxtrack train --method "
                    "linear-combination")
    joints = trained.description.get("skeleton", [])
    if len(joints) != trained.model.layout.num_skeleton:
        raise UserError(f"--model {args.model}: its description names {len(joints)} skeleton "
                        f"joints for {trained.model.layout.num_skeleton} vertices; make one with "
                        f"jaxtrack train --method linear-combination")
    cameras = _calibrated_cameras(args, len(args.video))
    probes = _probe_videos(args, cameras, start)
    fps_model = float(trained.description.get("fps", 30.0))

    # every argument checked: decode (at the model's scale and frame rate), observe, track
    tick = time.perf_counter()
    videos, strides = [], []
    for path, (scale, _, fps) in zip(args.video, probes, strict=True):
        strides.append(max(1, round(fps / fps_model)) if math.isfinite(fps) else 1)
        try:
            videos.append(read_video(path, start=start, stride=strides[-1], scale=scale,
                                     max_frames=None if stop is None else
                                     -(-(stop - start) // strides[-1])))
        except VideoError as error:
            raise UserError(f"--video: {one_line(error)}") from None
    count = min(video.num_frames for video in videos)
    if count < 3:
        raise UserError(f"--video: {count} frame(s) to track; the median background needs at "
                        f"least 3")
    decode_seconds = time.perf_counter() - tick
    tick = time.perf_counter()
    views = []
    for index, video in enumerate(videos):
        frames = video.frames[:count]
        masks = None
        if given_masks[index] is not None:
            masks = fit_mask_file(given_masks[index], args.masks[index],
                                  video.frame_indices[:count], video.image_size)
        frames, background, masks, origin, people = lc.video_view(frames, masks,
                                                                  cameras is not None)
        observations, status = lc.observe(frames, background, skin_reference=skin, masks=masks)
        height, width = video.frames.shape[1:3]
        size = probes[index][1]
        views.append({"frames": frames, "observations": observations, "status": status,
                      "origin": origin, "people": people, "video": video,
                      "stride": strides[index], "size": size,
                      # per axis: the decoder rounds the scaled size
                      "scale": np.array([width / size[0], height / size[1]]),
                      "name": cameras[index].name if cameras else f"view{index}"})
    observe_seconds = time.perf_counter() - tick
    tracker = linear_combination_tracker(trained.model, engine=Engine(particles),
                                         iterations=iterations)
    for view in views:
        # the same key for every view: views differ by what they see, not by their noise
        view["run"] = track_observations(tracker, jr.PRNGKey(args.seed), view["observations"])
    tick = time.perf_counter()
    chosen, ambiguity = lc.select_tracked_views(trained,
                                                [view["run"].estimates for view in views],
                                                selection=_view_selection(args))
    selection_seconds = time.perf_counter() - tick
    skeletons = [_skeletons(view["run"].estimates, args) for view in views]
    for view, skeleton in zip(views, skeletons, strict=True):
        if not (np.all(np.isfinite(skeleton))
                and np.all(np.isfinite(view["run"].estimates.log_fitness))):
            raise UserError(f"tracking --video {view['video'].path} produced non-finite "
                            f"skeletons; nothing written")
    record = lc.track_record(
        trained, cameras, views, skeletons, chosen, ambiguity, tracker, model=str(args.model),
        calibration=None if args.calibration is None else str(args.calibration),
        masks=args.masks, skin=skin, seed=args.seed, view_selection=_view_selection(args),
        skeleton_estimate=_skeleton_estimate(args))
    record["options"] = record_options
    with outputs_or_nothing(args.out) as written:
        fps = videos[0].fps if math.isfinite(videos[0].fps) else fps_model
        try:  # with several views: ambiguity bars, the selected view framed (Fig. 17)
            written.append(write_views_video(
                [view["frames"] for view in views],
                [view["run"].estimates.contour for view in views],
                [view["run"].estimates.best_markers for view in views],
                args.out / "overlay.mp4", fps=fps, names=[view["name"] for view in views],
                marker_names=_MARKERS, labels=[frame_labels(view["status"]) for view in views],
                ambiguity=ambiguity, selected=None if ambiguity is None else chosen,
                zoom=_ZOOM, skeletons=lc.shown_skeletons(skeletons, chosen, cameras),
                skeleton_names=list(trained.description["skeleton"])))
        except OSError as error:
            raise UserError(f"cannot write {args.out / 'overlay.mp4'}: {error}") from None
        record["seconds"] = {
            "decode": round(decode_seconds, 3), "observe": round(observe_seconds, 3),
            "view_selection": round(selection_seconds, 3),
            "per_view": [{"compile": round(view["run"].compile_seconds, 3),
                          "ms_per_frame": round(1e3 * view["run"].seconds_per_frame, 3)}
                         for view in views],
            "total": round(time.perf_counter() - started, 3)}
        json_path = _write_json(args.out / "track.json", record)
    observed = sum(int(np.sum(view["observations"].found)) for view in views)
    speeds = ", ".join(f"{1e3 * view['run'].seconds_per_frame:.1f}" for view in views)
    compile_seconds = sum(view["run"].compile_seconds for view in views)
    print(f"tracked {count} frames in {len(views)} view(s) ({observed} view-frames observed; "
          f"{speeds} ms/frame, compile {compile_seconds:.1f} s); total "
          f"{time.perf_counter() - started:.1f} s")
    print(f"  wrote {args.out / 'overlay.mp4'}\n  wrote {json_path}")
    return 0


def _write_json(path: Path, record: dict) -> Path:
    from jaxtrack._files import write_json_atomically

    return write_json_atomically(path, finite_json(record))


def _view_selection(args) -> str:
    """``--view-selection``, or the rule chosen on validation."""
    from jaxtrack.experiments import linear_combination as lc

    return getattr(args, "view_selection", None) or lc.DEFAULT_VIEW_SELECTION


def _skeleton_estimate(args) -> str:
    """``--skeleton``, or the estimate chosen on validation."""
    from jaxtrack.experiments import linear_combination as lc

    return getattr(args, "skeleton", None) or lc.DEFAULT_SKELETON_ESTIMATE


def _skeletons(estimates, args) -> np.ndarray:
    """``(time, joints, 3)`` the view's 3-D skeleton estimate that ``--skeleton`` names."""
    return np.asarray(estimates.skeleton_3d if _skeleton_estimate(args) == "mean"
                      else estimates.best_skeleton_3d, np.float64)
