# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # The latent-space tracker (Tian, Li & Sclaroff 2005), step by step
# Learn a GPLVM from real wave gestures, look at its latent space, track a held-out take with 200
# particles, compare with CONDENSATION in the full state, see where the error comes from, and
# initialise automatically on a real video. Run from the repository root; the prior is cached in
# `jaxtrack-demo/` (the demo's cache), so a second run skips training.
#
# Everything it reads is bundled with jaxtrack (the wave clips, and a half-size copy of the
# Pose2Sim demo's camera 3, `pose2sim/videos/cam03_half.mp4`). The sizes are the full ones;
# with the environment variable `JAXTRACK_SMOKE=1` (what `tests/test_notebooks.py` sets) the
# prior, the clips and the particle clouds are tiny and the prior is not cached, so the
# numbers printed then say nothing about the tracker: the ones quoted in the text are for the
# full sizes.

# %%
import os

import jax
import jax.numpy as jnp
import jax.random as jr
import matplotlib.pyplot as plt
import numpy as np

from jaxtrack.body import MARKER_EDGES, UPPER_BODY_12
from jaxtrack.evaluation import evaluate_track
from jaxtrack.experiments import render_test_sequences, run_method
from jaxtrack.experiments.demo import HELD_OUT_CLIP, TRAIN_CLIPS
from jaxtrack.priors.train import train_prior
from jaxtrack.trackers import Engine, Likelihood

SMOKE = os.environ.get("JAXTRACK_SMOKE") == "1"
if SMOKE:  # a prior of 1 view × 3 clips, 24 active points, 1 × 20 steps; 6-frame clips
    PRIOR = dict(views=1, active_size=24, iterations=1, active_steps=20, cache=None)
    TEST_FRAMES, LATENT_PARTICLES, CONDENSATION_PARTICLES = 6, 16, 32
    VIDEO_STRIDE, GRID = 20, 20  # 5 frames spread over the clip, for the median background
else:
    PRIOR = dict(cache="jaxtrack-demo/gplvm_waves.npz")
    TEST_FRAMES, LATENT_PARTICLES, CONDENSATION_PARTICLES = None, 200, 1000
    VIDEO_STRIDE, GRID = 1, 60

# The prior prints its number of training poses (frames × views) and ν, the per-frame standard
# deviation of the random walk in each latent dimension (learned from the training clips at
# their frame rate).
prior = train_prior(TRAIN_CLIPS, **PRIOR)
print(prior.description["num_poses"], "training poses; ν =", np.asarray(prior.model.dynamics_std))

# %% The learned latent space: training latents by clip, σ²(x) behind them
grid = np.stack(np.meshgrid(np.linspace(-3, 3, GRID), np.linspace(-3, 3, GRID)), -1).reshape(-1, 2)
model32 = prior.model.astype(jnp.float32)
variance = np.asarray(jax.jit(jax.vmap(model32.variance))(jnp.asarray(grid, jnp.float32)))
plt.imshow(np.log(variance.reshape(GRID, GRID)), extent=(-3, 3, 3, -3), cmap="Greys")
latents = np.asarray(prior.model.latents)
plt.scatter(*latents.T, s=2, c="tab:blue", label="training latents")
plt.scatter(*np.asarray(prior.model.active_latents).T, s=8, c="tab:red", label="active set")
plt.legend()
plt.title("log σ²(x) and the training latents")

# %% Track the held-out take with both methods (initialised from frame 0's truth)
sequence = render_test_sequences(HELD_OUT_CLIP, views=1, backgrounds=("photo",),
                                  max_frames=TEST_FRAMES)[0]
results = {method: run_method(method, prior, sequence, particles=particles)
           for method, particles in (("latent", LATENT_PARTICLES),
                                     ("condensation", CONDENSATION_PARTICLES))}
for method, result in results.items():
    metrics = evaluate_track(result.markers, sequence.truth, UPPER_BODY_12)
    print(f"{method:13s} {metrics['mean_error_torso']:.3f} of torso, "
          f"{metrics['frames_tracked']}/{metrics['num_frames']} frames tracked")

# %% [markdown]
# ## The likelihood
# Limb strips, their edges and the arms' foreground (the default), the same without the
# foreground term, the strips alone, the paper's eq. 7 marker patches. Every method takes
# `likelihood=`. With the patches the latent tracker loses the waving arm far more often: over
# the whole latent space the patches' best-scoring pose is 20 % of the torso from the truth,
# the strips' 8.8 % (`docs/likelihoods.md`). The edge term keeps scoring the limbs when their
# texture has drifted from the frame-0 strips, and the foreground term (a static camera's
# median background) keeps an arm off the place it has left. The cell prints each variant's
# mean marker error as a fraction of the torso length and the fraction of frames whose error
# stays under 15 % of it. In smoke mode only the last variant is tracked (each variant is a
# tracker of its own to compile); the others are built but not run.

# %%
likelihoods = {"strips + edges + fg": None,  # the default: tracked above
               "strips + edges": dict(background=False),
               "limb strips": dict(likelihood=Likelihood("limbs")),
               "marker patches": dict(likelihood=Likelihood("markers"))}
for name, options in likelihoods.items():
    if options is None:
        result = results["latent"]
    elif SMOKE and name != "marker patches":
        continue
    else:
        result = run_method("latent", prior, sequence, particles=LATENT_PARTICLES, **options)
    metrics = evaluate_track(result.markers, sequence.truth, UPPER_BODY_12)
    print(f"latent, {name:19s} {metrics['mean_error_torso']:.3f} of torso, "
          f"{metrics['fraction_within_15']:.0%} of frames within 15 %")

# %% [markdown]
# ## The refinement stage
# The reported pose is refined in the full SPM state (the default `Refinement()` stage),
# each refinement starting from a grid search over both arms' two image angles, about the
# carried arm and about its constant-velocity prediction; `ArmSearch(momentum=0)` searches
# about the carried arm alone, `arm_search=None` leaves the search out and `refinement=None`
# reports the paper's estimate, μ of the particles' mean latent. The particles are the same in
# all four runs: the refinement only leaves the latent space for the pose it reports. Every
# tracker takes the same stage (`condensation_tracker(..., refinement=Refinement())`); why the
# defaults are what they are, with the measurements, is in `docs/trackers.md`. Here the
# trackers are built with `latent_tracker` and run with `track`, what `run_method` does for
# a test sequence. In smoke mode only the paper's estimate is tracked.

# %%
from jaxtrack.trackers import ArmSearch, Refinement, latent_tracker, track  # noqa: E402
from jaxtrack.vision import median_grey_background  # noqa: E402

scene = median_grey_background(sequence.frames)  # what run_method scores the arms against
refinements = {"searched + refined (default)": "default",  # tracked above
               "searched about the carried arm alone":
                   Refinement(arm_search=ArmSearch(momentum=0.0)),
               "refined, no arm search": Refinement(arm_search=None),
               "paper's estimate": None}
for name, refinement in refinements.items():
    if refinement == "default":
        result = results["latent"]
    elif SMOKE and refinement is not None:
        continue
    else:
        tracker = latent_tracker(prior.model, prior.template, engine=Engine(LATENT_PARTICLES),
                                 fps=sequence.fps, background=scene, refinement=refinement)
        result = track(tracker, jr.PRNGKey(0), sequence.frames, sequence.truth[0])
    metrics = evaluate_track(result.markers, sequence.truth, UPPER_BODY_12)
    print(f"latent, {name:36s} {metrics['mean_error_torso']:.3f} of torso, "
          f"{metrics['fraction_within_15']:.0%} of frames within 15 %")

# %% Error per marker over time: the waving wrist is what the tracker loses
torso = np.linalg.norm(sequence.truth[:, 1] - sequence.truth[:, 3], axis=-1)
errors = np.linalg.norm(results["latent"].markers - sequence.truth, axis=-1) / torso[:, None]
for index in (0, 1, 6, 10):
    plt.plot(errors[:, index], label=UPPER_BODY_12[index])
plt.axhline(0.15, color="k", ls=":")
plt.xlabel("frame")
plt.ylabel("error / torso")
plt.legend()

# %% [markdown]
# ## Automatic initialisation on a real video
# The Pose2Sim demo's face is pixelated, so the Haar face detector rarely fires and the head
# guessed from the top of the largest foreground blob usually wins. The cell prints which kind
# of box won (`face` or `foreground`), the box (x, y, width, height in pixels) and the Dice
# overlap between the chosen pose's silhouette and the foreground mask (1: a perfect fit;
# below 0.35 `auto_initialise` refuses).

# %%
from jaxtrack.data import path as data_path  # noqa: E402
from jaxtrack.trackers.autoinit import auto_initialise  # noqa: E402
from jaxtrack.vision import foreground_mask, median_background, read_video  # noqa: E402

# the Pose2Sim demo's camera 3 at half size (544 × 960, 60 fps, 100 frames), bundled
video = read_video(data_path("pose2sim/videos/cam03_half.mp4"), stride=VIDEO_STRIDE)
foreground = foreground_mask(video.frames[0], median_background(video.frames))
found = auto_initialise(prior.model, prior.template, video.frames[0], foreground)
print(f"{found.source} box {found.face.tolist()}, overlap {found.score:.2f}")
plt.imshow(video.frames[0])
plt.imshow(np.ma.masked_where(~foreground, foreground), alpha=0.4, cmap="autumn")
for a, b in MARKER_EDGES[UPPER_BODY_12]:
    plt.plot(*found.markers[[a, b]].T, "c-", lw=2)
plt.axis("off")

# %% [markdown]
# ## The tracker itself on the video
# `start`/`update` over the video from the initial pose just found, what `jaxtrack track`
# runs. The cell prints the run time per frame after compilation and the compile time apart
# (compiling the chunk scan once takes tens of seconds on a CPU; see `docs/trackers.md`).

# %%
from jaxtrack.vision import to_grey  # noqa: E402

grey = to_grey(video.frames)
tracker = latent_tracker(prior.model, prior.template, engine=Engine(LATENT_PARTICLES),
                         fps=video.fps, background=median_grey_background(grey))
result = track(tracker, jr.PRNGKey(0), grey, found.markers)
print(f"{1e3 * result.seconds_per_frame:.2f} ms/frame, compile {result.compile_seconds:.1f} s")
