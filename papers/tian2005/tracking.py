"""The scripted comparison: latent tracker, CONDENSATION and MHT on subjects the prior never saw.

    python -m papers.tian2005.tracking                 # test subjects, the full grid (~1 h)
    python -m papers.tian2005.tracking --split validation  # the same grid, validation subjects
    python -m papers.tian2005.tracking --quick         # one short sequence, two methods (CI)
    python -m papers.tian2005.tracking --no-real-video # the rendered grid only
    python -m papers.tian2005.tracking --keypoints mediapipe --likelihoods limbs+edges

The grid is methods {latent (200 particles), CONDENSATION (1 000), MHT (10 modes)} × estimate
{the filter's own, + the shared refinement stage} × likelihood {eq. 7 marker patches, the default
limb strips and edges} × tracker seeds × rendered views of every gesture clip of the split's
subjects (:mod:`jaxtrack.data.splits`). Every method learns from the same training clips: the
latent tracker's GPLVM from their poses, the baselines' dynamics from the same poses
(``baseline_dynamics="training"``; ``--baseline-dynamics test_start`` runs Tian et al.'s first
30 frames of the test clip instead). Every run starts from frame 0's ground truth (the paper's
protocol), or with ``--init auto`` from the automatic initialisation a user without ground
truth runs (``jaxtrack track --init face``: the prior's pose that best explains frame 0's
foreground against the sequence's median background, :func:`auto_initial_markers`), the same
pose for every method, seed and estimate of a sequence; a sequence where it finds no one is
reported and left out. With ``--keypoints mediapipe`` the default likelihood also scores
MediaPipe Pose's keypoints of every frame (the keypoint term at η = 3/2,
``jaxtrack.likelihoods.edges``; MediaPipe in its venv, ``jaxtrack/vision/mediapipe.py``): rows
``limbs+edges+keypoints``.

On the test split the same methods and estimates then track the four real Pose2Sim videos of a
test subject (:mod:`papers.tian2005.real_video`: the default likelihood, initialised from the
reference's first frame and automatically, MediaPipe beside them where its venv exists), scored
against the keypoints triangulated from the four cameras; their table follows the rendered one
in ``table.md`` and their runs are in ``real_video.json`` (``--no-real-video`` leaves them out,
as ``--quick``, ``--split validation`` and a prior other than the default do: real video has no
validation subject, and :mod:`papers.tian2005.real_video` tracks with the default prior).

Writes to ``papers/tian2005/results/runs/tracking/<split>/``: ``runs.jsonl`` (one JSON object
per run),
``summary.json`` (per configuration: mean error with a 95 % t-interval over the runs, fraction
within 15 % of the torso, lost runs, median ms/frame and compile seconds apart), ``table.md``
(the table the README quotes) and ``errors.png``. Settings are chosen on ``--split validation``;
``--split test`` is only ever reported.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import math
import statistics
import time
from pathlib import Path

import jax.random as jr
import numpy as np
from tqdm import tqdm

from benchmarks._common import device_description, run_header
from jaxtrack._files import write_json_atomically
from jaxtrack._plotting import new_figure, save_figure
from jaxtrack.body import UPPER_BODY_12
from jaxtrack.data.clip_sets import (
    GESTURE_CLIPS,
    PRIOR_CLIPS,
    QUICK_TRAINING,
    WIDE_VALIDATION_CLIPS,
)
from jaxtrack.data.splits import UnknownSubjectError, check_disjoint, split_of
from jaxtrack.evaluation import evaluate_track
from jaxtrack.experiments import (
    BASELINE_DYNAMICS,
    DEFAULT_PARTICLES,
    build_tracker,
    render_test_sequences,
)
from jaxtrack.experiments.priors import auto_initial_pose, prior_tag
from jaxtrack.priors.dynamics import fit_latent_velocity
from jaxtrack.trackers import Likelihood, Refinement, track
from papers.tian2005 import RUNS, candidate_prior

METHODS = ("latent", "condensation", "mht")
ESTIMATES = ("own", "refined")
LIKELIHOODS = ("markers", "limbs+edges")
RESULTS = RUNS / "tracking"

COLUMNS = (("method", "method", "s"), ("estimate", "estimate", "s"),
           ("likelihood", "likelihood", "s"), ("particles", "N", "d"), ("runs", "runs", "d"),
           ("error_torso", "error/torso", ".1%"), ("error_torso_ci", "± 95 %", ".1%"),
           ("error_px", "error px", ".1f"), ("within_15", "within 15 %", ".0%"),
           ("lost", "lost", "s"), ("ms_per_frame", "ms/frame", ".1f"),
           ("compile_seconds", "compile s", ".1f"))


def t_interval(values) -> float:
    """Half-width of the 95 % Student-t interval of the mean (0 for a single value)."""
    from scipy import stats

    values = np.asarray(values, float)
    if len(values) < 2:
        return 0.0
    return float(stats.t.ppf(0.975, len(values) - 1) * values.std(ddof=1) / math.sqrt(len(values)))


def configurations(quick: bool, methods=METHODS, estimates=ESTIMATES,
                   likelihoods=LIKELIHOODS) -> list[dict]:
    """Every (method, estimate, likelihood) of the grid (or of the given subsets); ``quick``:
    latent and CONDENSATION with the default likelihood."""
    if quick:
        methods = tuple(m for m in methods if m != "mht")
        likelihoods = tuple(k for k in likelihoods if k == "limbs+edges") or ("limbs+edges",)
    return [{"method": m, "estimate": e, "likelihood": k}
            for m, e, k in itertools.product(methods, estimates, likelihoods)]


def auto_initial_markers(prior, sequence) -> tuple[np.ndarray | None, dict]:
    """``jaxtrack track --init face`` on the sequence's first frame, its foreground taken against
    the sequence's median background as ``jaxtrack track`` takes it
    (:func:`jaxtrack.experiments.priors.auto_initial_pose`; its record names the sequence)."""
    from jaxtrack.vision import median_background

    markers, record = auto_initial_pose(prior, sequence.images[0],
                                        median_background(sequence.images), sequence.truth[0])
    return markers, {"sequence": sequence.name, **record}


SETTINGS = {"edge_weight": "limbs+edges' kappa", "edge_tolerance": "limbs+edges' angular "
            "tolerance (degrees)", "foreground_weight": "limbs+edges' mu",
            "jump_probability": "the latent tracker's jump probability epsilon",
            "refine_steps": "the refinement's Gauss-Newton steps",
            "velocity_weight": "MHT's velocity weight", "prior_scale": "MHT's prior scale",
            "prune_below": "MHT's pruning threshold",
            "partitioned": "the latent tracker's partitioned sampling over the prior's parts "
                           "(1: on; with --parts)",
            "latent_velocity": "the latent tracker's second-order walk learned from the "
                               "prior's training latents (1: on)",
            "subject_lengths": "the latent tracker decodes with the subject's link lengths "
                               "from frame 0 (1: on)",
            "iterations": "the latent tracker's and CONDENSATION's select/predict/measure "
                          "cycles per frame"}
"""Defaults a run may override (``--set NAME=VALUE``), to choose them on validation subjects."""
_EDGES = ("edge_weight", "edge_tolerance", "foreground_weight")
_LATENT = ("jump_probability", "partitioned", "latent_velocity", "subject_lengths")
_MHT = ("velocity_weight", "prior_scale", "prune_below")


def run_one(prior, sequence, config: dict, seed: int, particles: int,
            baseline_dynamics: str, initial: np.ndarray | None = None,
            settings: dict | None = None, keypoints: tuple | None = None) -> dict:
    """Track one sequence with one configuration and seed from ``initial`` (frame 0's truth
    when None), with ``settings`` (of :data:`SETTINGS`) overriding the defaults and, given
    ``keypoints`` (a detector's ``(points, confidence)`` of the sequence), the default
    likelihood's keypoint term; the evaluation's scalars."""
    from jaxtrack.likelihoods.edges import CAUCHY_KEYPOINT_WEIGHT

    settings = settings or {}
    edges = {name: settings[name] for name in _EDGES if name in settings}
    keyed = keypoints is not None and config["likelihood"] == "limbs+edges"
    if keyed:
        edges["keypoint_weight"] = CAUCHY_KEYPOINT_WEIGHT
    likelihood = Likelihood(config["likelihood"],
                            **(edges if config["likelihood"] == "limbs+edges" else {}))
    latent_options = {name: settings[name] for name in _LATENT if name in settings
                      and config["method"] == "latent"} or None
    if latent_options and latent_options.pop("latent_velocity", 0.0):
        latent_options["velocity"] = fit_latent_velocity(
            np.asarray(prior.model.latents), prior.training_sequence_ids,
            fps=float(prior.model.dynamics_fps))
    mht_options = {name: settings[name] for name in _MHT if name in settings
                   and config["method"] == "mht"} or None
    # "own": the filter's estimate (weighted mean / best mode); "refined": the same Gauss–Newton
    # refinement stage for every method
    steps = {"steps": int(settings["refine_steps"])} if "refine_steps" in settings else {}
    refinement = Refinement(**steps) if config["estimate"] == "refined" else None
    engine_options = ({"iterations_per_frame": int(settings["iterations"])}
                      if "iterations" in settings else None)
    tracker = build_tracker(config["method"], prior, sequence, particles, likelihood,
                            refinement=refinement, baseline_dynamics=baseline_dynamics,
                            latent_options=latent_options, mht_options=mht_options,
                            engine_options=engine_options)
    initial = sequence.truth[0] if initial is None else initial
    result = track(tracker, jr.PRNGKey(seed), sequence.frames, initial, progress=False,
                   keypoints=keypoints if keyed else None)
    if keyed:
        config = {**config, "likelihood": "limbs+edges+keypoints"}
    metrics = evaluate_track(result.markers, sequence.truth, UPPER_BODY_12,
                             seconds_per_frame=result.seconds_per_frame,
                             compile_seconds=result.compile_seconds)
    return {**config, "sequence": sequence.name, "seed": seed, "particles": particles,
            **{key: metrics[key] for key in ("num_frames", "mean_error_px", "mean_error_torso",
                                              "fraction_within_15", "failed", "frames_tracked",
                                              "ms_per_frame", "compile_seconds")}}


def summarise(runs: list[dict]) -> list[dict]:
    """One row per configuration: means with their 95 % interval over runs (seeds × sequences)."""
    rows = []
    key = lambda run: (run["method"], run["estimate"], run["likelihood"], run["particles"])  # noqa: E731
    for (method, estimate, likelihood, particles), group in itertools.groupby(
            sorted(runs, key=key), key=key):
        group = list(group)
        torso = [run["mean_error_torso"] for run in group]
        lost = sum(run["failed"] for run in group)
        rows.append({
            "method": method, "estimate": estimate, "likelihood": likelihood,
            "particles": particles, "runs": len(group),
            "error_torso": statistics.mean(torso), "error_torso_ci": t_interval(torso),
            "error_px": statistics.mean(run["mean_error_px"] for run in group),
            "within_15": statistics.mean(run["fraction_within_15"] for run in group),
            "num_lost": lost, "lost": f"{lost}/{len(group)}",
            "ms_per_frame": statistics.median(run["ms_per_frame"] for run in group),
            # the first run of a configuration compiles; later ones reuse the compiled scan
            "compile_seconds": max(run["compile_seconds"] for run in group),
        })
    order = {name: index for index, name in enumerate(METHODS)}
    return sorted(rows, key=lambda row: (row["likelihood"] != "limbs+edges",
                                         row["estimate"], order[row["method"]],
                                         row["particles"]))


def markdown_table(rows: list[dict]) -> str:
    headers = [header for _, header, _ in COLUMNS]
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    for row in rows:
        lines.append("| " + " | ".join(format(row[name], spec) for name, _, spec in COLUMNS)
                     + " |")
    return "\n".join(lines)


def plot(rows: list[dict], path: Path, title: str) -> Path:
    figure, axis = new_figure(9, 4.5)
    labels = [f"{row['method']}\n{row['estimate']}\n{row['likelihood']}" for row in rows]
    positions = np.arange(len(rows))
    axis.bar(positions, [100 * row["error_torso"] for row in rows],
             yerr=[100 * row["error_torso_ci"] for row in rows], capsize=3,
             color=["C0" if row["method"] == "latent" else "C1" if row["method"] ==
                    "condensation" else "C2" for row in rows])
    axis.set_xticks(positions, labels, fontsize=7)
    axis.set_ylabel("mean marker error, % of the torso (95 % interval)")
    axis.set_title(title, fontsize=10)
    return save_figure(figure, path, dpi=120)


def wants_real_video(args, tag: str, settings: dict) -> bool:
    """Whether this run also tracks the real videos: the full test grid with the default prior
    and settings (real video has no validation subject; papers.tian2005.real_video tracks with the
    default prior and settings)."""
    return not (args.no_real_video or args.quick or args.split != "test" or tag != "waves"
                or settings or args.baseline_dynamics != "training"
                or args.keypoints != "none")  # papers.tian2005.real_video --keypoints runs those


def real_video_table(out: Path, methods: tuple[str, ...], estimates: tuple[str, ...]) -> str:
    """Track the four real Pose2Sim videos with ``methods`` × ``estimates``, one tracker seed
    (:func:`papers.tian2005.real_video.main`, both initialisations; 6 minutes on 2 cores for the
    whole grid on 2026-11-27), writing ``out/real_video.json``; its table, headed, for
    ``table.md``."""
    from papers.tian2005 import real_video

    path = out / "real_video.json"
    code = real_video.main(["--methods", *methods, "--estimates", *estimates,
                            "--out", str(path)])
    if code != 0:
        raise RuntimeError(f"papers.tian2005.real_video failed (exit status {code})")
    result = json.loads(path.read_text())
    frames = result["frames"] or "all the reference's"
    return (f"Real video (a test subject): the four Pose2Sim views, {frames} video frames each, "
            f"one in {result.get('stride', 1)} tracked, the default likelihood, one tracker "
            f"seed; error against the keypoints triangulated from the four cameras "
            f"(papers.tian2005.real_video):\n\n" + result["table"])


def _setting(text: str) -> tuple[str, float]:
    name, _, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if name not in SETTINGS or not math.isfinite(number):
        raise argparse.ArgumentTypeError(f"--set takes NAME=VALUE with NAME one of "
                                         f"{', '.join(SETTINGS)} and a number, got {text!r}")
    return name, number


def _particles(text: str) -> tuple[str, int]:
    method, _, value = text.partition("=")
    if method not in METHODS or not value.isdigit() or int(value) < 1:
        raise argparse.ArgumentTypeError(f"--particles takes METHOD=N with METHOD one of "
                                         f"{', '.join(METHODS)} and N a positive whole number, "
                                         f"got {text!r}")
    return method, int(value)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m papers.tian2005.tracking",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--split", choices=("validation", "test"), default="test",
                        help="whose subjects are tracked (settings are chosen on validation)")
    parser.add_argument("--seeds", type=int, default=3, help="tracker seeds per sequence")
    parser.add_argument("--views", type=int, default=2,
                        help="rendered views per clip (view 0 frontal, others random)")
    parser.add_argument("--max-frames", type=int, default=None,
                        help="track only the first frames of every clip")
    parser.add_argument("--baseline-dynamics", choices=BASELINE_DYNAMICS, default="training",
                        help="what CONDENSATION's AR(2) and MHT's step are learned from")
    parser.add_argument("--prior", choices=tuple(PRIOR_CLIPS), default="waves",
                        help="the prior's training clips (PRIOR_CLIPS; waves)")
    parser.add_argument("--mirror", action="store_true",
                        help="train the prior on the clips' left-right mirror images too")
    parser.add_argument("--parts", action="store_true",
                        help="one GPLVM per body part (torso, each arm; PartsGPLVM) instead of "
                             "one of the whole upper body (Tian et al.)")
    parser.add_argument("--back-constraint", type=float, default=None, metavar="WIDTH",
                        help="a back-constrained GPLVM of this kernel width (x = g(y); "
                             "fit_gplvm's back_constraint) instead of free latents")
    parser.add_argument("--latent-dim", type=int, default=2,
                        help="latent dimension of the prior (of each part's with --parts; 2)")
    parser.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS))
    parser.add_argument("--estimates", nargs="+", choices=ESTIMATES, default=list(ESTIMATES))
    parser.add_argument("--likelihoods", nargs="+", choices=LIKELIHOODS,
                        default=list(LIKELIHOODS))
    parser.add_argument("--init", choices=("truth", "auto"), default="truth",
                        help="start from frame 0's ground truth (the paper's protocol) or from "
                             "the automatic initialisation (jaxtrack track --init face)")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        type=_setting, help="override a default to compare it on validation "
                        "subjects: " + ", ".join(SETTINGS) + " (repeatable)")
    parser.add_argument("--clips", nargs="+", metavar="CLIP", default=None,
                        help="clips of the --split's subjects to track instead of its "
                             "GESTURE_CLIPS, or 'wide': the nine validation clips of "
                             "WIDE_VALIDATION_CLIPS (with --split validation)")
    parser.add_argument("--particles", action="append", default=[], metavar="METHOD=N",
                        type=_particles, help="particles (MHT: modes) of one method instead of "
                        "its default (" + ", ".join(f"{method} {count}" for method, count in
                                                    DEFAULT_PARTICLES.items()) + "; repeatable)")
    parser.add_argument("--quick", action="store_true",
                        help="a small prior; one clip, one view, one seed, 20 frames; latent and "
                             "CONDENSATION with the default likelihood (a smoke run for CI)")
    parser.add_argument("--keypoints", choices=("none", "mediapipe"), default="none",
                        help="the default likelihood also scores MediaPipe Pose's keypoints of "
                             "every frame (the keypoint term; MediaPipe's venv)")
    parser.add_argument("--no-real-video", action="store_true",
                        help="do not track the real Pose2Sim videos after the rendered grid")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder (default "
                        "papers/tian2005/results/runs/tracking/<split>)")
    args = parser.parse_args(argv)
    for name in ("seeds", "views"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} must be at least 1, got {getattr(args, name)}")
    if args.max_frames is not None and args.max_frames < 2:
        parser.error(f"--max-frames must be at least 2, got {args.max_frames}")
    if args.back_constraint is not None and not args.back_constraint > 0:
        parser.error(f"--back-constraint must be a positive width, got {args.back_constraint:g}")
    if not 1 <= args.latent_dim <= 6:
        parser.error(f"--latent-dim must be 1 to 6, got {args.latent_dim}")
    if args.init == "auto" and args.parts:
        parser.error("--init auto searches one GPLVM's poses; it does not take --parts")
    partitioned = dict(args.set).get("partitioned")
    if partitioned is not None and (partitioned not in (0.0, 1.0)
                                    or (partitioned == 1.0 and not args.parts)):
        parser.error(f"--set partitioned=1 needs --parts (one GPLVM per body part to partition) "
                     f"and partitioned is 0 or 1, got {partitioned:g}")
    iterations = dict(args.set).get("iterations")
    if iterations is not None and not (iterations >= 1 and float(iterations).is_integer()):
        parser.error(f"--set iterations must be a whole number of cycles >= 1, got {iterations:g}")
    for switch in ("latent_velocity", "subject_lengths"):
        if dict(args.set).get(switch, 0.0) not in (0.0, 1.0):
            parser.error(f"--set {switch} is 0 or 1, got {dict(args.set)[switch]:g}")
    if args.clips == ["wide"]:
        if args.split != "validation":
            parser.error(f"--clips wide names validation clips, and --split is {args.split}")
        args.clips = list(WIDE_VALIDATION_CLIPS)
    for clip in args.clips or ():
        try:
            where = split_of(clip)
        except UnknownSubjectError as error:
            parser.error(f"--clips: {error}")
        if where != args.split:
            parser.error(f"--clips: {clip} is a {where} subject's clip, and --split is "
                         f"{args.split}")
    clips = tuple(args.clips) if args.clips else GESTURE_CLIPS[args.split]
    seeds, views, max_frames = args.seeds, args.views, args.max_frames
    if args.quick:
        clips, seeds, views, max_frames = clips[:1], 1, 1, 20
    training_clips = PRIOR_CLIPS[args.prior]
    check_disjoint(training_clips, clips)
    assert all(split_of(clip) == args.split for clip in clips)
    tag = prior_tag(args.prior, args.mirror, args.parts, args.back_constraint,
                    args.latent_dim)
    settings = dict(args.set)
    particles = dict(args.particles)
    out = args.out or RESULTS / (args.split + ("" if tag == "waves" else "-" + tag)
                                 + ("-auto" if args.init == "auto" else "")
                                 + ("-keypoints" if args.keypoints != "none" else "")
                                 + "".join(f"-{name}={value:g}"
                                           for name, value in sorted(settings.items()))
                                 + "".join(f"-{method}{count}"
                                           for method, count in sorted(particles.items()))
                                 + (f"-{len(clips)}clips" if args.clips else "")
                                 + ("-quick" if args.quick else ""))
    out.mkdir(parents=True, exist_ok=True)

    started = time.perf_counter()
    # --quick: a small prior (2 views, 10 fps, 60 active points, one outer iteration)
    training = QUICK_TRAINING if args.quick else {}
    prior = candidate_prior(args.prior, args.mirror, args.parts, args.back_constraint,
                            args.latent_dim, **training)
    # --init auto takes its median background over the whole clip, as from a user's whole video,
    # then tracks the first --max-frames frames like every other run
    sequences = [sequence for index, clip in enumerate(clips)
                 for sequence in render_test_sequences(
                     clip, views=views, seed=index,
                     max_frames=None if args.init == "auto" else max_frames)]
    configs = configurations(args.quick, tuple(args.methods), tuple(args.estimates),
                             tuple(args.likelihoods))
    initial, inits = {}, []
    if args.init == "auto":
        for sequence in sequences:
            initial[sequence.name], record = auto_initial_markers(prior, sequence)
            inits.append(record)
            print(f"auto init {sequence.name}: " + (
                record.get("failed") or f"{record['source']}, overlap {record['overlap']:.2f}, "
                                        f"{record['error_torso']:.0%} of the torso off"))
        sequences = [dataclasses.replace(sequence, images=sequence.images[:max_frames],
                                         frames=sequence.frames[:max_frames],
                                         truth=sequence.truth[:max_frames])
                     for sequence in sequences if initial[sequence.name] is not None]
        if not sequences:
            print("the automatic initialisation found no one in any sequence; nothing to track")
            return 1
    detections, detector = {}, []
    if args.keypoints == "mediapipe":
        from jaxtrack.vision.mediapipe import detected_keypoints, run_mediapipe

        for sequence in sequences:
            found = run_mediapipe(sequence.images)
            if "skipped" in found:
                parser.error(f"--keypoints mediapipe, {sequence.name}: {found['skipped']}")
            detections[sequence.name] = detected_keypoints(found)
            # the detector alone, every frame (a frame without a person holds the last one)
            alone = evaluate_track(found["markers"], sequence.truth, UPPER_BODY_12)
            detector.append({"sequence": sequence.name,
                             **{key: alone[key] for key in ("mean_error_torso",
                                                            "fraction_within_15")}})
    jobs = [(sequence, config, seed) for config in configs for sequence in sequences
            for seed in range(seeds)]
    print(f"{len(configs)} configurations × {len(sequences)} sequences × {seeds} seeds = "
          f"{len(jobs)} runs on {args.split} subjects ({', '.join(clips)}); "
          f"{device_description()}")
    runs = []
    with open(out / "runs.jsonl", "w") as handle:
        for sequence, config, seed in tqdm(jobs, desc="tracking", unit="run"):
            run = run_one(prior, sequence, config, seed,
                          particles.get(config["method"], DEFAULT_PARTICLES[config["method"]]),
                          args.baseline_dynamics, initial.get(sequence.name), settings,
                          detections.get(sequence.name))
            runs.append(run)
            handle.write(json.dumps(run) + "\n")
            handle.flush()
    rows = summarise(runs)
    table = markdown_table(rows)
    print(table)
    init_note = "initialised from frame 0's truth"
    if args.init == "auto":
        found = [record for record in inits if "failed" not in record]
        init_note = (f"initialised automatically (jaxtrack track --init face) in "
                     f"{len(found)} of {len(inits)} sequences, the initial pose "
                     f"{statistics.mean(r['error_torso'] for r in found):.0%} of the torso off "
                     f"on average; the others are left out")
    note = (f"{args.split} subjects: {', '.join(clips)}; {len(sequences)} sequences × {seeds} "
            f"seeds; prior trained on {', '.join(training_clips)}"
            f"{' and their mirror images' if args.mirror else ''}"
            f"{', one GPLVM per body part' if args.parts else ''}"
            + ("" if args.back_constraint is None else
               f", back-constrained (width {args.back_constraint:g})")
            + ("" if args.latent_dim == 2 else f", {args.latent_dim}-D latent spaces")
            + f"{'; MediaPipe keypoints scored by the keypoint term' if detections else ''}"
            + "".join(f"; {SETTINGS[name]} {value:g}" for name, value in settings.items())
            + "; baselines' dynamics from "
            f"{args.baseline_dynamics}; {init_note}. error: mean over runs, "
            "± the 95 % t-interval; lost: error above 25 % of the torso for 10 frames in a row; "
            "ms/frame: median over runs; compile s: apart.")
    if detector:
        print(f"MediaPipe alone: {detector}")
        note += (" MediaPipe alone on the same sequences: "
                 f"{100 * statistics.mean(r['mean_error_torso'] for r in detector):.1f} % of the "
                 f"torso, {100 * statistics.mean(r['fraction_within_15'] for r in detector):.0f} "
                 "% of frames within 15 %.")
    (out / "table.md").write_text(table + "\n\n" + note + "\n")
    plot(rows, out / "errors.png", f"{args.split} subjects: mean marker error")
    write_json_atomically(out / "summary.json", {
        **run_header("papers.tian2005.tracking", argv, started),
        "split": args.split, "clips": list(clips), "prior": args.prior, "mirror": args.mirror,
        "parts": args.parts, "back_constraint": args.back_constraint,
        "latent_dim": args.latent_dim,
        "training_clips": list(training_clips),
        "seeds": seeds, "views": views, "max_frames": max_frames,
        "baseline_dynamics": args.baseline_dynamics, "init": args.init, "auto_init": inits,
        "keypoints": args.keypoints, "mediapipe_alone": detector,
        "settings": settings, "rows": rows})
    if wants_real_video(args, tag, settings):  # the rendered grid's outputs are already written
        real = real_video_table(out, tuple(args.methods), tuple(args.estimates))
        (out / "table.md").write_text(table + "\n\n" + note + "\n\n" + real + "\n")
    print(f"wrote {out}/ (runs.jsonl, summary.json, table.md, errors.png) in "
          f"{time.perf_counter() - started:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
