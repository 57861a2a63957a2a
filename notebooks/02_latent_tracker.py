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

# %%
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
from jaxtrack.trackers import Likelihood

prior = train_prior(TRAIN_CLIPS, cache="jaxtrack-demo/gplvm_waves.npz")
print(prior.description["num_poses"], "training poses; ν =", np.asarray(prior.model.dynamics_std))

# %% The learned latent space: training latents by clip, σ²(x) behind them
grid = np.stack(np.meshgrid(np.linspace(-3, 3, 60), np.linspace(-3, 3, 60)), -1).reshape(-1, 2)
model32 = prior.model.astype(jnp.float32)
variance = np.asarray(jax.jit(jax.vmap(model32.variance))(jnp.asarray(grid, jnp.float32)))
plt.imshow(np.log(variance.reshape(60, 60)), extent=(-3, 3, 3, -3), cmap="Greys")
latents = np.asarray(prior.model.latents)
plt.scatter(*latents.T, s=2, c="tab:blue", label="training latents")
plt.scatter(*np.asarray(prior.model.active_latents).T, s=8, c="tab:red", label="active set")
plt.legend()
plt.title("log σ²(x) and the training latents")

# %% Track the held-out take with both methods (initialised from frame 0's truth)
sequence = render_test_sequences(HELD_OUT_CLIP, views=1, backgrounds=("photo",))[0]
results = {method: run_method(method, prior, sequence, particles=particles)
           for method, particles in (("latent", 200), ("condensation", 1000))}
for method, result in results.items():
    metrics = evaluate_track(result.markers, sequence.truth, UPPER_BODY_12)
    print(f"{method:13s} {metrics['mean_error_torso']:.3f} of torso, "
          f"{metrics['frames_tracked']}/{metrics['num_frames']} frames tracked")

# %% The likelihood: limb strips, their edges and the arms' foreground (default), the same
# without the foreground term, the strips alone, the paper's patches. Every method takes
# `likelihood=`; with the paper's eq. 7 patches the latent tracker loses the waving arm far
# more often (README, "Tracking": the patches' best-scoring pose over the whole latent space is
# 20 % of the torso from the truth, the strips' 8.8 %), the edge term keeps scoring the limbs
# when their texture has drifted from the frame-0 strips, and the foreground term (a static
# camera's median background) keeps an arm off the place it has left.
no_foreground = run_method("latent", prior, sequence, particles=200, background=False)
strips = run_method("latent", prior, sequence, particles=200, likelihood=Likelihood("limbs"))
paper = run_method("latent", prior, sequence, particles=200, likelihood=Likelihood("markers"))
for name, result in (("strips + edges + fg", results["latent"]),
                     ("strips + edges", no_foreground), ("limb strips", strips),
                     ("marker patches", paper)):
    metrics = evaluate_track(result.markers, sequence.truth, UPPER_BODY_12)
    print(f"latent, {name:19s} {metrics['mean_error_torso']:.3f} of torso, "
          f"{metrics['fraction_within_15']:.0%} of frames within 15 %")

# %% The reported pose is refined in the full SPM state (the default `Refinement()` stage),
# each refinement starting from a grid search over both arms' two image angles, about the
# carried arm and about its constant-velocity prediction; `ArmSearch(momentum=0)` searches
# about the carried arm alone, `arm_search=None` leaves the search out and `refinement=None`
# reports the paper's estimate, μ of the particles' mean latent. The particles are the same in
# all four runs: the refinement only leaves the latent space for the pose it reports. Every
# tracker takes the same stage (`condensation_tracker(..., refinement=Refinement())`).
from jaxtrack.trackers import ArmSearch, Refinement, latent_tracker, track  # noqa: E402
from jaxtrack.vision import median_grey_background  # noqa: E402

scene = median_grey_background(sequence.frames)  # what run_method scores the arms against


def latent_run(refinement):
    tracker = latent_tracker(prior.model, prior.template, fps=sequence.fps, background=scene,
                             refinement=refinement)
    return track(tracker, jr.PRNGKey(0), sequence.frames, sequence.truth[0])


for name, result in (
        ("searched + refined (default)", results["latent"]),
        ("searched about the carried arm alone",
         latent_run(Refinement(arm_search=ArmSearch(momentum=0.0)))),
        ("refined, no arm search", latent_run(Refinement(arm_search=None))),
        ("paper's estimate", latent_run(None))):
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

# %% Automatic initialisation on a real video (Pose2Sim, face pixelated: the blob head wins)
from jaxtrack.trackers.autoinit import auto_initialise  # noqa: E402
from jaxtrack.vision import foreground_mask, median_background, read_video  # noqa: E402

video = read_video("../shared/data/pose2sim_demo_singleperson/videos/cam03.mp4", scale=0.5)
foreground = foreground_mask(video.frames[0], median_background(video.frames))
found = auto_initialise(prior.model, prior.template, video.frames[0], foreground)
print(f"{found.source} box {found.face.tolist()}, overlap {found.score:.2f}")
plt.imshow(video.frames[0])
plt.imshow(np.ma.masked_where(~foreground, foreground), alpha=0.4, cmap="autumn")
for a, b in MARKER_EDGES[UPPER_BODY_12]:
    plt.plot(*found.markers[[a, b]].T, "c-", lw=2)
plt.axis("off")

# %% The tracker itself: start/update over the video (what `jaxtrack track` runs)
from jaxtrack.vision import to_grey  # noqa: E402

grey = to_grey(video.frames)
tracker = latent_tracker(prior.model, prior.template, fps=video.fps,
                         background=median_grey_background(grey))
result = track(tracker, jr.PRNGKey(0), grey, found.markers)
print(f"{1e3 * result.seconds_per_frame:.2f} ms/frame, compile {result.compile_seconds:.1f} s")
