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
``overlay.mp4``, ``track.json`` and, with calibrated views, ``track.trc`` (the selected
view's neck-relative 3-D skeleton, OpenSim's and Pose2Sim's format). The model fixes the
tracking scale, so ``--max-size`` and the latent tracker's options are not used. Why these choices:
``docs/linear-combination.md``.

Every argument is checked before any work; a bad one raises :class:`UserError` (one line).
The record: :func:`jaxtrack.experiments.linear_combination.track_record`. With ``--keypoints``
the views are tracked at once from their detections instead
(:mod:`jaxtrack.cli._track_linear_combination_views`).
"""

from __future__ import annotations

import argparse
import math
import time

import jax.random as jr
import numpy as np

from jaxtrack.cli._common import (
    UserError,
    at_least,
    check_camera_indices,
    check_seed,
    fit_mask_file,
    one_line,
    output_directory,
    pipeline_errors,
    read_mask_files,
)
from jaxtrack.cli._train_linear_combination import load_model

__all__ = ["track"]

_PARTICLES, _ITERATIONS = 300, 5


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
    check_camera_indices(chosen, len(cameras))
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
    from jaxtrack.cli._track_image import frame_range, options_record, tracked_end
    from jaxtrack.experiments import linear_combination as lc
    from jaxtrack.experiments.pipeline import Window, track_video
    from jaxtrack.trackers import Engine
    from jaxtrack.trackers.linear_combination import linear_combination_tracker

    if getattr(args, "keypoints", None) is not None:
        from jaxtrack.cli._track_linear_combination_views import track_keypoints

        return track_keypoints(args)
    started = time.perf_counter()
    record_options = options_record(args)
    particles = at_least(args.particles, 1, "--particles", _PARTICLES)
    iterations = at_least(args.iterations, 1, "--iterations", _ITERATIONS)
    check_seed(args.seed)
    if args.init != "face":
        raise UserError("--init is not used by --method linear-combination (it starts from the "
                        "model's clusters)")
    for name in ("coverage_weight", "keypoint_weight", "person", "detector",
                 "fit_iterations", "guided"):  # refused, not ignored
        if getattr(args, name, None) is not None:
            raise UserError(f"--{name.replace('_', '-')} does not apply to --method "
                            f"linear-combination (it takes detections as --keypoints)")
    for name in ("no_fit", "no_image"):
        if getattr(args, name, False):
            raise UserError(f"--{name.replace('_', '-')} applies to --method "
                            f"linear-combination only with --keypoints")
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
    # each video at the model's frame rate: every stride-th frame
    strides = [max(1, round(fps / fps_model)) if math.isfinite(fps) else 1
               for _, _, fps in probes]
    for index, (path, masks) in enumerate(zip(args.video, given_masks, strict=True)):
        if masks is not None:  # the aspect ratio, on the first frame tracked
            fit_mask_file(masks, args.masks[index], [start], probes[index][1])
        end = tracked_end(path, stop)  # one past the last video frame tracked
        if masks is not None and end is not None and end > start:
            last = start + (end - 1 - start) // strides[index] * strides[index]
            if len(masks) <= last:
                raise UserError(f"--masks {args.masks[index]}: holds {len(masks)} masks, but "
                                f"video frame {last} is tracked (one mask per video frame, from "
                                f"its first)")
    tracker = linear_combination_tracker(trained.model, engine=Engine(particles),
                                         iterations=iterations, skin_reference=skin)
    selection, estimate = _view_selection(args), _skeleton_estimate(args)
    report = lc.video_report(
        trained, cameras, tracker, model=str(args.model),
        calibration=None if args.calibration is None else str(args.calibration),
        masks=args.masks, skin=skin, seed=args.seed, view_selection=selection,
        skeleton_estimate=estimate)
    with pipeline_errors("--video"):
        record = track_video(
            tracker, args.video, args.out, key=jr.PRNGKey(args.seed),
            scale=[scale for scale, _, _ in probes], start=start, stride=strides,
            max_frames=None if stop is None else -(-(stop - start) // max(strides)),
            window=None if cameras is None else Window(lc.CROP_SIZE, locate=lc.locate_window),
            masks=given_masks if len(args.video) > 1 else given_masks[0],
            view_names=[camera.name for camera in cameras] if cameras else None,
            progress=False, report=report, extra_record={"options": record_options})
    runs = record["runs"]
    observed = sum(int(np.sum(run.result.estimates.found)) for run in runs)
    speeds = ", ".join(f"{1e3 * run.result.seconds_per_frame:.1f}" for run in runs)
    compile_seconds = sum(run.result.compile_seconds for run in runs)
    print(f"tracked {len(runs[0].frame_indices)} frames in {len(runs)} view(s) ({observed} "
          f"view-frames observed; {speeds} ms/frame, compile {compile_seconds:.1f} s); total "
          f"{time.perf_counter() - started:.1f} s")
    print(f"  wrote {record['paths']['overlay']}\n  wrote {record['paths']['json']}")
    if cameras is not None:
        print(f"  wrote {_write_trc(record, args.out / 'track.trc', fps_model)}")
    return 0


def _write_trc(record: dict, path, fps_model: float):
    """The selected view's 3-D skeleton of every frame (``skeleton_world_m``: the calibration's
    world axes, Y up, metres, relative to the neck) as a ``.trc`` file, blank where no view
    was selected; at the tracked frame rate (the model's where the video states none)."""
    from jaxtrack.vision import write_trc

    joints = list(record["joints"])
    skeletons = np.full((len(record["frames"]), len(joints), 3), np.nan)
    for t, frame in enumerate(record["frames"]):
        if frame["selected_view"] is not None:
            world = frame["views"][frame["selected_view"]]["skeleton_world_m"]
            skeletons[t] = [world[joint] for joint in joints]
    view = record["views"][0]
    rate = view["fps"] / view["stride"] if view["fps"] else fps_model
    return write_trc(path, skeletons, joints, rate, first_frame=record["frames"][0]["frame"] + 1)


def _view_selection(args) -> str:
    """``--view-selection``, or the rule chosen on validation."""
    from jaxtrack.experiments import linear_combination as lc

    return getattr(args, "view_selection", None) or lc.DEFAULT_VIEW_SELECTION


def _skeleton_estimate(args) -> str:
    """``--skeleton``, or the estimate chosen on validation."""
    from jaxtrack.experiments import linear_combination as lc

    return getattr(args, "skeleton", None) or lc.DEFAULT_SKELETON_ESTIMATE
