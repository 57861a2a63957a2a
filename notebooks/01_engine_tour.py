# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # The SMC engine in ten cells
# A bootstrap particle filter on a random linear-Gaussian model, checked against the exact
# Kalman filter; smoothing; and three estimators of the gradient of the log evidence, checked
# against the Kalman filter's exact gradient.
#
# The sizes below are the full ones. With the environment variable `JAXTRACK_SMOKE=1` (what
# `tests/test_notebooks.py` sets) every size is small, so that the whole notebook runs in
# seconds plus compile time; the numbers it then prints are noisier than the ones quoted here.

# %%
import os

import jax
import jax.numpy as jnp
import jax.random as jr
import matplotlib.pyplot as plt

jax.config.update("jax_enable_x64", True)
from jaxtrack import smc  # noqa: E402

SMOKE = os.environ.get("JAXTRACK_SMOKE") == "1"
PARTICLE_COUNTS = (100, 400) if SMOKE else (100, 1_000, 10_000)
SMOOTHING_PARTICLES, SMOOTHED_PATHS = (500, 50) if SMOKE else (5_000, 500)
GRADIENT_PARTICLES, GRADIENT_SEEDS = (200, 4) if SMOKE else (5_000, 20)

model = smc.random_linear_gaussian(jr.key(0), state_dim=2, observation_dim=1)
states, observations = model.sample(jr.key(1), 50)
exact = smc.kalman_filter(model, observations)

# %% [markdown]
# ## Log evidence against the number of particles
# The particle filter's evidence estimate is unbiased on the natural scale, so its logarithm
# is biased low by about half its variance, and that variance shrinks as 1/N (its spread as
# 1/√N). Each line is one run with one seed, so each difference from the Kalman filter's exact
# value is one draw of that error: with the full sizes 0.50 nats at N = 100, 0.22 at 1 000 and
# 0.12 at 10 000 (jax 0.10.2 on a CPU; the keys are fixed, so the run below prints them).

# %%
for num in PARTICLE_COUNTS:
    estimate = smc.run(jr.key(2), model, observations, num).log_evidence
    print(f"N={num:>6}: PF {float(estimate):9.3f}   Kalman {float(exact.log_evidence):9.3f}")

# %% Filtered and smoothed means
result = smc.run(jr.key(3), model, observations, SMOOTHING_PARTICLES, keep_history=True)
smoothed = smc.ffbsi(jr.key(4), model, result, SMOOTHED_PATHS)
rts, _ = smc.rts_smoother(model, observations)
plt.plot(states[:, 0], "k", label="true state")
plt.plot(result.mean[:, 0], label="particle filter")
plt.plot(exact.filtered_means[:, 0], "--", label="Kalman filter")
plt.plot(smoothed.mean[:, 0], label="FFBSi smoother")
plt.plot(rts[:, 0], ":", label="RTS smoother")
plt.legend()

# %% [markdown]
# ## The gradient of the log evidence with respect to the observation noise
# `jax.grad` goes through the whole filter; what it returns depends on how the resampler
# passes gradient through the selection of parents (`jaxtrack/smc/_resampling.py`):
#
# - `StopGradient()` (Ścibior & Wood 2021) leaves the forward pass unchanged and gives the
#   Fisher-identity estimate of the score along the particles' ancestral paths: consistent
#   (its bias is O(1/N)), but its variance is large. The paths of a particle filter coalesce
#   to a few ancestors, so this path-space estimate's variance grows about as T²/N in the
#   number of frames T (Poyiadjis, Doucet & Singh 2011). With 5 000 particles and 50 frames,
#   over 20 seeds it averages 0.364 against the exact 0.391, with a standard deviation of
#   0.280 from seed to seed: a single run is one draw of that spread, and the mean of the 20
#   is 0.4 standard errors (0.063) from the exact value, as a consistent estimator's should be.
# - `SoftResampling(alpha=0.5)` (Karkus et al. 2018) draws parents from a mixture of the
#   weights and the uniform and carries the ratio: part of the selection's gradient passes,
#   so the estimate is biased for every α > 0 (about −1.4 here), with a smaller spread
#   (about 0.1) and a noisier forward pass.
# - A plain scheme (`Systematic()`) resets the weights to 1/N: the selection's dependence on
#   the parameter is dropped and only the pathwise part is left, strongly biased (about −3.1,
#   of the wrong sign) however many particles.
#
# The cell prints each estimator's mean over the seeds, its standard deviation and the
# standard error of the mean, beside the exact gradient.

# %%
def noisy_model(log_std):
    return smc.LinearGaussian(model.transition_matrix, model.transition_covariance,
                              model.observation_matrix, jnp.exp(2 * log_std) * jnp.eye(1),
                              model.initial_mean, model.initial_covariance)


log_std = 0.5 * jnp.log(model.observation_covariance[0, 0])
exact_grad = jax.grad(lambda s: smc.kalman_filter(noisy_model(s), observations).log_evidence)(
    log_std)
keys = jr.split(jr.key(5), GRADIENT_SEEDS)
print(f"exact gradient {float(exact_grad):.3f}; N = {GRADIENT_PARTICLES}, "
      f"{GRADIENT_SEEDS} seeds")
for resampler in (smc.StopGradient(), smc.SoftResampling(alpha=0.5), smc.Systematic()):
    def log_evidence(log_std, key, resampler=resampler):
        return smc.filter_sequence(key, noisy_model(log_std), observations,
                                   GRADIENT_PARTICLES, resampler=resampler).log_evidence

    grads = jax.jit(jax.vmap(jax.grad(log_evidence), in_axes=(None, 0)))(log_std, keys)
    print(f"{type(resampler).__name__:15s} mean {float(grads.mean()):7.3f}   "
          f"sd {float(grads.std()):6.3f}   "
          f"standard error {float(grads.std() / GRADIENT_SEEDS ** 0.5):6.3f}")
