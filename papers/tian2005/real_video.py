"""The trackers on the four real Pose2Sim videos, scored against the triangulated reference.

    python -m papers.tian2005.real_video  # 4 views × 3 methods × 2 estimates × 2 inits
    python -m papers.tian2005.real_video --frames 40      # the first 40 video frames of each view
    python -m papers.tian2005.real_video --quick          # one view, 10 frames, the latent tracker
    python -m papers.tian2005.real_video --score out/track.json   # a jaxtrack track run, scored

Each video (``shared/data/pose2sim_demo_singleperson/videos/cam0N.mp4``, 1080 × 1920 at 60 fps,
a man balancing on a beam) is downscaled as ``jaxtrack track`` does (longer side at most
``--max-size``, default 960) and tracked from video frame 1 (the first frame the reference
covers: ``.trc`` row k is video frame k + 1), every second frame by default (``--stride``: the
60 fps videos at the 30 fps of the training poses, the rate at which CONDENSATION's AR(2) and
MHT's step are learned, so that no method's dynamics run at the wrong rate), by

- the latent tracker (200 particles), CONDENSATION (1 000 particles, AR(2) dynamics) and MHT
  (10 modes), all from the same prior: the GPLVM and the training poses of the wave gestures of
  the scripted comparison's training subjects (``jaxtrack.data.clip_sets.TRAINING_CLIPS``,
  as in the demo; ``jaxtrack.data.splits``), with the default likelihood (limb strips, edges and the
  arms' foreground against the video's median background);
- each reporting its own estimate and with the shared refinement stage (``Refinement()``);
- each initialised (a) from the reference's markers in the first tracked frame and (b)
  automatically (``jaxtrack.trackers.autoinit``, as ``jaxtrack track --init face``: face and
  blob-head boxes, the prior's poses against the foreground of the video's median background,
  or against the first frame's person mask with ``--masks``, as ``jaxtrack track --masks``),
  or (c, ``--inits detector``) from MediaPipe's keypoints in the first tracked frame.

With ``--keypoints mediapipe`` every method's likelihood also scores MediaPipe Pose's keypoints
of each frame (the keypoint term, ``jaxtrack.likelihoods.edges``: the detector's error model,
its scales fitted on validation subjects by ``papers.tian2005.keypoint_term``, at η =
``--keypoint-weight``, default 3/2, the Cauchy density's own).

Also scored: "static", the initial pose held still (how far the subject moves), and MediaPipe
Pose (``jaxtrack/vision/mediapipe.py``, a per-frame detector in its own venv, when ``make
detector`` has made it). Every frame after the first tracked one is scored by
:func:`jaxtrack.evaluation.evaluate_track` against the reference
(:mod:`jaxtrack.evaluation.reference`, about 10 px median accuracy at full size, ~1-3 % of the
torso): mean error in % of the reference torso (neck–pelvis) and the fraction of frames within
15 % of it. Compile time and ms/frame are reported apart. Writes
``papers/tian2005/results/runs/real_video.json`` (``--out``) and prints a markdown table.
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import time
from pathlib import Path

import jax.random as jr
import numpy as np

from benchmarks._common import device_description, run_header
from jaxtrack._files import write_json_atomically
from jaxtrack.body import UPPER_BODY_12
from jaxtrack.data.splits import split_of
from jaxtrack.evaluation import evaluate_track, torso_lengths
from jaxtrack.evaluation.reference import default_folder, load_reference
from jaxtrack.experiments import DEFAULT_PARTICLES
from jaxtrack.experiments.priors import auto_initial_pose
from jaxtrack.vision.mediapipe import (
    add_mask_options,
    check_mask_options,
    likelihood_options,
    masks_or_exit,
)
from papers.tian2005 import RUNS, candidate_prior

VIEWS = ("cam01", "cam02", "cam03", "cam04")
METHODS = ("latent", "condensation", "mht")
ESTIMATES = ("own", "refined")
INITS = ("reference", "auto", "detector")
RESULTS = RUNS
QUICK = {"views": ("cam02",), "frames": 10, "methods": ("latent",), "estimates": ("refined",)}
SCORED = ("num_frames", "mean_error_px", "median_error_px", "mean_error_torso",
          "fraction_within_15", "failed", "failure_frame", "ms_per_frame", "compile_seconds",
          "errors_torso")


class View:
    """One camera's tracked frames (downscaled), their background and reference."""

    def __init__(self, folder: Path, camera: str, frames: int | None, max_size: int, *,
                 filtered: bool = False, stride: int = 1):
        from jaxtrack.vision import (
            median_background,
            median_grey_background,
            read_video,
            to_grey,
        )

        path = folder / "videos" / f"{camera}.mp4"
        probe = read_video(path, max_frames=1)
        height, width = probe.frames.shape[1:3]
        scale = min(1.0, max_size / max(height, width))
        video = read_video(path, scale=scale)  # every frame: the median background needs them
        self.name, self.fps = camera, float(video.fps) / stride  # the rate tracked
        self.scale = video.frames.shape[2] / width  # the decoder rounds the size
        self.size = (width, height)
        reference = load_reference(folder, filtered=filtered,
                                   num_video_frames=len(video.frames))[camera]
        covered = reference.frame_indices
        stop = len(covered) if frames is None else min(len(covered), frames)
        indices = covered[:stop:stride]
        if len(indices) < 2:
            raise SystemExit(f"{camera}: tracking needs at least 2 frames, got {len(indices)} "
                             f"(--frames {stop}, --stride {stride})")
        self.frame_indices = indices
        self.truth = reference.select(indices).scaled(self.scale).markers
        self.images = video.frames[indices]
        self.frames = to_grey(self.images)
        # the whole video's median, as `jaxtrack track` takes over the frames it reads
        self.background_rgb = median_background(video.frames)
        self.background = median_grey_background(to_grey(video.frames))
        self.masks = None  # person masks of the tracked frames, where a run gives them
        self.detections = None  # MediaPipe's run on the tracked frames, where one is made
        self.keypoints = None  # (points, confidence) for the keypoint term, where it is on


def detections(view: View) -> dict:
    """MediaPipe Pose on the view's tracked frames (run once, kept on the view)."""
    from jaxtrack.vision.mediapipe import run_mediapipe

    if view.detections is None:
        view.detections = run_mediapipe(view.images)
    return view.detections


def make_tracker(method: str, estimate: str, prior, view: View,
                 options: dict | None = None):
    """The tracker of one configuration (the protocol's ``build_tracker``, with the whole
    video's background; ``options``: the likelihood's settings, e.g. μ and ν, None its
    defaults)."""
    from jaxtrack import trackers

    refinement = trackers.Refinement() if estimate == "refined" else None
    particles = DEFAULT_PARTICLES[method]
    likelihood = trackers.Likelihood(**(options or {}))
    if method == "latent":
        return trackers.latent_tracker(prior.model, prior.template,
                                       engine=trackers.Engine(particles), fps=view.fps,
                                       refinement=refinement, background=view.background,
                                       likelihood=likelihood)
    states, ids = prior.training_states, prior.training_sequence_ids
    if method == "condensation":
        return trackers.condensation_tracker(prior.template, states,
                                             engine=trackers.Engine(particles),
                                             refinement=refinement, background=view.background,
                                             sequence_ids=ids, likelihood=likelihood)
    return trackers.mht_tracker(prior.template, states, num_modes=particles,
                                refinement=refinement, background=view.background,
                                sequence_ids=ids, likelihood=likelihood)


def score(markers: np.ndarray, view: View, **timing) -> dict:
    """Every frame after the first tracked one against the reference."""
    metrics = evaluate_track(markers[1:], view.truth[1:], UPPER_BODY_12, **timing)
    return {key: metrics[key] for key in SCORED}


def run_tracker(prior, view: View, method: str, estimate: str, init: str,
                initial_pose: np.ndarray, seed: int, options: dict | None = None) -> dict:
    """One configuration on one view; with ``view.masks`` the observations carry them as the
    foreground term's per-frame mask, with ``view.keypoints`` the detector's keypoints for
    the keypoint term."""
    from jaxtrack.trackers import track

    tracker = make_tracker(method, estimate, prior, view, options)
    result = track(tracker, jr.PRNGKey(seed), view.frames, initial_pose, progress=False,
                   masks=view.masks, keypoints=view.keypoints)
    if not np.all(np.isfinite(result.markers)):
        return {"method": method, "estimate": estimate, "init": init, "view": view.name,
                "seed": seed, "skipped": "non-finite markers"}
    return {"method": method, "estimate": estimate, "init": init, "view": view.name,
            "seed": seed, "tracker": result.options,
            **score(result.markers, view, seconds_per_frame=result.seconds_per_frame,
                    compile_seconds=result.compile_seconds)}


def swapped_frames(markers: np.ndarray, view: View) -> dict:
    """Of the scored frames (every one after the first), those where the markers with the
    person's left and right exchanged are nearer the reference than as given (a detector's
    left/right swap), and how far those are once swapped back (% of the torso)."""
    from jaxtrack.likelihoods.edges import MIRRORED_MARKERS

    truth = view.truth[1:]
    torso = torso_lengths(truth, UPPER_BODY_12)
    given = np.linalg.norm(markers[1:] - truth, axis=-1).mean(-1) / torso
    back = np.linalg.norm(markers[1:, list(MIRRORED_MARKERS)] - truth, axis=-1).mean(-1) / torso
    swapped = back < given
    return {"frames_swapped": int(swapped.sum()),
            "swapped_back_errors_torso": np.sort(back[swapped]).round(4).tolist()}


def run_mediapipe_view(view: View) -> dict:
    found = detections(view)
    row = {"method": "mediapipe", "estimate": "own", "init": "none", "view": view.name}
    if "skipped" in found:
        return {**row, "skipped": found["skipped"]}
    return {**row, "version": found["version"], "frames_without_person": found["filled"],
            "first_frame_seconds": found["first_seconds"],
            **swapped_frames(found["markers"], view),
            **score(found["markers"], view,
                    seconds_per_frame=float(np.median(found["seconds"])))}


def score_track_file(path: Path, folder: Path) -> dict:
    """A ``jaxtrack track`` run's ``track.json`` of one of the Pose2Sim videos (named by its
    file, ``cam0N.mp4``) against the reference: every frame it tracked after the first that the
    reference covers, in the video's own pixels, as the table scores them."""
    import json

    record = json.loads(Path(path).read_text())
    camera = Path(record["video"]).stem
    if camera not in VIEWS:
        raise SystemExit(f"--score {path}: its video {record['video']} is none of the Pose2Sim "
                         f"demo's {', '.join(VIEWS)}")
    reference = load_reference(folder, num_video_frames=100)[camera]
    covered = set(int(index) for index in reference.frame_indices)
    frames = [entry for entry in record["frames"] if entry["frame"] in covered]
    if len(frames) < 2:
        raise SystemExit(f"--score {path}: fewer than 2 of its frames have a reference")
    markers = np.array([[entry["markers"][name] for name in UPPER_BODY_12]
                        for entry in frames])
    truth = reference.select([entry["frame"] for entry in frames]).markers
    metrics = evaluate_track(markers[1:], truth[1:], UPPER_BODY_12)
    return {"track": str(path), "view": camera, "frames_scored": len(frames) - 1,
            "keypoint_weight": record["tracker"]["likelihood"].get("keypoint_weight"),
            **{key: metrics[key] for key in ("mean_error_torso", "fraction_within_15",
                                             "mean_error_px")}}


def table(runs: list[dict], views: tuple[str, ...]) -> str:
    """Markdown: one row per (method, estimate, init); per view "error % / within 15 %"."""
    done = [run for run in runs if "skipped" not in run]
    key = lambda run: (run["method"], run["estimate"], run["init"])  # noqa: E731
    order = {name: i for i, name in enumerate((*METHODS, "static", "mediapipe"))}
    header = ["method", "estimate", "init", *views, "mean error %", "mean within 15 %",
              "ms/frame", "compile s"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for (method, estimate, init), group in itertools.groupby(
            sorted(done, key=lambda run: (order[run["method"]], run["estimate"],
                                          run["init"] != "reference", run["init"])), key=key):
        group = list(group)
        by_view = {run["view"]: run for run in group}
        cells = [f"{100 * by_view[v]['mean_error_torso']:.1f} / "
                 f"{100 * by_view[v]['fraction_within_15']:.0f} %" if v in by_view else "—"
                 for v in views]
        ms = [run["ms_per_frame"] for run in group if run.get("ms_per_frame") is not None]
        compile_s = [run["compile_seconds"] for run in group
                     if run.get("compile_seconds") is not None]
        lines.append("| " + " | ".join([
            method, estimate, init, *cells,
            f"{100 * statistics.mean(r['mean_error_torso'] for r in group):.1f}",
            f"{100 * statistics.mean(r['fraction_within_15'] for r in group):.0f} %",
            f"{statistics.median(ms):.1f}" if ms else "—",
            f"{max(compile_s):.1f}" if compile_s else "—"]) + " |")
    return "\n".join(lines)


def _share_compilations() -> None:
    """A persistent compilation cache for this run only: the runner compiles every ``track``
    call ahead of time, and the same configuration on another view of the same size, or from
    the other initial pose, compiles to the same program. The first compilation of each is
    what the table reports (the largest compile time of a row)."""
    import atexit
    import shutil
    import tempfile

    import jax

    folder = tempfile.mkdtemp(prefix="jaxtrack-real-video-xla-")
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    jax.config.update("jax_compilation_cache_dir", folder)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m papers.tian2005.real_video",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--views", nargs="+", choices=VIEWS, default=list(VIEWS))
    parser.add_argument("--frames", type=int, default=None,
                        help="track within this many video frames of each view from video "
                             "frame 1, every --stride-th (default: all the reference covers, 99)")
    parser.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS))
    parser.add_argument("--estimates", nargs="+", choices=ESTIMATES, default=list(ESTIMATES))
    parser.add_argument("--inits", nargs="+", choices=INITS, default=["reference", "auto"],
                        help="initial poses: the reference's, the automatic one (jaxtrack "
                             "track --init face), MediaPipe's first keypoints (detector)")
    parser.add_argument("--seeds", type=int, default=1, help="tracker seeds per configuration")
    parser.add_argument("--max-size", type=int, default=960, metavar="PX",
                        help="downscale so the longer side is at most PX (default 960)")
    parser.add_argument("--stride", type=int, default=2,
                        help="track every STRIDE-th video frame (default 2: the 60 fps videos at "
                             "the training poses' 30 fps, the rate CONDENSATION's AR(2) and "
                             "MHT's step are learned at)")
    parser.add_argument("--filtered", action="store_true",
                        help="score against Pose2Sim's Butterworth-filtered triangulation")
    parser.add_argument("--no-mediapipe", action="store_true",
                        help="do not run MediaPipe Pose even if its venv exists")
    parser.add_argument("--quick", action="store_true",
                        help="cam02, 10 frames, the latent tracker with refinement, both inits, "
                             "a small prior (a smoke run)")
    add_mask_options(parser)
    parser.add_argument("--keypoints", choices=("none", "mediapipe"), default="none",
                        help="every method's likelihood also scores MediaPipe Pose's keypoints "
                             "of each frame (the keypoint term)")
    parser.add_argument("--keypoint-weight", type=float, default=None, metavar="ETA",
                        help="the keypoint term's η (default 3/2, the Cauchy density's own; "
                             "needs --keypoints)")
    parser.add_argument("--score", type=Path, default=None, metavar="TRACK_JSON",
                        help="only score a jaxtrack track run of one of the videos (its "
                             "track.json) against the reference, and print it")
    parser.add_argument("--data", type=Path, default=None,
                        help="the pose2sim_demo_singleperson folder (default: shared data)")
    parser.add_argument("--out", type=Path, default=None,
                        help="JSON output (default papers/tian2005/results/runs/real_video.json; "
                             "--quick: real_video_quick.json)")
    args = parser.parse_args(argv)
    if args.frames is not None and args.frames < 2:
        parser.error(f"--frames must be at least 2, got {args.frames}")
    if args.seeds < 1:
        parser.error(f"--seeds must be at least 1, got {args.seeds}")
    if args.stride < 1:
        parser.error(f"--stride must be at least 1, got {args.stride}")
    if args.max_size < 32:
        parser.error(f"--max-size must be at least 32, got {args.max_size}")
    suffix = check_mask_options(parser, args).replace("-", "_")
    if args.keypoint_weight is not None and not (np.isfinite(args.keypoint_weight)
                                                 and args.keypoint_weight > 0):
        parser.error(f"--keypoint-weight must be a positive number, got {args.keypoint_weight}")
    if args.keypoint_weight is not None and args.keypoints == "none":
        parser.error("--keypoint-weight: the keypoint term reads a detector's keypoints; give "
                     "--keypoints mediapipe")
    if "detector" in args.inits and args.no_mediapipe:
        parser.error("--inits detector starts from MediaPipe's keypoints; leave out "
                     "--no-mediapipe")
    options = likelihood_options(args)
    if args.keypoints != "none":
        from jaxtrack.likelihoods.edges import CAUCHY_KEYPOINT_WEIGHT

        options["keypoint_weight"] = (CAUCHY_KEYPOINT_WEIGHT if args.keypoint_weight is None
                                      else args.keypoint_weight)
        suffix += "_keypoints" + (f"_eta{args.keypoint_weight:g}"
                                  if args.keypoint_weight is not None else "")
    views, frames = tuple(args.views), args.frames
    methods, estimates = tuple(args.methods), tuple(args.estimates)
    if args.quick:
        views, frames = QUICK["views"], QUICK["frames"]
        methods, estimates = QUICK["methods"], QUICK["estimates"]
    try:
        folder = args.data or default_folder()
    except FileNotFoundError as error:
        parser.error(str(error))
    if args.score is not None:
        if not args.score.is_file():
            parser.error(f"--score {args.score}: no such file")
        scored = score_track_file(args.score, folder)
        print(f"{scored['view']}, {scored['frames_scored']} frames: "
              f"{100 * scored['mean_error_torso']:.1f} % of the torso, "
              f"{100 * scored['fraction_within_15']:.0f} % of frames within 15 %")
        return 0
    out = args.out or RESULTS / (("real_video_quick" if args.quick else "real_video") + suffix
                                 + ".json")

    from jaxtrack.data.clip_sets import QUICK_TRAINING, TRAINING_CLIPS

    assert all(split_of(clip) == "training" for clip in TRAINING_CLIPS)
    started = time.perf_counter()
    _share_compilations()
    prior = candidate_prior("waves", **(QUICK_TRAINING if args.quick else {}))
    print(f"prior: {', '.join(TRAINING_CLIPS)} ({time.perf_counter() - started:.0f} s); "
          f"{device_description()}")

    runs, inits = [], {}
    for camera in views:
        view = View(folder, camera, frames, args.max_size, filtered=args.filtered,
                    stride=args.stride)
        if args.masks == "mediapipe":
            view.masks = masks_or_exit(view.images, camera)
        if args.keypoints == "mediapipe" or "detector" in args.inits:
            from jaxtrack.vision.mediapipe import detected_keypoints

            found = detections(view)
            if "skipped" in found:
                raise SystemExit(f"--keypoints mediapipe / --inits detector, {camera}: "
                                 f"{found['skipped']}")
            if args.keypoints == "mediapipe":
                view.keypoints = detected_keypoints(found)
        height, width = view.frames.shape[1:]
        print(f"{camera}: video frames {view.frame_indices[0]}..{view.frame_indices[-1]} at "
              f"{width}x{height}, reference torso "
              f"{np.median(torso_lengths(view.truth, UPPER_BODY_12)):.0f} px")
        poses = {}
        if "reference" in args.inits:
            poses["reference"] = view.truth[0]
            runs.append({"method": "static", "estimate": "own", "init": "reference",
                         "view": camera,
                         **score(np.repeat(view.truth[:1], len(view.truth), 0), view)})
        if "auto" in args.inits:
            pose, record = auto_initial_pose(
                prior, view.images[0], view.background_rgb, view.truth[0],
                None if view.masks is None else view.masks[0])
            inits[camera] = record
            print(f"  auto init: {record}")
            if pose is None:
                runs.append({"method": "all", "init": "auto", "view": camera,
                             "skipped": record["failed"]})
            else:
                poses["auto"] = pose
        if "detector" in args.inits:
            from jaxtrack.vision.mediapipe import detected_keypoints

            first, confidence = (value[0] for value in detected_keypoints(detections(view)))
            if np.all(confidence > 0):
                poses["detector"] = first
            else:
                runs.append({"method": "all", "init": "detector", "view": camera,
                             "skipped": "MediaPipe did not find every marker in the first "
                                        "frame"})
        for method, estimate, (init, pose), seed in itertools.product(
                methods, estimates, poses.items(), range(args.seeds)):
            run = run_tracker(prior, view, method, estimate, init, pose, seed, options)
            runs.append(run)
            print(f"  {method:12s} {estimate:7s} {init:9s} seed {seed}: "
                  + (run["skipped"] if "skipped" in run else
                     f"{100 * run['mean_error_torso']:5.1f} % torso, "
                     f"{100 * run['fraction_within_15']:3.0f} % within 15 %, "
                     f"{run['ms_per_frame']:.1f} ms/frame, compile {run['compile_seconds']:.1f} s"))
        if not (args.no_mediapipe or args.quick):
            run = run_mediapipe_view(view)
            runs.append(run)
            print("  mediapipe: " + (run["skipped"] if "skipped" in run else
                                     f"{100 * run['mean_error_torso']:.1f} % torso, "
                                     f"{100 * run['fraction_within_15']:.0f} % within 15 %, "
                                     f"{run['ms_per_frame']:.1f} ms/frame; left and right "
                                     f"swapped in {run['frames_swapped']} frames"))
    text = table(runs, views)
    print(text)
    header = run_header("papers.tian2005.real_video", argv, started)
    write_json_atomically(out, {
        **header,
        "data": str(folder), "views": list(views), "frames": frames, "stride": args.stride,
        "max_size": args.max_size, "masks": args.masks,
        "foreground_weight": args.foreground_weight, "coverage_weight": args.coverage_weight,
        "keypoints": args.keypoints, "keypoint_weight": options.get("keypoint_weight"),
        "methods": list(methods), "estimates": list(estimates), "inits": list(args.inits),
        "seeds": args.seeds, "training_clips": list(TRAINING_CLIPS),
        "prior": "quick" if args.quick else "full",
        "reference": {"trc": "filtered" if args.filtered else "raw",
                      "frame_alignment": "trc row k = video frame k + 1",
                      "scored_frames": "every tracked frame after the first"},
        "auto_init": inits, "table": text, "runs": runs})
    print(f"wrote {out} in {header['seconds']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
