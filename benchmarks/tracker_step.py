"""Per-frame cost of the latent-space tracker (Tian, Li & Sclaroff 2005), component by component.

The tracker is built as ``jaxtrack demo`` and ``jaxtrack evaluate`` build it: the GPLVM trained
on the demo's three wave gestures (cached in ``benchmarks/results/gplvm_waves.npz``), frame 0 of
the held-out wave rendered over a photo, 200 (and 1 000) particles. Each component runs on the
particle cloud of a real tracking state (after a few tracked frames), jitted and compiled ahead
(compile time apart), the median of many calls with ``block_until_ready``:

    propagate   random walk of every particle (``model.propagate``, vmapped)
    mu          the GPLVM mean μ(x) of every particle's latent point
    features    link-vector features → 25-d SPM states (``states_from_features``)
    spm         SPM states → 12 markers (``spm_forward``)
    markers     features → 12 markers directly (``markers_from_features``, the model's path)
    decode      latent + placement → markers, as the model does it (μ, then markers)
    likelihood  the appearance log-likelihood of every particle's markers (nearest-pixel limb
                strips by default, ``--likelihood markers`` for eq. 7's patches)
    resample    systematic resampling of the weights
    step        one whole ``smc.step`` (select, propagate, decode, measure)
    estimate    the tracker's per-frame estimate (μ of the local mode's mean latent, best
                particle)
    arm search  the arm search that starts each refinement, for one candidate (7 × 7
                upper-arm × forearm angles per arm about the carried arm and 7 × 7 about
                its constant-velocity prediction, scored by the arm's two strips)
    refine      the full-state refinement of the reported pose (two candidates, each arm
                searched, then Gauss–Newton, ``refine_steps`` = 10)
    refine, no arm search
                the same with ``arm_grid = 0`` (Gauss–Newton alone)
    update      ``step`` + ``estimate`` + ``refine``: one frame of the tracker
    track       the per-frame cost inside ``track``'s compiled scan of 64-frame chunks
    track, paper's estimate
                the same scan with ``refine_steps = 0`` (the particle filter alone)
    track, no image
                the paper's-estimate scan with a stand-in likelihood that reads no pixel: the
                engine's own cost, below which no likelihood can bring the tracker
    track()     ``TrackResult.seconds_per_frame`` of ``track`` itself on the whole held-out
                clip (137 frames after frame 0, chunks of at most 64; host copies of the
                frames included), median of a few calls
    edge maps   (``limbs+edges``) ``vision.edge_observations`` per frame: Canny, the labelled
                distance transform and the edges' tangents (OpenCV, host)
    track() from grey
                (``limbs+edges``) ``track`` given grey frames, building the edge maps chunk by
                chunk itself: what ``jaxtrack evaluate`` and ``jaxtrack track`` pay per frame
    pipeline    ``jaxtrack.experiments.track_video`` on the same frames written to a video
                file (mp4v, at their own size): decoding chunk by chunk, grey conversion and
                ``track`` (the ``pipeline_seconds_per_frame`` it records: compilation and
                frame 0's set-up excluded, as ``track()``'s), called in turn with ``track()``
                given the grey frames in memory (``track() from grey, paired``); beside it
                ``track()``'s own ``seconds_per_frame`` inside the pipeline, and the median
                over the pairs of the pipeline's time over ``track()``'s in the same pair
                (one call here can take three times another of the same work, so only
                neighbouring calls are compared); and over what a user pays without the
                pipeline, the same pair's ``decode, then track()``: the whole video decoded
                to grey (``iter_video_chunks(grey=True)``), then ``track()``. On two cores the
                tracker's step keeps both busy, so decoding is not hidden behind it: the
                first ratio is the cost of decoding, the second the pipeline's own
    pipeline + overlay + JSON
                the whole call, the second decoding pass that draws the overlay and the JSON
                included (compilation excluded), per frame

Wall times on this shared machine move with other jobs: the load average is printed, and CPU
seconds (all threads of the process) are reported beside the wall times.

    python -m benchmarks.tracker_step                    # 200 and 1 000 particles, both likelihoods
    python -m benchmarks.tracker_step --particles 200 --likelihood markers --repeats 50
    python -m benchmarks.tracker_step --particles 200 --likelihood limbs+edges --track-only

``--profile``: where one frame of the latent tracker's compiled scan spends its time, stage by
stage and op by op (JAX's profiler on CPU XLA).

The tracker is built as ``benchmarks.tracker_step`` builds it (the demo's held-out wave over a
photo, ``limbs+edges`` with the median background, 200 particles). The chunk scan of
``jaxtrack.trackers.track`` is compiled ahead, timed without the profiler (median of
``--repeats`` runs), then run once under ``jax.profiler.trace``. Every op XLA executed is
matched to its HLO instruction, whose ``op_name`` carries the tracker's named scopes:

    filter        the particle filter's step and estimate (propagate, μ, strips, resample)
    candidates    μ of the particles' estimate: the second refinement candidate
    arm_search    the arm search of both candidates
    gauss_newton  the damped Gauss–Newton of both candidates
    choice        scoring the refined candidates and keeping the better one
    other         the scan's own bookkeeping

Control-flow thunks (while, conditional, call) are left out, their bodies being counted op by
op. The profiler slows every op down, so the table gives each stage's share of the traced
time and that share of the untraced ms per frame.

Second, the cost of dispatching an op, to tell a floor set by the number of ops from one set
by their work: a scan whose body is a chain of ``k`` rounds of three dependent tiny ops (a
gather, a sum, an 8 × 8 matrix–vector product), for a few ``k``; the slope is the cost per op.

    python -m benchmarks.tracker_step --profile   # table, top ops; writes results/profile_step.json
``--detections``: the same questions for CONDENSATION on a detector's output alone (issue 48:
"at most 5 ms per frame and view at 1 000 particles, compile time and detector time apart"):
``detection_tracking.detection_tracker`` (random walk in the 25-d SPM state, the density's
hand-set defaults) on MediaPipe's detections of the Pose2Sim demo's cam01 (99 frames,
``detections_evaluation.load_setting``). Rows: each piece of a frame compiled alone
(``propagate``, ``spm`` forward kinematics, ``density`` of every particle, ``resample``,
``step``), the chunk scan ``track`` compiles (per frame), and ``track()``'s own
``seconds_per_frame``; wall and CPU ms (medians), compile seconds apart. ``--against DIR``
(a checkout of another commit: ``git archive COMMIT | tar -x -C DIR``) runs the same
measurement there and here in turn, ``--rounds`` times each, and quotes medians and the
median of the paired ratios (``JAXTRACK_DATA`` must name the shared data for a checkout
outside this tree):

    JAXTRACK_DATA=/work/shared/data python -m benchmarks.tracker_step --detections \\
        --against /tmp/base --rounds 3
"""

from __future__ import annotations

import argparse
import collections
import dataclasses
import gzip
import itertools
import json
import os
import re
import statistics
import tempfile
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from benchmarks._common import device_description, print_table, time_compiled, write_json
from jaxtrack import smc
from jaxtrack.body import spm_forward
from jaxtrack.priors.poses import markers_from_features, states_from_features

RESULTS = Path(__file__).parent / "results"
CHUNK = 64
TRACK_CALLS = 5
PIPELINE_PAIRS = 9


def _load_average() -> float:
    return os.getloadavg()[0]


def build(num_particles: int, frames: int | None = None, seed: int = 0,
          likelihood: str = "limbs", images: list | None = None):
    """(tracker, observations, grey frames, frame 0's pose) for the demo's held-out wave,
    ``frames`` frames of it; the observations are grey frames, or grey frames with edge maps
    for ``"limbs+edges"``. ``images``: a list that receives the RGB frames."""
    from jaxtrack import trackers
    from jaxtrack.experiments import render_test_sequences
    from jaxtrack.experiments.demo import HELD_OUT_CLIP, TRAIN_CLIPS
    from jaxtrack.likelihoods import needs_edges
    from jaxtrack.priors.train import train_prior
    from jaxtrack.vision import edge_observations, median_grey_background

    prior = train_prior(TRAIN_CLIPS, cache=RESULTS / "gplvm_waves.npz", seed=seed,
                        progress=False)
    sequence = render_test_sequences(HELD_OUT_CLIP, views=1, backgrounds=("photo",),
                                     max_frames=frames, seed=seed)[0]
    if images is not None:
        images.append(np.asarray(sequence.images))
    # the compiled scan is timed on observations made beforehand (edge maps are OpenCV
    # preprocessing that track() does on the host; the "edge maps" row times them)
    observations = (edge_observations(sequence.frames) if needs_edges(likelihood)
                    else np.asarray(sequence.frames, np.float32))
    # as jaxtrack evaluate builds it: with limbs+edges, the foreground term against the
    # sequence's median background
    background = (median_grey_background(sequence.frames) if needs_edges(likelihood) else None)
    tracker = trackers.latent_tracker(prior.model, prior.template,
                                      engine=trackers.Engine(num_particles),
                                      fps=sequence.fps,
                                      likelihood=trackers.Likelihood(likelihood),
                                      background=background)
    return (tracker, observations, np.asarray(sequence.frames, np.float32),
            sequence.truth[0])


def _tracked_state(tracker, frames, initial_pose, steps: int = 8):
    """The tracker state after ``steps`` tracked frames (a realistic, spread particle cloud)."""
    from jaxtrack.trackers._runner import _chunk

    key_start, key_frames = jr.split(jr.PRNGKey(1))
    state = tracker.start(key_start, frames[0], initial_pose)
    state, _ = _chunk(tracker, state, jr.split(key_frames, steps), jnp.asarray(frames[1:steps + 1]))
    return state


class _NoImage(eqx.Module):
    """A stand-in likelihood that reads no pixel (it still uses the markers, so that the
    decoding is not optimised away): ``−10⁻⁶ |markers|²``."""

    def log_likelihood(self, markers, image, sharpness, nearest=True):
        del image, sharpness, nearest
        return -1e-6 * jnp.sum(jnp.square(markers))


def _chunk_arguments(tracker, state, frames) -> tuple:
    """The arguments of ``track``'s compiled chunk scan over frames 1 … CHUNK."""
    return (tracker, state, jr.split(jr.PRNGKey(3), CHUNK), jnp.asarray(frames[1:CHUNK + 1]))


def _scan_timing(tracker, state, frames, repeats: int) -> dict:
    """Per-frame wall and CPU ms of ``track``'s compiled scan over a chunk of CHUNK frames."""
    from jaxtrack.trackers._runner import _chunk

    arguments = _chunk_arguments(tracker, state, frames)
    tick = time.perf_counter()
    compiled = _chunk.lower(*arguments).compile()
    compile_s = time.perf_counter() - tick
    times, cpu_times = [], []
    for _ in range(max(repeats // 10, 5)):
        tick, cpu = time.perf_counter(), time.process_time()
        jax.block_until_ready(compiled(*arguments))
        times.append(time.perf_counter() - tick)
        cpu_times.append(time.process_time() - cpu)
    return {"compile_s": compile_s, "ms": 1e3 * statistics.median(times) / CHUNK,
            "cpu_ms": 1e3 * statistics.median(cpu_times) / CHUNK}


def pipeline_rows(tracker, images: np.ndarray, grey: np.ndarray, initial_pose
                  ) -> dict[str, dict]:
    """The video pipeline on ``images`` written to a video file, beside ``track()`` given the
    same clip's grey frames in memory, the two called in turn (a first call of each compiles;
    then PIPELINE_PAIRS pairs): rows ``track() from grey, paired``, ``pipeline`` and
    ``pipeline + overlay + JSON``. ``ratio`` is the median over the pairs of the pipeline's ms
    per frame over ``track()``'s in the same pair: on a shared machine one call can take three
    times another of the same work, so only calls made side by side are compared."""
    import tempfile

    from jaxtrack.experiments import track_video
    from jaxtrack.trackers import track
    from jaxtrack.vision import iter_video_chunks, write_frames

    with tempfile.TemporaryDirectory(prefix="jaxtrack-pipeline-") as folder:
        video = write_frames(images, Path(folder) / "clip.mp4", 30.0,
                             (images.shape[2], images.shape[1]))
        records, walls, own, decoded = [], [], [], []
        for seed in range(PIPELINE_PAIRS + 1):
            own.append(track(tracker, jr.PRNGKey(seed), grey, initial_pose, chunk_size=CHUNK,
                             progress=False).seconds_per_frame)
            # what a user pays without the pipeline: decode the whole video, then track()
            tick = time.perf_counter()
            frames = np.concatenate([chunk.frames for chunk in iter_video_chunks(
                video, CHUNK, grey=True)])
            decode = (time.perf_counter() - tick) / len(frames)
            decoded.append(decode + track(tracker, jr.PRNGKey(seed), frames, initial_pose,
                                          chunk_size=CHUNK, progress=False).seconds_per_frame)
            tick = time.perf_counter()
            records.append(track_video(tracker, video, Path(folder) / "out",
                                       key=jr.PRNGKey(seed), initial_pose=initial_pose,
                                       scale=1.0, chunk_frames=CHUNK, progress=False))
            walls.append(time.perf_counter() - tick - records[-1]["timings"]["compile_seconds"])
    frames = len(images)
    pipeline = [r["timings"]["pipeline_seconds_per_frame"] for r in records[1:]]
    own, decoded = own[1:], decoded[1:]
    whole = [wall / frames for wall in walls[1:]]
    return {
        "track() from grey, paired": {"compile_s": None, "cpu_ms": None,
                                      "ms": 1e3 * statistics.median(own)},
        "decode, then track()": {"compile_s": None, "cpu_ms": None,
                                 "ms": 1e3 * statistics.median(decoded),
                                 "ratio": statistics.median(d / o for d, o in zip(
                                     decoded, own, strict=True))},
        "pipeline": {"compile_s": records[0]["timings"]["compile_seconds"], "cpu_ms": None,
                     "ms": 1e3 * statistics.median(pipeline),
                     "track_ms": 1e3 * statistics.median(
                         r["timings"]["seconds_per_frame"] for r in records[1:]),
                     "ratio": statistics.median(p / o for p, o in zip(pipeline, own,
                                                                      strict=True)),
                     "ratio_to_decode_then_track": statistics.median(
                         p / d for p, d in zip(pipeline, decoded, strict=True))},
        "pipeline + overlay + JSON": {"compile_s": None, "cpu_ms": None,
                                      "ms": 1e3 * statistics.median(whole),
                                      "ratio": statistics.median(w / o for w, o in zip(
                                          whole, own, strict=True))},
    }


def components(tracker, frames, initial_pose, repeats: int) -> dict[str, dict]:
    """Compile and time each component on the same tracked state; ``{name: timings}``."""
    from jaxtrack.trackers import Refinement, search_arms
    from jaxtrack.trackers._refinement import _predicted

    paper = dataclasses.replace(tracker, refinement=None)
    tracker_state = _tracked_state(tracker, frames, initial_pose)
    paper_state = dataclasses.replace(tracker_state, refined=None, refine_std=None)
    model = tracker_state.model
    state = tracker_state.filter
    particles, log_weights = state.particles, state.log_weights
    frame = jnp.asarray(frames[9])
    key = jr.PRNGKey(2)
    num = tracker.num_particles
    latents, placements = particles["latent"], particles["placement"]
    features = jax.vmap(model.prior.mean)(latents)
    states = jax.vmap(states_from_features, in_axes=(0, 0, None))(features, placements,
                                                                   model.template)
    markers = jax.vmap(spm_forward, in_axes=(0, None))(states, model.template)

    def propagate(key, particles):
        return jax.vmap(model.propagate, in_axes=(0, 0, None))(jr.split(key, num), particles, 1)

    def mean(latents):
        return jax.vmap(model.prior.mean)(latents)

    def to_states(features, placements):
        return jax.vmap(states_from_features, in_axes=(0, 0, None))(features, placements,
                                                                    model.template)

    def forward(states):
        return jax.vmap(spm_forward, in_axes=(0, None))(states, model.template)

    def direct(features, placements):
        return jax.vmap(markers_from_features)(features, placements)

    def decode(particles):
        return jax.vmap(model.markers_of)(particles)

    def likelihood(markers, frame):
        return jax.vmap(model.templates.log_likelihood, in_axes=(0, None, None, None))(
            markers, frame, model.sharpness, model.nearest)

    def resample(key, log_weights):
        return smc.Systematic()(key, log_weights)

    def step(key, state, frame):
        return smc.step(key, state, frame, model)

    def estimate(state, info):
        return tracker._cloud(model, state, info)

    def search(carried, frame):
        arms = tracker.refinement.arm_search
        return search_arms(arms, carried.refined.pose, frame, model.templates, model.template,
                           model.sharpness, _predicted(arms, carried.refined))

    def refine(carried, filtered, estimate, frame):
        return tracker._report(carried, filtered, estimate, frame)

    def refine_only(carried, filtered, estimate, frame):
        no_search = Refinement(steps=tracker.refinement.steps,
                               prior_std=tracker.refinement.prior_std, arm_search=None)
        return dataclasses.replace(tracker, refinement=no_search)._report(carried, filtered,
                                                                          estimate, frame)

    def update(key, state, frame):
        return tracker.update(key, state, frame)

    filtered, info = jax.jit(lambda *arguments: step(*arguments))(key, state, frame)
    frame_estimate = jax.jit(estimate)(filtered, info)
    cases = {
        "propagate": (propagate, key, particles),
        "mu": (mean, latents),
        "features": (to_states, features, placements),
        "spm": (forward, states),
        "markers": (direct, features, placements),
        "decode": (decode, particles),
        "likelihood": (likelihood, markers, frame),
        "resample": (resample, key, log_weights),
        "step": (step, key, state, frame),
        "estimate": (estimate, state, info),
        "arm search": (search, tracker_state, frame),
        "refine": (refine, tracker_state, filtered, frame_estimate, frame),
        "refine, no arm search": (refine_only, tracker_state, filtered, frame_estimate,
                                  frame),
        "update": (update, key, tracker_state, frame),
    }
    rows = {}
    for name, (function, *arguments) in cases.items():
        compile_s, wall_s, cpu_s, _ = time_compiled(function, *arguments, repeats=repeats)
        rows[name] = {"compile_s": compile_s, "ms": 1e3 * wall_s, "cpu_ms": 1e3 * cpu_s}

    rows["track"] = _scan_timing(tracker, tracker_state, frames, repeats)
    rows["track, paper's estimate"] = _scan_timing(paper, paper_state, frames, repeats)
    # the same scan with a likelihood that reads no pixel: what is left is the engine's own
    # cost (draws, μ, decoding, resampling, estimate), the floor of any likelihood's ms/frame
    blind = eqx.tree_at(lambda s: s.model.templates, paper_state, _NoImage())
    rows["track, no image"] = _scan_timing(paper, blind, frames, repeats)

    return rows


def track_rows(tracker, frames, initial_pose, grey=None, images: np.ndarray | None = None
               ) -> dict[str, dict]:
    """``track()`` on the whole clip (from observations made beforehand, and from grey frames
    where those differ) and the pipeline's rows beside it; ``{name: timings}``."""
    from jaxtrack.trackers import track

    rows = {}
    # the whole clip through track() itself: a first call (which compiles the chunk shape),
    # then the median of the timed ones
    results = [track(tracker, jr.PRNGKey(seed), frames, initial_pose, chunk_size=CHUNK,
                     progress=False) for seed in range(TRACK_CALLS + 1)]
    rows["track()"] = {"compile_s": results[0].compile_seconds,
                       "ms": 1e3 * statistics.median(r.seconds_per_frame for r in results[1:]),
                       "cpu_ms": None}
    if grey is not None and grey.shape != frames.shape:
        from jaxtrack.vision import edge_observations

        times = []
        for _ in range(TRACK_CALLS):
            tick = time.perf_counter()
            edge_observations(grey)
            times.append((time.perf_counter() - tick) / len(grey))
        rows["edge maps"] = {"compile_s": None, "ms": 1e3 * statistics.median(times),
                             "cpu_ms": None}
        results = [track(tracker, jr.PRNGKey(seed), grey, initial_pose, chunk_size=CHUNK,
                         progress=False) for seed in range(TRACK_CALLS)]
        rows["track() from grey"] = {
            "compile_s": None, "cpu_ms": None,
            "ms": 1e3 * statistics.median(r.seconds_per_frame for r in results)}
    if images is not None:  # beside track() given the same grey frames in memory
        rows.update(pipeline_rows(tracker, images, frames if grey is None else grey,
                                  initial_pose))
    return rows



STAGES = ("filter", "candidates", "arm_search", "gauss_newton", "choice")
_CONTROL_FLOW = {"while", "conditional", "call"}


def _instructions(hlo: str) -> dict[str, tuple[str, str]]:
    """``{instruction name: (opcode, op_name)}`` of an optimised HLO module's text."""
    found = {}
    pattern = re.compile(r"^\s*(?:ROOT )?%([\w.\-]+) = .*?\s([a-z][\w\-]*)\((.*)$", re.M)
    for match in pattern.finditer(hlo):
        name, opcode, rest = match.groups()
        scope = re.search(r'op_name="([^"]*)"', rest)
        found.setdefault(name, (opcode, scope.group(1) if scope else ""))
    return found


def _stage(op_name: str) -> str:
    for stage in STAGES:
        if re.search(rf"(^|[/(]){stage}[/)]", op_name):
            return stage
    return "other"


def _trace_events(directory: Path) -> list[dict]:
    paths = sorted(directory.glob("plugins/profile/*/*.trace.json.gz"))
    if not paths:
        raise RuntimeError(f"jax.profiler wrote no trace.json.gz under {directory}")
    with gzip.open(paths[-1]) as handle:
        return [event for event in json.load(handle)["traceEvents"] if event.get("ph") == "X"]


def profile_chunk(tracker, frames, initial_pose, repeats: int) -> dict:
    """Untraced ms per frame of the chunk scan, and the traced ops grouped by stage."""
    from jaxtrack.trackers._runner import _chunk

    arguments = _chunk_arguments(tracker, _tracked_state(tracker, frames, initial_pose), frames)
    compiled = _chunk.lower(*arguments).compile()
    instructions = _instructions(compiled.compiled.as_text())
    jax.block_until_ready(compiled(*arguments))
    times = []
    for _ in range(repeats):
        tick = time.perf_counter()
        jax.block_until_ready(compiled(*arguments))
        times.append((time.perf_counter() - tick) / CHUNK)
    with tempfile.TemporaryDirectory() as directory:
        with jax.profiler.trace(directory):
            jax.block_until_ready(compiled(*arguments))
        events = _trace_events(Path(directory))
    stages = collections.defaultdict(lambda: {"ops": 0, "us": 0.0})
    ops = collections.defaultdict(lambda: {"count": 0, "us": 0.0, "stage": "", "op_name": ""})
    for event in events:
        opcode, op_name = instructions.get(event["name"], (None, ""))
        if opcode is None or opcode in _CONTROL_FLOW:
            continue
        stage = _stage(op_name)
        stages[stage]["ops"] += 1
        stages[stage]["us"] += event["dur"]
        op = ops[event["name"]]
        op["count"] += 1
        op["us"] += event["dur"]
        op["stage"], op["op_name"] = stage, op_name
    traced_us = sum(stage["us"] for stage in stages.values())
    ms = 1e3 * statistics.median(times)
    if traced_us == 0:
        raise RuntimeError("the trace holds no op of the compiled scan")
    table = {name: {"ops_per_frame": value["ops"] / CHUNK,
                    "share": value["us"] / traced_us,
                    "ms_per_frame": ms * value["us"] / traced_us}
             for name, value in sorted(stages.items(), key=lambda item: -item[1]["us"])}
    top = [{"op": name, "stage": value["stage"], "per_frame": value["count"] / CHUNK,
            "share": value["us"] / traced_us, "op_name": value["op_name"]}
           for name, value in sorted(ops.items(), key=lambda item: -item[1]["us"])[:15]]
    return {"ms_per_frame": ms, "ops_per_frame": sum(v["ops"] for v in stages.values()) / CHUNK,
            "stages": table, "top_ops": top}


def dispatch_cost(rounds=(0, 16, 64, 256), repeats: int = 30) -> dict:
    """µs per scan step of a chain of ``k`` rounds of three dependent tiny ops, and the
    fitted µs per op."""
    rng = np.random.default_rng(0)
    matrix = jnp.asarray(rng.normal(size=(8, 8)) / 3, jnp.float32)
    table = jnp.linspace(0, 1, 4096, dtype=jnp.float32)
    step_us = {}
    for count in rounds:
        def body(x, _, count=count):
            for _ in range(count):
                index = (jnp.abs(x[:4]) * 4000).astype(jnp.int32)
                x = x + jnp.take(table, index, mode="clip").sum()
                x = jnp.tanh(matrix @ x)
            return x, x[0]

        run = jax.jit(lambda x, body=body: jax.lax.scan(body, x, None, length=CHUNK))
        start = jnp.ones(8, jnp.float32)
        compiled = run.lower(start).compile()
        jax.block_until_ready(compiled(start))
        times = []
        for _ in range(repeats):
            tick = time.perf_counter()
            jax.block_until_ready(compiled(start))
            times.append(time.perf_counter() - tick)
        step_us[count] = 1e6 * statistics.median(times) / CHUNK
    slope = np.polyfit(list(step_us), list(step_us.values()), 1)[0]
    return {"step_us": step_us, "us_per_op": float(slope) / 3}

def profile_main(args) -> None:
    """``--profile``: the chunk scan's time by stage and op, and the cost of dispatching an op."""
    particles = args.particles[0]
    tracker, frames, _, initial_pose = build(particles, likelihood="limbs+edges")
    load = _load_average()
    profile = profile_chunk(tracker, frames, initial_pose, args.repeats)
    dispatch = dispatch_cost()
    print(f"{device_description()}, load {load:.2f}")
    print(f"\nlatent tracker, {particles} particles: {profile['ms_per_frame']:.2f} ms and "
          f"{profile['ops_per_frame']:.0f} ops per frame in the scan\n")
    print_table([{"stage": name, **row, "share": 100 * row["share"]}
                 for name, row in profile["stages"].items()],
                [("stage", "stage", "s"), ("ops_per_frame", "ops/frame", ".0f"),
                 ("share", "share %", ".1f"), ("ms_per_frame", "ms/frame", ".3f")])
    print("\ncostliest ops:\n")
    print_table([{**op, "share": 100 * op["share"],
                  "from": op["op_name"].split("closed_call/")[-1][-60:]}
                 for op in profile["top_ops"]],
                [("op", "op", "s"), ("stage", "stage", "s"), ("per_frame", "runs/frame", ".0f"),
                 ("share", "share %", ".1f"), ("from", "from", "s")])
    print(f"\ndispatch: {dispatch['us_per_op']:.3f} µs per op (scan steps of k rounds: "
          + ", ".join(f"k={k} {us:.1f} µs" for k, us in dispatch["step_us"].items()) + ")")
    print(f"the tracker's {profile['ops_per_frame']:.0f} ops per frame at that cost: "
          f"{profile['ops_per_frame'] * dispatch['us_per_op'] / 1e3:.3f} ms")
    write_json(args.output or str(RESULTS / "profile_step.json"),
               {"device": device_description(), "load_average": load, "particles": particles,
                "profile": profile, "dispatch": dispatch})



DETECTION_VIEW = "cam01"
DETECTION_REPEATS = 30  # calls of each compiled piece
DETECTION_TRACK_CALLS = 5  # track() calls after the one that compiles


def build_detections(num_particles: int):
    """(tracker, observations, frame 0's pose) for CONDENSATION on cam01's MediaPipe
    detections, as ``detections_evaluation`` builds its filter (unfitted: the fit changes
    the density's numbers, not its cost)."""
    from jaxtrack.experiments.detection_tracking import (
        _pose2sim_view,
        detection_tracker,
        initial_pose_of,
    )
    from jaxtrack.experiments.detections_evaluation import load_setting
    from jaxtrack.trackers._particles import detection_observations

    setting = load_setting()
    camera = setting.cameras[setting.views.index(DETECTION_VIEW)]
    detections = _pose2sim_view(setting, DETECTION_VIEW,
                                tuple(float(v) for v in camera.image_size))
    observations = detection_observations(detections)
    pose = initial_pose_of(observations.detections)
    return detection_tracker(pose, num_particles=num_particles), observations, pose


def _timed(function, *arguments, repeats: int = DETECTION_REPEATS) -> dict:
    compile_s, wall_s, cpu_s, _ = time_compiled(function, *arguments, repeats=repeats)
    return {"compile_s": compile_s, "ms": 1e3 * wall_s, "cpu_ms": 1e3 * cpu_s}


def detection_rows(num_particles: int) -> dict[str, dict]:
    """Each piece of a frame of the detection tracker, its chunk scan and ``track()``."""
    from jaxtrack.trackers import track
    from jaxtrack.trackers._particles import device_observation
    from jaxtrack.trackers._runner import _chunk

    tracker, observations, pose = build_detections(num_particles)
    frames = device_observation(observations)
    count = int(frames.detections.num_people.shape[0])
    # a realistic cloud: the state after 8 tracked frames
    state = tracker.start(jr.PRNGKey(0), jax.tree.map(lambda leaf: leaf[0], frames), pose)
    state, _ = _chunk(tracker, state, jr.split(jr.PRNGKey(1), 8),
                      jax.tree.map(lambda leaf: leaf[1:9], frames))
    model, cloud = state.model, state.filter
    frame = jax.tree.map(lambda leaf: leaf[10], frames)
    markers = jax.vmap(model.markers_of)(cloud.particles)
    rows = {
        "propagate": _timed(lambda key, particles: jax.vmap(
            model.propagate, in_axes=(0, 0, None))(jr.split(key, num_particles), particles, 1),
            jr.PRNGKey(2), cloud.particles),
        "spm": _timed(jax.vmap(model.markers_of), cloud.particles),
        "density": _timed(lambda markers, frame: jax.vmap(
            model.templates.log_likelihood, in_axes=(0, None, None, None))(
                markers, frame, model.sharpness, model.nearest), markers, frame),
        "resample": _timed(lambda key, log_weights: smc.Systematic()(key, log_weights),
                           jr.PRNGKey(3), cloud.log_weights),
        "step": _timed(lambda key, cloud, frame: tracker.engine.step(key, cloud, frame, model),
                       jr.PRNGKey(4), cloud, frame),
    }
    # the chunk scan track() compiles, over the video's frames after frame 0 (one chunk)
    arguments = (tracker, state, jr.split(jr.PRNGKey(5), count - 1),
                 jax.tree.map(lambda leaf: leaf[1:], frames))
    tick = time.perf_counter()
    compiled = _chunk.lower(*arguments).compile()
    compile_s = time.perf_counter() - tick
    walls, cpus = [], []
    for _ in range(DETECTION_TRACK_CALLS + 1):
        tick, cpu = time.perf_counter(), time.process_time()
        jax.block_until_ready(compiled(*arguments))
        walls.append(time.perf_counter() - tick)
        cpus.append(time.process_time() - cpu)
    rows["scan"] = {"compile_s": compile_s, "ms": 1e3 * statistics.median(walls[1:]) / (count - 1),
                    "cpu_ms": 1e3 * statistics.median(cpus[1:]) / (count - 1)}
    results, cpus = [], []
    for seed in range(DETECTION_TRACK_CALLS + 1):
        cpu = time.process_time()
        results.append(track(tracker, jr.PRNGKey(seed), observations, pose, progress=False))
        cpus.append((time.process_time() - cpu) / (count - 1))
    rows["track()"] = {"compile_s": results[0].compile_seconds,
                       "ms": 1e3 * statistics.median(r.seconds_per_frame for r in results[1:]),
                       "cpu_ms": 1e3 * statistics.median(cpus[1:])}
    return rows


DETECTION_COLUMNS = [("component", "component", "s"), ("ms", "wall ms", ".3f"),
                     ("cpu_ms", "cpu ms", ".3f"), ("compile_s", "compile s", ".2f")]


def _source_commit(folder: Path) -> str:
    import subprocess

    done = subprocess.run(["git", "-C", str(folder), "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True)
    return done.stdout.strip() or "unknown"


def detections_main(args) -> None:
    """``--detections``: the detection tracker's rows, here, or here and in ``--against`` in
    turn."""
    import subprocess
    import sys

    import jaxtrack

    particles = args.particles[0]
    output = args.output or str(RESULTS / "detection_step.json")
    if args.against is None:
        load = _load_average()
        rows = detection_rows(particles)
        record = {"device": device_description(), "particles": particles,
                  "view": DETECTION_VIEW, "load_average": [load, _load_average()],
                  "jaxtrack": str(Path(jaxtrack.__file__).parent),
                  "commit": _source_commit(Path(jaxtrack.__file__).parent), "rows": rows}
        if not args.quiet:
            print(f"detection tracker, {particles} particles, {DETECTION_VIEW} "
                  f"({record['commit']}, load {load:.1f})")
            print_table([{"component": name, **row} for name, row in rows.items()],
                        DETECTION_COLUMNS)
        write_json(output, record)
        return
    here = Path(__file__).resolve().parents[1]
    trees = {"against": Path(args.against).resolve(), "here": here}
    runs: dict[str, list] = {name: [] for name in trees}
    with tempfile.TemporaryDirectory(prefix="jaxtrack-detection-step-") as folder:
        for round_ in range(args.rounds):
            for name, tree in trees.items():
                path = Path(folder) / f"{name}{round_}.json"
                # this file run as a script in ``tree``: its jaxtrack and benchmarks come first
                env = {**os.environ, "PYTHONPATH": str(tree)}
                subprocess.run([sys.executable, str(Path(__file__).resolve()), "--detections",
                                "--quiet", "--particles", str(particles), "--output",
                                str(path)], cwd=tree, env=env, check=True)
                runs[name].append(json.loads(path.read_text()))
                print(f"round {round_ + 1}/{args.rounds}: {name} ({runs[name][-1]['commit']}) "
                      f"track() {runs[name][-1]['rows']['track()']['ms']:.2f} ms/frame, load "
                      f"{runs[name][-1]['load_average'][0]:.1f}", flush=True)
    summary = {}
    for name, records in runs.items():
        summary[name] = {row: {key: statistics.median(r["rows"][row][key] for r in records)
                               for key in ("ms", "cpu_ms", "compile_s")}
                         for row in records[0]["rows"]}
        print(f"\n{name}: {records[0]['commit']} ({records[0]['jaxtrack']}), medians of "
              f"{len(records)} runs")
        print_table([{"component": row, **values} for row, values in summary[name].items()],
                    DETECTION_COLUMNS)
    ratios = {row: statistics.median(h["rows"][row]["ms"] / a["rows"][row]["ms"] for h, a in
                                     zip(runs["here"], runs["against"], strict=True))
              for row in summary["here"]}
    print("\nhere / against, median of the paired ratios (wall ms): " + ", ".join(
        f"{row} {value:.3f}" for row, value in ratios.items()))
    write_json(output, {"device": device_description(), "particles": particles,
                        "view": DETECTION_VIEW, "rounds": args.rounds, "summary": summary,
                        "paired_ratio_here_over_against": ratios, "runs": runs})
    print(f"wrote {output}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--particles", type=int, nargs="+", default=None,
                        help="default 200 and 1000 (--detections: 1000)")
    parser.add_argument("--repeats", type=int, default=200)
    parser.add_argument("--likelihood", nargs="+",
                        choices=("limbs+edges", "limbs", "markers"),
                        default=["limbs+edges", "limbs", "markers"])
    parser.add_argument("--track-only", action="store_true",
                        help="only the track() and pipeline rows (no component timings)")
    parser.add_argument("--frames", type=int, default=None,
                        help="frames of the clip (default: all 138)")
    parser.add_argument("--profile", action="store_true",
                        help="profile the chunk scan by stage and op instead (first --particles; "
                             "--repeats 10 is plenty)")
    parser.add_argument("--output", default=None,
                        help="JSON (default results/tracker_step.json, profile_step.json or "
                             "detection_step.json)")
    parser.add_argument("--detections", action="store_true",
                        help="CONDENSATION on cam01's MediaPipe detections instead (first "
                             "--particles)")
    parser.add_argument("--against", default=None,
                        help="with --detections: a checkout of another commit, measured in "
                             "turn with this one")
    parser.add_argument("--rounds", type=int, default=3,
                        help="with --against: runs of each checkout")
    parser.add_argument("--quiet", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.detections:
        if args.rounds < 1:
            parser.error(f"--rounds must be at least 1, got {args.rounds}")
        if args.against is not None and not (Path(args.against) / "jaxtrack").is_dir():
            parser.error(f"--against {args.against}: no jaxtrack package there; give a "
                         f"checkout of another commit (git archive COMMIT | tar -x -C DIR)")
        args.particles = args.particles or [1000]
        detections_main(args)
        return
    args.particles = args.particles or [200, 1000]
    if args.profile:
        profile_main(args)
        return
    args.output = args.output or str(RESULTS / "tracker_step.json")

    device = device_description()
    cores = len(os.sched_getaffinity(0))
    print(f"device: {device}; this process may run on {cores} core(s)")
    frames_needed = args.frames  # None: the whole clip (138 frames at 30 fps)
    results = {}
    for likelihood, num_particles in itertools.product(args.likelihood, args.particles):
        images = []
        tracker, frames, grey, initial_pose = build(num_particles, frames_needed,
                                                    likelihood=likelihood, images=images)
        load_before = _load_average()
        rows = {} if args.track_only else components(tracker, frames, initial_pose,
                                                     args.repeats)
        rows.update(track_rows(tracker, frames, initial_pose, grey, images[0]))
        load_after = _load_average()
        print(f"\nlatent tracker, {likelihood}, {num_particles} particles, {grey.shape[2]}x"
              f"{grey.shape[1]} frames (load average {load_before:.2f} → {load_after:.2f})")
        table = [{"component": name, **row} for name, row in rows.items()]
        print_table(table, [("component", "component", "s"), ("ms", "wall ms", ".3f"),
                            ("cpu_ms", "cpu ms", ".3f"), ("compile_s", "compile s", ".2f"),
                            ("track_ms", "its track() ms", ".3f"),
                            ("ratio", "÷ track() from grey, paired", ".3f"),
                            ("ratio_to_decode_then_track", "÷ decode, then track()", ".3f")])
        results[f"{likelihood}/{num_particles}"] = {"load_average": [load_before, load_after],
                                                    "components": rows}
    write_json(args.output, {"device": device, "cores": cores, "repeats": args.repeats,
                             "chunk": CHUNK,
                             "results": results})
    print(f"\nwrote {args.output}")


if __name__ == "__main__":
    main()
