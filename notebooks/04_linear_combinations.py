# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # The linear-combination tracker (Ong & Gong 2002), step by step
# Render real wave gestures through the four calibrated Pose2Sim cameras, build hybrid vectors
# (contour, hands, 3-D skeleton), learn the global PCA, the clusters and their transition
# matrix, track a test subject's wave with cluster jumps, compare with the two baselines, sweep
# clusters × samples (the paper's Fig. 10 and 12), and pick the least ambiguous view per frame
# (§5.5–5.7). The reasoning: `docs/linear-combination.md`; the measured numbers:
# `papers/ong2002/README.md`.
#
# Everything it reads is bundled with jaxtrack (the wave clips, the Pose2Sim calibration and its
# background photo). With `JAXTRACK_SMOKE=1` (what `tests/test_notebooks.py` sets) the clips,
# views, contours and particle clouds are tiny, so the numbers printed then say nothing about
# the tracker.

# %%
import os

import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

from jaxtrack.experiments import linear_combination as lc

SMOKE = os.environ.get("JAXTRACK_SMOKE") == "1"
HISTORY = "animateddrawings/history_c119d6b/"
TRAIN = ["animateddrawings/fair1_wave_hello", HISTORY + "8yr_old_wave_hello"]  # training subjects
TEST = HISTORY + "cmu_1006_wave_hello_1"  # a test subject (jaxtrack.data.splits)
if SMOKE:
    TRAIN = TRAIN[:1]
    SIZES = dict(views=(0, 1), num_contour=40, max_frames=12)
    CLUSTERS, PARTICLES, ITERATIONS, FRAMES = 3, 16, 2, 6
    SURFACE_CLUSTERS, SURFACE_SAMPLES = (3,), (8,)
else:
    SIZES = dict(views=(0, 1, 2, 3), num_contour=100, max_frames=None)
    CLUSTERS, PARTICLES, ITERATIONS, FRAMES = 20, 300, 5, 90
    SURFACE_CLUSTERS, SURFACE_SAMPLES = (10, 20, 40, 80), (20, 50, 100, 300)
FITNESS = lc.DEFAULT_FITNESS  # P = 64, Q = 16, chosen on validation (docs/defaults.md)

trained = lc.train(TRAIN, num_clusters=CLUSTERS, **SIZES)
model = trained.model
print(f"{len(trained.vectors)} training vectors, {model.num_components} global eigenvectors "
      f"({trained.description['explained_variance']:.0%} of the variance), "
      f"{model.num_clusters} clusters")

# %% [markdown]
# ## The model: eigenvalues, clusters, transitions
# Each training vector's coefficients (eq. 2) in the first two global components, coloured by
# its k-means cluster; the transition matrix U counted over consecutive training frames
# (§4.1). A mostly diagonal U with a few strong off-diagonal entries is what a gesture's
# ordered passage through its clusters looks like.

# %%
figure, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
coefficients = np.asarray(model.training_coefficients) * np.asarray(model.eigenvalues)
second = coefficients[:, 1] if model.num_components > 1 else np.zeros(len(coefficients))
left.scatter(coefficients[:, 0], second, c=np.asarray(model.training_clusters),
             s=4, cmap="tab20")
left.set(xlabel="λ₁ a₁", ylabel="λ₂ a₂", title="training vectors by cluster")
right.imshow(np.asarray(model.transition), cmap="Greys")
right.set(xlabel="next cluster b", ylabel="cluster a", title="U")
plt.show()

# %% [markdown]
# ## Tracking a test subject, with both baselines
# The test take is rendered through camera 1 and observed as a video would be: background
# subtraction, skin blobs, gradient map. The tracker (cluster jumps, clamps, 5 iterations per
# frame), the global-PCA filter with Brownian motion and the nearest-neighbour lookup are
# scored by the mean 3-D distance of the 12 skeleton vertices (neck-relative, camera frame).

# %%
sequence = lc.render_hybrid_sequences(TEST, views=(0,), num_contour=model.layout.num_contour,
                                      max_frames=FRAMES, keep_observations=True, seed=7)[0]
errors = {}
for method in lc.METHODS:
    run = lc.run_method(method, trained, sequence.observations, particles=PARTICLES,
                        iterations=ITERATIONS, fitness=FITNESS)
    errors[method] = lc.skeleton_error(run["skeleton"], sequence.skeleton)
    print(f"{method:20s} mean 3-D error {errors[method].mean():.3f} m")
for method, error in errors.items():
    plt.plot(error, label=method)
plt.xlabel("frame")
plt.ylabel("3-D skeleton error (m)")
plt.legend()
plt.show()

# %% [markdown]
# ## Error against clusters and samples (Fig. 10 and 12)
# The paper's trend: on training sequences the error falls with more clusters and samples; on
# novel motion too many clusters over-fit.

# %%
surface = np.zeros((len(SURFACE_CLUSTERS), len(SURFACE_SAMPLES)))
for row, clusters in enumerate(SURFACE_CLUSTERS):
    model_k = lc.train(TRAIN, num_clusters=clusters, **SIZES)
    for column, samples in enumerate(SURFACE_SAMPLES):
        run = lc.run_method("linear-combination", model_k, sequence.observations,
                            particles=samples, iterations=ITERATIONS, fitness=FITNESS,
                            step=jnp.asarray(lc.DEFAULT_STEP))
        surface[row, column] = lc.skeleton_error(run["skeleton"], sequence.skeleton).mean()
print("3-D error (m), rows: clusters", SURFACE_CLUSTERS, "columns: samples", SURFACE_SAMPLES)
print(np.round(surface, 3))

# %% [markdown]
# ## Choosing a view (§5.5–5.7)
# Every camera is tracked on its own. Each view's ambiguity is that of the nearest training
# vector (eq. 14): how many training vectors look alike there but have different skeletons.
# The paper reads each frame's best-particle skeleton from the view of greatest fitness ×
# 1/ambiguity (`selection="paper", estimate="best"`); jaxtrack's defaults, chosen together on
# validation subjects (`python -m papers.ong2002.view_selection`), read the particles' weighted
# mean skeleton from the view of least ambiguity over ±5 frames.

# %%
selection = lc.multi_view(trained, TEST, views=SIZES["views"], max_frames=FRAMES,
                          particles=PARTICLES, iterations=ITERATIONS, fitness=FITNESS)
print(f"selected view {selection['selected_m']:.3f} m, best view per frame (oracle) "
      f"{selection['best_m']:.3f} m, worst view {selection['worst_m']:.3f} m; the selected "
      f"view was the best on {selection['selected_is_best']:.0%} of the frames")
ambiguity = np.asarray(selection["ambiguity"])
plt.imshow(ambiguity.T, aspect="auto", cmap="viridis")
plt.plot(selection["chosen"], "r.", label="selected view")
plt.xlabel("frame")
plt.ylabel("view")
plt.colorbar(label="ambiguity (eq. 14)")
plt.legend()
plt.show()
