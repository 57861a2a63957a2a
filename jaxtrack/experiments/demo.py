"""The demo (``jaxtrack demo``), the main job: Tian, Li & Sclaroff's latent-space tracker against
standard CONDENSATION on a real wave by a person the prior has never seen.

1. Train (or load the cached) GPLVM on the training subjects' bundled real wave gestures
   (AnimatedDrawings optical mocap, MIT; :mod:`jaxtrack.data.splits`), projected from five
   viewpoints: Algorithm 1 of the paper.
2. Render a wave by a held-out test subject (``cmu_1006``, never in training) over a real photo
   background, with exact 2-D ground truth.
3. Track it with the latent tracker (200 particles) and with CONDENSATION in the full 25-d SPM
   state (1 000 particles; AR(2) dynamics learned from the same training poses), both
   initialised from frame 0's ground truth and scored by the same likelihood (limb strips and
   their edges), each with 3 seeds; each reports the filter's own estimate and, in a second
   run, the same full-state refinement stage (the latent tracker's default).
4. Print a comparison table; write overlay videos, the latent-space plot, the error plot and the
   metrics (JSON) to ``./jaxtrack-demo/``. The video and the error plot show the two methods
   alike, each with the refinement.

Frame 0 is not error-free for every run although each starts from frame 0's truth: frame 0's
report is the pose as each tracker holds it (``Tracker.first_estimate``), before any frame has
been observed or refined. The latent tracker holds it as a cloud about μ⁻¹(truth), so its frame
0 is the prior's reconstruction of this new person's pose (and the cloud's spread) decoded by
μ: the offset is the prior's error on a person it never saw, the same error its own estimate
carries later. CONDENSATION holds a cloud about the true state itself.
"""

from __future__ import annotations

import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

HISTORY = "animateddrawings/history_c119d6b/"
TRAIN_CLIPS = ("animateddrawings/fair1_wave_hello", HISTORY + "8yr_old_wave_hello")
HELD_OUT_CLIP = HISTORY + "cmu_1006_wave_hello_2"
# (label, method, particles, refinement: "none" the filter's own estimate, "shared" Refinement())
RUNS = (("latent", "latent", 200, "none"), ("latent + refinement", "latent", 200, "shared"),
        ("condensation", "condensation", 1000, "none"),
        ("condensation + refinement", "condensation", 1000, "shared"))
# the overlay video's and error plot's runs: like with like, both with the same refinement
SHOWN = ("latent + refinement", "condensation + refinement")
REPEATS = 3  # tracker seeds per method: the table shows the first, the summary all


def _decoder(prior):
    """Latent point → 12 image markers at a fixed placement (for the latent-space plot)."""
    from jaxtrack.body import spm_forward
    from jaxtrack.priors.poses import states_from_features

    model = prior.model.astype(jnp.float32)
    template = jax.tree.map(lambda leaf: jnp.asarray(leaf, jnp.float32), prior.template)
    placement = jnp.array([np.log(100.0), 0.0, 0.0], jnp.float32)

    @jax.jit
    def decode(latent):
        state = states_from_features(model.mean(latent), placement, template)
        return spm_forward(state, template)

    return lambda latent: np.asarray(decode(jnp.asarray(latent, jnp.float32)))


def _latent_plots(prior, output: Path) -> list[Path]:
    """The latent-space figure: one for a whole-body GPLVM, one per part for a
    :class:`~jaxtrack.priors.gplvm.PartsGPLVM` (each part's latent varied, the others held at
    the first training pose's)."""
    from jaxtrack.body import MARKER_EDGES, UPPER_BODY_12
    from jaxtrack.priors.gplvm import PartsGPLVM, plot_latent_space

    edges, labels = MARKER_EDGES[UPPER_BODY_12], prior.labels or None
    decode = _decoder(prior)
    if not isinstance(prior.model, PartsGPLVM):
        return [plot_latent_space(prior.model, output / "latent_space.png", labels=labels,
                                  decode=decode, edges=edges)]
    base = np.asarray(prior.model.latents[0], np.float64)
    paths, offset = [], 0
    for part, name in zip(prior.model.parts, prior.model.names, strict=True):
        def decode_part(latent, offset=offset, size=part.latent_dim):
            full = base.copy()
            full[offset:offset + size] = latent
            return decode(full)

        paths.append(plot_latent_space(
            part, output / f"latent_space_{name}.png", labels=labels, decode=decode_part,
            edges=edges, title=f"{name.replace('_', ' ')}: GPLVM latent space "
                               f"({part.latents.shape[0]} poses, {part.active_size} active)"))
        offset += part.latent_dim
    return paths


def run_demo(seed: int = 0, output_dir: str | Path = "jaxtrack-demo") -> int:
    """Run the four steps above, printing progress and the comparison; returns 0."""
    from jaxtrack._files import write_json_atomically
    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.data.splits import check_disjoint, split_of
    from jaxtrack.evaluation import (
        compare_methods,
        evaluate_track,
        plot_errors_over_time,
    )
    from jaxtrack.experiments import render_test_sequences, run_method
    from jaxtrack.priors.train import train_prior
    from jaxtrack.trackers import Refinement
    from jaxtrack.vision import write_overlay_video

    started = time.perf_counter()
    output = Path(output_dir)
    output.mkdir(parents=True, exist_ok=True)
    check_disjoint(TRAIN_CLIPS, [HELD_OUT_CLIP])
    cache = output / "gplvm_waves.npz"
    print(f"[1/4] GPLVM on {len(TRAIN_CLIPS)} real wave gestures of training subjects × 5 views "
          f"({'cached' if cache.exists() else 'training'}: {cache}) ...")
    prior = train_prior(TRAIN_CLIPS, cache=cache, seed=seed)
    print(f"      {prior.description['num_poses']} poses, active set {prior.model.active_size}, "
          f"ν = {np.round(np.asarray(prior.model.dynamics_std), 3).tolist()} per frame "
          f"at {float(prior.model.dynamics_fps):.0f} fps")
    print(f"[2/4] rendering {HELD_OUT_CLIP}, a wave by a test subject the prior never saw "
          f"(real photo background) ...")
    sequence = render_test_sequences(HELD_OUT_CLIP, views=1, backgrounds=("photo",),
                                     seed=seed)[0]
    print(f"      {len(sequence.frames)} frames, {sequence.frames.shape[2]}x"
          f"{sequence.frames.shape[1]} at {sequence.fps:.0f} fps")
    print(f"[3/4] tracking (seeds {seed}–{seed + REPEATS - 1}; videos and plots show seed "
          f"{seed}) ...")
    results, metrics, repeats = {}, {}, {}
    for label, method, particles, stage in RUNS:
        refinement = Refinement() if stage == "shared" else None
        runs = [run_method(method, prior, sequence, particles=particles, seed=seed + offset,
                           refinement=refinement) for offset in range(REPEATS)]
        results[label] = runs[0]
        metrics[label], *others = [evaluate_track(
            run.markers, sequence.truth, UPPER_BODY_12, seconds_per_frame=run.seconds_per_frame,
            compile_seconds=run.compile_seconds) for run in runs]
        metrics[label]["particles"] = particles
        # the first run pays one-off costs (first touches of the frame buffers): median of all
        metrics[label]["ms_per_frame"] = float(np.median([1e3 * run.seconds_per_frame
                                                          for run in runs]))
        repeats[label] = [{key: row[key] for key in ("mean_error_torso", "fraction_within_15",
                                                     "failed", "frames_tracked")}
                          for row in (metrics[label], *others)]
    print()
    print(f"held-out subject's wave ({len(sequence.frames)} frames), initialised from frame 0's "
          f"truth; seed {seed}, ms/frame the median over the seeds")
    print(compare_methods({f"{label} (N={particles})": metrics[label]
                           for label, _, particles, _ in RUNS}))
    print("  lost: the error stayed above 25 % of the torso for 10 frames in a row; "
          "followed: the frames before that")
    print("  + refinement: the same Gauss–Newton refinement of the reported pose in the full "
          "state for both methods")
    print("  frame 0 is each tracker's pose before it has seen a frame: the latent tracker's is "
          "its prior's reconstruction of the true pose (its error on a new person)")
    for label, *_ in RUNS:
        row = metrics[label]
        print(f"  {label:26s} followed {row['frames_tracked']} of {row['num_frames']} frames, "
              f"compile {row['compile_seconds']:.1f} s")
    print(f"over seeds {seed}–{seed + REPEATS - 1} (one seed is a noisy estimate: the error "
          f"moves by several % of the torso between seeds):")
    for label, *_ in RUNS:
        runs = repeats[label]
        errors = [run["mean_error_torso"] for run in runs]
        print(f"  {label:26s} error {100 * np.mean(errors):.1f} % of torso "
              f"({', '.join(f'{100 * e:.1f}' for e in errors)}), within 15 % "
              f"{100 * np.mean([run['fraction_within_15'] for run in runs]):.0f} %, lost in "
              f"{sum(run['failed'] for run in runs)} of {len(runs)}")
    print("[4/4] writing the overlay videos and plots ...")
    written = [
        write_overlay_video(sequence.images, {m: results[m].markers for m in SHOWN},
                            output / "tracking.mp4", fps=sequence.fps,
                            marker_names=UPPER_BODY_12, truth=sequence.truth),
        plot_errors_over_time({m: metrics[m]["errors_torso"] for m in SHOWN},
                              output / "errors.png", fps=sequence.fps,
                              title=f"held-out subject's wave: {HELD_OUT_CLIP.split('/')[-1]}"),
        *_latent_plots(prior, output),
        write_json_atomically(output / "metrics.json", {
            "train_clips": list(TRAIN_CLIPS), "test_clip": HELD_OUT_CLIP,
            "splits": {clip: split_of(clip) for clip in (*TRAIN_CLIPS, HELD_OUT_CLIP)},
            "prior": prior.description, "methods": metrics,
            "seeds": {"first": seed, "runs": repeats}}),
    ]
    for path in written:
        print(f"  wrote {path}")
    print(f"done in {time.perf_counter() - started:.1f} s")
    return 0
