"""Ong & Gong's linear-combination tracker on the four real Pose2Sim videos with view selection,
scored against the triangulated reference.

``jaxtrack track --method linear-combination`` runs on all four calibrated cameras of
``shared/data/pose2sim_demo_singleperson`` (a man balancing on a beam, 100 frames at 60 fps,
taken at the model's 30 fps) with the model ``jaxtrack train --method linear-combination``
makes from the training subjects (cached as ``benchmarks/results/lc_model.npz``; ``--model`` to
give another). Its ``track.json`` is then scored against the reference
(``jaxtrack.evaluation.reference``: keypoints triangulated from the four cameras):

- 2-D, per view: the head and the two hands the tracker reports, in video pixels, against the
  reference's head marker and wrists (hands under the better left/right assignment per frame),
  as a fraction of the reference torso (neck to pelvis) in that view;
- 3-D, per view: the mean distance over the 12 skeleton vertices after the similarity transform
  that best maps each frame's skeleton onto the reference's
  (``experiments.linear_combination.aligned_skeleton_error``, the usual monocular 3-D score,
  blind to the subject's size and the global rotation), in millimetres;
- 3-D without the alignment, per view: the skeleton ``track.json`` gives in the calibration's
  world axes (``skeleton_world_m``, neck-relative) against the reference's, neck-relative,
  in millimetres: the score of the rendered evaluation, which also charges the skeleton's
  orientation and size;
- view selection: the 3-D error (aligned, and without the alignment) of the view the tracker
  selected against the best (oracle) and the worst view of each frame;
- a baseline that never looks at the video: the mean of the model's training skeletons, held
  constant, scored as the tracker is.

    python -m papers.ong2002.real_video [--particles 300] [--iterations 5]
    python -m papers.ong2002.real_video --silhouettes mediapipe
    python -m papers.ong2002.real_video --demo multiperson

``--silhouettes``: ``background`` (the default) takes each view's silhouettes against the
video's median background, as ``jaxtrack track`` does by default; the man barely leaves his
place, so the median holds him and the silhouettes are fragments. ``mediapipe`` gives
``jaxtrack track --masks`` MediaPipe's person segmentation of each video instead
(``jaxtrack/vision/mediapipe.py``, in its own venv, ``make detector``; cached in
``benchmarks/results/mediapipe_masks/``, shared with ``papers.kwatra2002.mixed_state_real_video``).

``--demo multiperson`` tracks the two-person take instead
(``shared/data/pose2sim_demo_multiperson``: the same man in a lunge with his arms out while a
woman walks through, the same four cameras). It has no reference, so it is not scored: the
script reports per view the frames observed and the times selected, and leaves the overlay
(``benchmarks/results/linear_combination_real_video_multiperson/overlay.mp4``) to be looked at.

Prints the tables and writes ``benchmarks/results/linear_combination_real_video.json``; the
tracker's overlay video (every view's contour, head and hands, the ambiguity bars and the
selected view) is left in ``benchmarks/results/linear_combination_real_video/``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from benchmarks._common import device_description, print_table, write_json

RESULTS = Path(__file__).resolve().parents[2] / "benchmarks" / "results"
"""The model cache, the overlays and the JSON: kept out of git beside the other benchmarks'
results (the MediaPipe masks there are shared with ``papers.kwatra2002.mixed_state_real_video``)."""
CAMERAS = ("cam01", "cam02", "cam03", "cam04")


def hands_error(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """``(time, 2)`` distances of two hands under the better left/right assignment."""
    straight = np.linalg.norm(estimate - truth, axis=-1)
    crossed = np.linalg.norm(estimate - truth[:, ::-1], axis=-1)
    better = straight.sum(axis=1) <= crossed.sum(axis=1)
    return np.where(better[:, None], straight, crossed)


def score_track(record: dict, references: dict, world_markers: np.ndarray,
                reference_frames: np.ndarray, mean_skeleton: np.ndarray | None = None) -> dict:
    """Score a ``track.json`` record against the reference (see the module docstring).

    Args:
        record: the parsed ``track.json`` of a run on the cameras in ``references``' order.
        references: camera name → :class:`jaxtrack.evaluation.reference.CameraReference`.
        world_markers: ``(rows, 12, 3)`` the reference's 12 markers in 3-D, one row per
            ``reference_frames`` entry.
        reference_frames: ``(rows,)`` the video frame of each row.
        mean_skeleton: ``(12, 3)`` a constant skeleton (``record["joints"]`` order) scored as a
            baseline: what the 3-D error is when the video is not looked at.
    """
    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.experiments.linear_combination import aligned_skeleton_error

    joints = record["joints"]
    order = [joints.index(name) for name in UPPER_BODY_12]
    row_of = {int(frame): row for row, frame in enumerate(reference_frames)}
    frames = [entry for entry in record["frames"] if int(entry["frame"]) in row_of]
    if not frames:
        raise SystemExit("no tracked frame is covered by the reference")
    rows = np.array([row_of[int(entry["frame"])] for entry in frames])
    names = [view["camera"] for view in record["views"]]
    head, neck, pelvis = (UPPER_BODY_12.index(name) for name in ("head", "neck", "pelvis"))
    wrists = [UPPER_BODY_12.index("right_wrist"), UPPER_BODY_12.index("left_wrist")]
    per_view, errors_3d, raw_errors_3d = {}, [], []
    # the reference in jaxtrack track's world axes (read_qca(world_up="y"): the Z-up point
    # (X, Y, Z) is (X, Z, −Y)), neck-relative, as skeleton_world_m
    truth_world = world_markers[rows][..., [0, 2, 1]] * np.array([1.0, 1.0, -1.0])
    truth_world = truth_world - truth_world[:, neck:neck + 1]
    for index, name in enumerate(names):
        reference = references[name].select([int(entry["frame"]) for entry in frames])
        torso = np.linalg.norm(reference.markers[:, neck] - reference.markers[:, pelvis], axis=-1)
        entries = [entry["views"][index] for entry in frames]
        observed = np.array([entry["head"] is not None for entry in entries])
        head_2d = np.array([entry["head"] if entry["head"] is not None else [np.nan] * 2
                            for entry in entries], float)
        hands_2d = np.array([entry["hands"] if entry["hands"] is not None else [[np.nan] * 2] * 2
                             for entry in entries], float)
        head_error = np.linalg.norm(head_2d - reference.markers[:, head], axis=-1) / torso
        hand_error = hands_error(hands_2d, reference.markers[:, wrists]) / torso[:, None]
        skeleton = np.array([[entry["skeleton_m"][joint] for joint in joints]
                             for entry in entries], float)[:, order]
        error_3d = 1e3 * aligned_skeleton_error(skeleton, world_markers[rows])
        errors_3d.append(error_3d)
        world = np.array([[entry["skeleton_world_m"][joint] for joint in joints]
                          for entry in entries], float)[:, order]
        raw_3d = 1e3 * np.linalg.norm(world - truth_world, axis=-1).mean(axis=-1)
        raw_errors_3d.append(raw_3d)
        per_view[name] = {
            "frames": int(len(entries)), "observed": int(observed.sum()),
            "head_error_torso": _mean(head_error[observed]),
            "hand_error_torso": _mean(hand_error[observed]),
            "aligned_3d_error_mm": _mean(error_3d), "raw_3d_error_mm": _mean(raw_3d)}
    chosen = np.array([-1 if entry["selected_view"] is None else entry["selected_view"]
                       for entry in frames])
    selected = chosen >= 0
    selection = {"frames": int(selected.sum()),
                 "times_selected": {name: int(np.sum(chosen == index))
                                    for index, name in enumerate(names)}}
    for prefix, errors in (("", errors_3d), ("raw_", raw_errors_3d)):
        errors = np.stack(errors, axis=1)  # (time, views)
        chosen_error = errors[np.arange(len(frames)), np.maximum(chosen, 0)]
        selection |= {f"{prefix}selected_mm": _mean(chosen_error[selected]),
                      f"{prefix}oracle_mm": _mean(errors[selected].min(axis=1)),
                      f"{prefix}worst_mm": _mean(errors[selected].max(axis=1))}
    scores = {"views": per_view, "selection": selection, "frames": int(len(frames))}
    if mean_skeleton is not None:
        constant = np.broadcast_to(np.asarray(mean_skeleton, float)[order], (len(rows), 12, 3))
        scores["constant_mean_skeleton_mm"] = _mean(
            1e3 * aligned_skeleton_error(constant, world_markers[rows]))
    return scores


def unscored_summary(record: dict) -> dict:
    """What a ``track.json`` of a take without a reference says: per view the frames observed,
    the times selected and the mean ambiguity where observed."""
    names = [view["camera"] for view in record["views"]]
    frames = record["frames"]
    per_view = {}
    for index, name in enumerate(names):
        entries = [entry["views"][index] for entry in frames]
        ambiguity = [entry["ambiguity"] for entry in entries
                     if entry["observed"] and entry["ambiguity"] is not None]
        per_view[name] = {
            "frames": len(entries), "observed": sum(bool(entry["observed"]) for entry in entries),
            "selected": sum(entry["selected_view"] == index for entry in frames),
            "mean_ambiguity": _mean(ambiguity),
            "crop_from_silhouettes": record["views"][index]["crop_from_silhouettes"]}
    return {"frames": len(frames), "views": per_view,
            "no_view_observed": sum(entry["selected_view"] is None for entry in frames)}


def _report_unscored(record: dict, args, tracked: Path, seconds: float) -> int:
    summary = unscored_summary(record)
    print(f"\n{summary['frames']} frames tracked, not scored (no reference); device: "
          f"{device_description()}; {seconds:.0f} s")
    print_table([{"view": name, **values} for name, values in summary["views"].items()],
                [("view", "view", "s"), ("observed", "observed", "d"),
                 ("selected", "selected", "d"), ("mean_ambiguity", "mean ambiguity", ".3f")])
    print(f"overlay: {tracked / 'overlay.mp4'}")
    _write(args, tracked, record, summary=summary)
    return 0


def _write(args, tracked: Path, record: dict, **results) -> None:
    write_json(args.out, {"benchmark": "linear_combination_real_video",
                          "device": device_description(), "arguments": {
                              key: str(value) for key, value in vars(args).items()},
                          "tracked": str(tracked), **results,
                          "seconds": record.get("seconds")})


def _mean(values: np.ndarray) -> float | None:
    values = np.asarray(values, float)
    return float(np.mean(values)) if values.size else None


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--model", type=Path, default=RESULTS / "lc_model.npz",
                        help="a jaxtrack train --method linear-combination model (made there "
                             "if missing)")
    parser.add_argument("--particles", type=int, default=300)
    parser.add_argument("--iterations", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--view-selection", choices=("ambiguity", "fitness", "paper"),
                        default=None,
                        help="jaxtrack track's rule (default: its own, chosen on validation)")
    parser.add_argument("--skeleton", choices=("mean", "best"), default=None,
                        help="jaxtrack track's 3-D skeleton estimate (default: its own, "
                             "chosen on validation)")
    parser.add_argument("--demo", choices=("singleperson", "multiperson"),
                        default="singleperson",
                        help="the Pose2Sim take: one man (scored against its reference) or the "
                             "man and a woman walking through (no reference: not scored)")
    parser.add_argument("--silhouettes", choices=("background", "mediapipe"),
                        default="background",
                        help="the views' silhouettes: against the median background, or "
                             "MediaPipe's person masks (module docstring)")
    parser.add_argument("--out", type=Path, default=None,
                        help="JSON output (default benchmarks/results/"
                             "linear_combination_real_video[_multiperson].json)")
    args = parser.parse_args(argv)
    if args.particles < 1 or args.iterations < 1:
        parser.error(f"--particles and --iterations must be at least 1, got {args.particles} "
                     f"and {args.iterations}")
    multiperson = args.demo == "multiperson"
    args.out = args.out or RESULTS / ("linear_combination_real_video"
                                      + ("_multiperson" if multiperson else "")
                                      + (f"_{args.view_selection}" if args.view_selection
                                         else "")
                                      + (f"_{args.skeleton}" if args.skeleton else "")
                                      + ("_mediapipe" if args.silhouettes == "mediapipe"
                                         else "") + ".json")

    from jaxtrack.cli import main as jaxtrack
    from jaxtrack.evaluation.reference import (
        TRC_FILES,
        default_folder,
        load_reference,
        read_trc,
        to_upper_body,
        trc_to_world,
    )

    folder = default_folder()
    calibration = folder / "Calib.qca.txt"
    if multiperson:  # the same cameras (its Calib.qca.txt is byte-identical)
        folder = folder.parent / "pose2sim_demo_multiperson"
        calibration = folder / "calibration" / "Calib.qca.txt"
    videos = [folder / "videos" / f"{camera}.mp4" for camera in CAMERAS]
    if not all(video.is_file() for video in videos):
        raise SystemExit(f"{folder / 'videos'}: the Pose2Sim demo's videos are not there")
    begin = time.perf_counter()
    if not args.model.is_file():
        if jaxtrack(["train", "--method", "linear-combination", "--out", str(args.model)]):
            raise SystemExit("training the model failed")
    masks = []
    if args.silhouettes == "mediapipe":
        from jaxtrack.vision.mediapipe import demo_masks

        for camera in CAMERAS:
            made = demo_masks(folder, camera)
            if isinstance(made, dict):
                raise SystemExit(f"--silhouettes mediapipe: {made['skipped']}")
            masks.append(str(made))
    tracked = args.out.with_suffix("")
    code = jaxtrack(["track", "--method", "linear-combination", "--model", str(args.model),
                     "--video", *map(str, videos), "--calibration", str(calibration),
                     "--particles", str(args.particles), "--iterations", str(args.iterations),
                     "--seed", str(args.seed), "--out", str(tracked),
                     *(["--view-selection", args.view_selection] if args.view_selection
                       else []),
                     *(["--skeleton", args.skeleton] if args.skeleton else []),
                     *(["--masks", *masks] if masks else [])])
    if code:
        raise SystemExit("tracking failed")
    record = json.loads((tracked / "track.json").read_text())
    if multiperson:
        return _report_unscored(record, args, tracked, time.perf_counter() - begin)
    references = load_reference(folder, num_video_frames=100)
    _, positions, _ = read_trc(folder / "reference" / "pose-3d" / TRC_FILES[False])
    world = to_upper_body(trc_to_world(positions))
    frames = references[CAMERAS[0]].frame_indices
    world = world[references[CAMERAS[0]].rows]
    from jaxtrack.experiments import linear_combination as lc

    trained = lc.load(args.model)
    layout = trained.model.layout
    mean_skeleton = np.asarray(trained.vectors)[:, layout.skeleton_slice].mean(axis=0).reshape(
        layout.num_skeleton, 3)
    scores = score_track(record, references, world, frames, mean_skeleton)

    print(f"\n{scores['frames']} frames scored; device: {device_description()}; "
          f"{time.perf_counter() - begin:.0f} s")
    print_table([{"view": name, **values} for name, values in scores["views"].items()],
                [("view", "view", "s"), ("observed", "observed", "d"),
                 ("head_error_torso", "head error (torso)", ".2f"),
                 ("hand_error_torso", "hand error (torso)", ".2f"),
                 ("aligned_3d_error_mm", "3-D error, aligned (mm)", ".0f"),
                 ("raw_3d_error_mm", "3-D error, not aligned (mm)", ".0f")])
    selection = scores["selection"]
    print(f"\nview selection over {selection['frames']} frames: selected "
          f"{selection['selected_mm']:.0f} mm, oracle {selection['oracle_mm']:.0f} mm, worst "
          f"{selection['worst_mm']:.0f} mm after alignment ({selection['raw_selected_mm']:.0f}, "
          f"{selection['raw_oracle_mm']:.0f} and {selection['raw_worst_mm']:.0f} mm without); "
          f"times selected {selection['times_selected']}")
    print(f"the training skeletons' mean, held constant: {scores['constant_mean_skeleton_mm']:.0f} "
          f"mm")
    _write(args, tracked, record, scores=scores)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
