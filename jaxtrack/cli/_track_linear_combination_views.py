"""``jaxtrack track --method linear-combination --keypoints ...``: Ong & Gong's (2002) model
tracked over several calibrated views at once, each view's detections scored by the normalised
detection density (:func:`jaxtrack.experiments.linear_combination.track_views`). Writes
``track.json`` and ``track.trc``. Every argument is checked before any work; a bad one raises
:class:`UserError` (one line).
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
    check_camera_indices,
    check_seed,
    one_line,
    output_directory,
    read_calibration,
)
from jaxtrack.cli._track_linear_combination import _ITERATIONS, _PARTICLES, _skeleton_estimate
from jaxtrack.cli._train_linear_combination import load_model

__all__ = ["track_keypoints"]

_KEYPOINT_SUFFIXES = (".npz", ".json", "")


def _keypoint_sources(args, cameras) -> list:
    """One ``--keypoints`` source per camera: the paths given, one per video in order, or, for
    one FOLDER, its entry named after each camera (``cam01.npz``, ``cam01.json`` or a folder
    ``cam01/`` of OpenPose JSON); with one camera the path itself."""
    given = args.keypoints if isinstance(args.keypoints, list | tuple) else [args.keypoints]
    given = [Path(path) for path in given]
    if len(given) == len(cameras):
        return given
    if len(given) == 1 and given[0].is_dir():
        folder, sources = given[0], []
        for camera in cameras:
            found = [folder / f"{camera.name}{suffix}" for suffix in _KEYPOINT_SUFFIXES
                     if (folder / f"{camera.name}{suffix}").exists()]
            if not found:
                raise UserError(f"--keypoints {folder}: no keypoints of camera {camera.name} "
                                f"there; give one source per view ({camera.name}.npz, "
                                f"{camera.name}.json or a folder {camera.name}/ for each of "
                                f"{', '.join(c.name for c in cameras)})")
            sources.append(found[0])
        return sources
    raise UserError(f"--keypoints: {len(given)} source(s) for {len(cameras)} camera(s); give "
                    f"one per --video, in order, or a folder holding one per camera named "
                    f"after it (cam01.npz, ...)")


def _detection_cameras(args, count: int) -> list:
    """``--calibration``'s cameras (Z up: Pose2Sim ``.toml`` or Qualisys ``.qca.txt``), those
    of ``--cameras`` or the first ``count``."""
    path = args.calibration
    if path is None:
        raise UserError("--calibration is required with --keypoints for --method "
                        "linear-combination: the 3-D skeleton is placed by the calibrated views "
                        "(a Pose2Sim Calib*.toml or a Qualisys .qca.txt)")
    cameras = read_calibration(path)
    chosen = list(range(min(count, len(cameras)))) if args.cameras is None else list(args.cameras)
    check_camera_indices(chosen, len(cameras))
    if len(chosen) != count:
        raise UserError(f"--video: {count} video(s) but {len(chosen)} camera(s) of "
                        f"--calibration {path}; give one video per camera, in order (or pick "
                        f"the cameras with --cameras)")
    if count < 2:
        raise UserError("--keypoints with --method linear-combination needs at least 2 "
                        "calibrated views (one --video and one keypoint source per camera)")
    return [cameras[index] for index in chosen]


def track_keypoints(args: argparse.Namespace) -> int:
    """``jaxtrack track --method linear-combination --keypoints ...``: the tracker over the
    calibrated views, each view's detections scored by the detection density (the image
    fitness reads one camera's contour, which a world skeleton seen by several views does not
    give: detections alone). Writes ``track.json`` and ``track.trc`` (Y up, metres, as
    Pose2Sim writes its own)."""
    from jaxtrack._files import write_json_atomically
    from jaxtrack.cli._common import outputs_or_nothing
    from jaxtrack.cli._pose import read_keypoints
    from jaxtrack.cli._track_image import frame_range
    from jaxtrack.cli._track_image import options_record as record_of
    from jaxtrack.experiments import linear_combination as lc
    from jaxtrack.vision import VideoError, read_video, write_trc

    started = time.perf_counter()
    particles = at_least(args.particles, 1, "--particles", _PARTICLES)
    iterations = at_least(args.iterations, 1, "--iterations", _ITERATIONS)
    check_seed(args.seed)
    for option, given in (("--init", args.init != "face"), ("--masks", args.masks is not None),
                          ("--skin", args.skin is not None),
                          ("--view-selection", getattr(args, "view_selection", None)),
                          ("--person", args.person is not None),
                          ("--detector", args.detector is not None),
                          ("--coverage-weight", args.coverage_weight is not None),
                          ("--keypoint-weight", args.keypoint_weight is not None),
                          ("--fit-iterations", args.fit_iterations is not None),
                          ("--guided", getattr(args, "guided", None) is not None)):
        if given:
            raise UserError(f"{option} does not apply to --method linear-combination with "
                            f"--keypoints (every view's detections at once, from the first "
                            f"frame's triangulation; the density is not fitted)")
    start, stop = frame_range(args.frames)
    output_directory(args.out, "--out")
    cameras = _detection_cameras(args, len(args.video))
    sources = _keypoint_sources(args, cameras)
    trained = load_model(args.model, "--model", "make one with jaxtrack train --method "
                         "linear-combination")
    keypoints, sizes, rates = [], [], []
    for path, source, camera in zip(args.video, sources, cameras, strict=True):
        if not path.is_file():
            raise UserError(f"--video {path}: no such file")
        try:
            probe = read_video(path, start=0, max_frames=1)
        except VideoError as error:
            raise UserError(f"--video: {one_line(error)}") from None
        height, width = probe.frames.shape[1:3]
        camera_width, camera_height = camera.image_size
        if abs(width / height - camera_width / camera_height) > 0.02 * camera_width / camera_height:
            raise UserError(f"--video {path} is {width}x{height} but camera {camera.name} of "
                            f"--calibration is {camera_width}x{camera_height} (another shape): "
                            f"give the videos in the order of the calibration's cameras")
        points, confidence = read_keypoints(source)
        if not np.isfinite(points).any():
            raise UserError(f"--keypoints {source}: no keypoint found in any frame")
        # keypoints are in the video's pixels; the calibration's may be another size
        factor = max(camera_width, camera_height) / max(width, height)
        keypoints.append((points * factor, confidence))
        sizes.append((width, height))
        rates.append(probe.source_fps)
    rows = min(len(points) for points, _ in keypoints)
    stop = rows if stop is None else min(stop, rows)
    if stop - start < 2:
        raise UserError(f"--frames: the keypoints of every view cover video frames 0-{rows - 1};"
                        f" at least 2 must be tracked from frame {start}")
    keypoints = [(points[start:stop], confidence[start:stop]) for points, confidence in keypoints]
    first = lc.views_first_pose(keypoints, cameras)
    if not np.all(np.isfinite(first[1])):
        raise UserError(f"--keypoints: in video frame {start} the neck is found in fewer than 2 "
                        f"views, so the first skeleton cannot be placed; start where it is "
                        f"(--frames START:STOP)")
    estimate = _skeleton_estimate(args)
    run = lc.track_views(trained.model, cameras, keypoints, particles=particles,
                         iterations=iterations, seed=args.seed)
    world = run["skeleton" if estimate == "mean" else "best_skeleton"]
    joints = list(trained.description["skeleton"])
    rate = rates[0] if rates[0] and math.isfinite(rates[0]) else None
    record = {
        "method": "linear-combination", "evidence": "detections",
        "options": {**record_of(args), "tracker": run["options"], "skeleton": estimate},
        "model": str(args.model), "calibration": str(args.calibration),
        "views": [{"camera": camera.name, "video": str(video), "keypoints": str(source),
                   "size": list(size), "fps": fps}
                  for camera, video, source, size, fps in zip(cameras, args.video, sources,
                                                              sizes, rates, strict=True)],
        "joints": joints, "world": "the calibration's (Z up), metres", "fps": rate,
        "seconds_per_frame": run["seconds_per_frame"],
        "compile_seconds": run["compile_seconds"],
        "frames": [{"frame": start + t,
                    "skeleton_world_m": {joint: [round(float(v), 5) for v in world[t, k]]
                                         for k, joint in enumerate(joints)},
                    "markers": {camera.name: {
                        joint: [round(float(v) / (max(camera.image_size) / max(size)), 2)
                                for v in run["markers"][t, view, k]]
                        for k, joint in enumerate(joints)}
                        for view, (camera, size) in enumerate(zip(cameras, sizes, strict=True))},
                    "ess": round(float(run["ess"][t]), 2),
                    "scale": round(float(run["scale"][t]), 4),
                    "spread_m": round(float(run["spread"][t]), 4)}
                   for t in range(len(world))]}
    out = Path(args.out)
    with outputs_or_nothing(out) as written:
        written.append(out / "track.json")
        write_json_atomically(out / "track.json", record)
        written.append(out / "track.trc")
        # Pose2Sim's .trc is Y up: (X, Y, Z) of the Z-up world is written (Y, Z, X)
        write_trc(out / "track.trc", world[..., [1, 2, 0]], joints, rate or 30.0, "m",
                  first_frame=start + 1)
    print(f"tracked {len(world)} frames in {len(cameras)} views from their keypoints "
          f"({1e3 * run['seconds_per_frame']:.1f} ms/frame, compile "
          f"{run['compile_seconds']:.1f} s); total {time.perf_counter() - started:.1f} s")
    print(f"  wrote {out / 'track.json'}\n  wrote {out / 'track.trc'}")
    return 0
