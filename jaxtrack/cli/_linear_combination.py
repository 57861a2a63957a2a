"""``jaxtrack train|evaluate|track --method linear-combination``: Ong & Gong's (2002) tracker.

- ``train``: real clips rendered through the Pose2Sim cameras (``--cameras``), hybrid vectors,
  global PCA, clusters and their transition matrix, saved as one ``.npz``
  (:func:`jaxtrack.experiments.linear_combination.train`).
- ``evaluate``: the model trained on training subjects (cached beside ``--json`` as
  ``lc_cache.npz``), the tracker and its two baselines on held-out subjects' clips, 3-D
  skeleton error (:func:`jaxtrack.experiments.linear_combination.evaluate`).
- ``track``: one video per calibrated camera. Each is decoded at the scale the model was
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
    check_clips,
    check_held_out,
    check_json_and_plots,
    check_seed,
    finite_json,
    fit_mask_file,
    load_clip_sources,
    one_line,
    output_directory,
    output_folder,
    outputs_or_nothing,
    pose2sim_cameras,
    read_mask_files,
)

__all__ = ["CACHE_NAME", "evaluate", "track", "train"]

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


def _load(path: Path, what: str, remedy: str):
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
        _load(args.out, "--out", "delete it or choose another --out")
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
    trained = _load(cache, "the model cached beside --json:",
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
        labels=[_labels(sequence.status)], zoom=_ZOOM))


# ----------------------------------------------------------------------------------- track


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

    from jaxtrack.cli.track import _frame_range, _options_record
    from jaxtrack.experiments import linear_combination as lc
    from jaxtrack.trackers import Engine
    from jaxtrack.trackers.linear_combination import linear_combination_tracker, track_observations
    from jaxtrack.vision import VideoError, median_background, read_video, write_views_video

    started = time.perf_counter()
    options_record = _options_record(args)
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
    start, stop = _frame_range(args.frames)
    output_directory(args.out, "--out")  # probed before any frame is read
    for path in args.video:
        if not path.is_file():
            raise UserError(f"--video {path}: no such file")
    given_masks = read_mask_files(args.masks, len(args.video))
    trained = _load(args.model, "--model", "make one with jaxtrack train --method "
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
        background = median_background(frames) if masks is None else None
        origin, people = np.zeros(2), count
        if cameras is not None:
            centre, people = lc.subject_centre(frames, background, masks=masks)
            origin = np.round(centre - np.asarray(lc.CROP_SIZE) / 2)
            frames = lc.cut_window(frames, origin, lc.CROP_SIZE)
            if masks is None:
                background = lc.cut_window(background, origin, lc.CROP_SIZE)
            else:
                masks = lc.cut_window(masks[..., None], origin, lc.CROP_SIZE,
                                      mode="constant")[..., 0]
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
    record = _track_record(args, trained, cameras, views, skeletons, chosen, ambiguity, tracker,
                           skin)
    record["options"] = options_record
    with outputs_or_nothing(args.out) as written:
        fps = videos[0].fps if math.isfinite(videos[0].fps) else fps_model
        try:  # with several views: ambiguity bars, the selected view framed (Fig. 17)
            written.append(write_views_video(
                [view["frames"] for view in views],
                [view["run"].estimates.contour for view in views],
                [view["run"].estimates.best_markers for view in views],
                args.out / "overlay.mp4", fps=fps, names=[view["name"] for view in views],
                marker_names=_MARKERS, labels=[_labels(view["status"]) for view in views],
                ambiguity=ambiguity, selected=None if ambiguity is None else chosen,
                zoom=_ZOOM, skeletons=_shown_skeletons(skeletons, chosen, cameras),
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


def _to_video(points: np.ndarray, view: dict) -> np.ndarray:
    """Tracking pixels (inside the crop) -> the video's own pixels (pixel centres at
    integers, as ``scale_camera``)."""
    return (points + view["origin"] + 0.5) / view["scale"] - 0.5


def _rounded(values, digits: int):
    values = np.asarray(values, np.float64)
    if not np.all(np.isfinite(values)):
        return None
    return np.round(values, digits).tolist()


def _view_statuses(view: dict) -> list:
    """Each frame's :class:`jaxtrack.cli._status.FrameStatus` in one view: its head and hands
    in the video's own pixels against the video's size, its best particle's log-fitness."""
    from jaxtrack.cli._status import frame_statuses

    estimate = view["run"].estimates
    points = _to_video(np.asarray(estimate.best_markers, np.float64), view)
    return frame_statuses(points, tuple(view["size"]),
                          degenerate=~(np.asarray(estimate.ess) > 0),
                          no_person=~np.asarray(estimate.found, bool),
                          log_likelihood=np.asarray(estimate.log_fitness, np.float64))


def _track_record(args, trained, cameras, views, skeletons, chosen, ambiguity, tracker,
                  skin) -> dict:
    from jaxtrack.cli._status import (
        LOST_RULE,
        FrameStatus,
        status_counts,
        status_legend,
    )

    joints = list(trained.description["skeleton"])
    view_statuses = [_view_statuses(view) for view in views]
    frame_statuses = [FrameStatus.NO_PERSON if chosen[t] is None
                      else view_statuses[chosen[t]][t] for t in range(len(chosen))]
    frames = []
    for t in range(len(chosen)):
        entries = []
        for index, view in enumerate(views):
            estimate = view["run"].estimates
            found = bool(estimate.found[t])
            markers = np.asarray(estimate.best_markers[t], np.float64)
            video_markers = _to_video(markers, view) if found else None
            skeleton = np.asarray(skeletons[index][t], np.float64)
            entry = {
                "status": view["status"][t] or "observed", "observed": found,
                "frame_status": view_statuses[index][t].value,
                "log_fitness": round(float(estimate.log_fitness[t]), 4),
                "ambiguity": None if ambiguity is None else _rounded(ambiguity[t, index], 5),
                "cluster": int(estimate.cluster[t]), "ess": round(float(estimate.ess[t]), 2),
                "head": None if video_markers is None else _rounded(video_markers[0], 2),
                "hands": None if video_markers is None else _rounded(video_markers[1:], 2),
                "skeleton_m": dict(zip(joints, np.round(skeleton, 4).tolist(), strict=True))}
            if cameras is not None:  # neck-relative in the calibration's world axes (Y up)
                world = skeleton @ np.asarray(cameras[index].rotation, np.float64)
                entry["skeleton_world_m"] = dict(zip(joints, np.round(world, 4).tolist(),
                                                     strict=True))
            entries.append(entry)
        video = views[0]["video"]
        index = int(video.frame_indices[t])
        frames.append({"frame": index, "time_s": (round(index / video.source_fps, 4)
                                                  if math.isfinite(video.source_fps) else None),
                       "status": frame_statuses[t].value,
                       "views": entries, "selected_view": chosen[t],
                       "selected": None if chosen[t] is None else views[chosen[t]]["name"]})
    return {
        "method": "linear-combination", "model": str(args.model),
        "statuses": status_legend(), "lost_rule": LOST_RULE,
        "status_of_a_frame": "the selected view's (each view's is its frame_status)",
        "status_counts": status_counts(frame_statuses),
        "trained_on": {key: trained.description.get(key) for key in
                       ("clips", "views", "fps", "num_clusters", "frames")},
        "calibration": None if args.calibration is None else str(args.calibration),
        "views": [{"video": str(view["video"].path), "camera": view["name"],
                   "size": list(view["size"]), "fps": _rounded(view["video"].source_fps, 3),
                   "stride": view["stride"],
                   "scale": np.round(view["scale"], 5).tolist(),
                   "crop_origin": np.round(view["origin"], 1).tolist(),
                   "crop_from_silhouettes": view["people"],
                   "silhouettes": ("background subtraction against the median of the "
                                   "video's frames" if args.masks is None
                                   else f"masks {args.masks[index]}")}
                  for index, view in enumerate(views)],
        "tracked_size": list(views[0]["frames"].shape[2:0:-1]),
        "skin": "fixed chroma box" if skin is None else list(skin),
        "particles": tracker.num_particles, "iterations": tracker.iterations,
        "view_selection": _view_selection(args) if len(views) > 1 else None,
        "skeleton_estimate": _skeleton_estimate(args),
        "seed": args.seed, "tracker": views[0]["run"].options, "joints": joints,
        "coordinates": "head and hands in the video's own pixels (hands ordered left to right "
                       "in the image); skeleton_m (the skeleton_estimate) in the camera's "
                       "frame, metres, relative to the neck",
        "frames": frames}


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


def _shown_skeletons(skeletons: list[np.ndarray], chosen: list[int | None],
                     cameras) -> np.ndarray:
    """``(time, joints, 3)`` the 3-D skeleton the overlay draws each frame: the selected view's
    (the only view's) of each view's ``skeletons`` ``(time, joints, 3)``, x right, y up,
    metres from the neck; in the calibration's world axes when there is one (the same axes
    whichever view is selected), else the camera's axes with y and z turned to point up and
    toward the viewer. NaN in a frame no view observed."""
    count = len(chosen)
    joints = np.asarray(skeletons[0]).shape[1]
    shown = np.full((count, joints, 3), np.nan)
    for t, index in enumerate(chosen):
        if index is None:
            continue
        skeleton = np.asarray(skeletons[index][t], np.float64)
        if cameras is not None:
            shown[t] = skeleton @ np.asarray(cameras[index].rotation, np.float64)
        else:
            shown[t] = skeleton * np.array([1.0, -1.0, -1.0])
    return shown


def _labels(status: list[str]) -> list[str]:
    """Per frame ``"3/40 no skin blobs"``: the frame's number and why it was not observed
    (the first words of its status)."""
    return [f"{t + 1}/{len(status)} {text.split(':')[0].split('(')[0].strip()}".strip()
            for t, text in enumerate(status)]
