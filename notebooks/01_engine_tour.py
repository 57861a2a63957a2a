# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # The SMC engine in ten cells
# A bootstrap particle filter on a random linear-Gaussian model, checked against the exact
# Kalman filter; the stop-gradient estimator's gradient of the log evidence; and smoothing.

# %%
import jax
import jax.numpy as jnp
import jax.random as jr
import matplotlib.pyplot as plt

jax.config.update("jax_enable_x64", True)
from jaxtrack import smc  # noqa: E402

model = smc.random_linear_gaussian(jr.key(0), state_dim=2, observation_dim=1)
states, observations = model.sample(jr.key(1), 50)
exact = smc.kalman_filter(model, observations)

# %% Log evidence vs the number of particles
for num in (100, 1_000, 10_000):
    estimate = smc.run(jr.key(2), model, observations, num).log_evidence
    print(f"N={num:>6}: PF {float(estimate):9.3f}   Kalman {float(exact.log_evidence):9.3f}")

# %% Filtered and smoothed means
result = smc.run(jr.key(3), model, observations, 5_000, keep_history=True)
smoothed = smc.ffbsi(jr.key(4), model, result, 500)
rts, _ = smc.rts_smoother(model, observations)
plt.plot(states[:, 0], "k", label="true state")
plt.plot(result.mean[:, 0], label="particle filter")
plt.plot(exact.filtered_means[:, 0], "--", label="Kalman filter")
plt.plot(smoothed.mean[:, 0], label="FFBSi smoother")
plt.plot(rts[:, 0], ":", label="RTS smoother")
plt.legend()

# %% Gradient of the log evidence w.r.t. the observation noise (stop-gradient estimator)
def log_evidence(log_std, key, resampler):
    noisy = smc.LinearGaussian(model.transition_matrix, model.transition_covariance,
                               model.observation_matrix, jnp.exp(2 * log_std) * jnp.eye(1),
                               model.initial_mean, model.initial_covariance)
    return smc.filter_sequence(key, noisy, observations, 5_000, resampler=resampler).log_evidence

log_std = 0.5 * jnp.log(model.observation_covariance[0, 0])
exact_grad = jax.grad(lambda s: smc.kalman_filter(smc.LinearGaussian(
    model.transition_matrix, model.transition_covariance, model.observation_matrix,
    jnp.exp(2 * s) * jnp.eye(1), model.initial_mean, model.initial_covariance),
    observations).log_evidence)(log_std)
for resampler in (smc.StopGradient(), smc.Systematic()):
    grad = jax.grad(log_evidence)(log_std, jr.key(5), resampler)
    print(f"{type(resampler).__name__:12s} {float(grad):8.3f}   exact {float(exact_grad):8.3f}")
