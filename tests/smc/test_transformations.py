"""jit == no-jit, vmap == loop, no retracing across frames, sharded == unsharded."""

import json
import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from jaxtrack import smc

from .helpers import rebuild


@pytest.fixture(scope="module")
def problem():
    model = smc.random_linear_gaussian(jr.key(0), state_dim=3, observation_dim=2)
    _, observations = model.sample(jr.key(1), 8)
    return model, observations


def test_jit_equals_no_jit(problem):
    model, observations = problem
    compiled = smc.run(jr.key(2), model, observations, 64, keep_history=True)
    with jax.disable_jit():
        eager = smc.filter_sequence(jr.key(2), model, observations, 64, keep_history=True)
    np.testing.assert_array_equal(compiled.ancestors, eager.ancestors)
    np.testing.assert_allclose(compiled.log_evidence_increments, eager.log_evidence_increments,
                               rtol=1e-10)
    np.testing.assert_allclose(compiled.mean, eager.mean, rtol=1e-10, atol=1e-12)


def test_vmap_equals_loop(problem):
    model, observations = problem
    keys = jr.split(jr.key(3), 3)
    batch = jnp.stack([observations, observations * 0.5, -observations])
    vmapped = smc.run_batch(keys, model, batch, 128, ess_threshold=0.5)
    plain_vmap = jax.vmap(lambda k, y: smc.run(k, model, y, 128, ess_threshold=0.5))(keys, batch)
    chunked = smc.run_batch(keys, model, batch, 128, ess_threshold=0.5, chunk_size=2)
    for index in range(3):
        single = smc.run(keys[index], model, batch[index], 128, ess_threshold=0.5)
        for batched in (vmapped, plain_vmap, chunked):
            np.testing.assert_allclose(batched.log_evidence[index], single.log_evidence,
                                       rtol=1e-10)
            np.testing.assert_allclose(batched.mean[index], single.mean, rtol=1e-9, atol=1e-12)
            np.testing.assert_array_equal(batched.resampled[index], single.resampled)


def test_auto_chunk_size_follows_the_particle_state_and_bad_sizes_are_refused(problem):
    model, observations = problem
    eye = lambda rows, columns=None: jnp.eye(rows, columns, dtype=jnp.float32)  # noqa: E731
    wide = smc.LinearGaussian(eye(25), eye(25), eye(1, 25), eye(1), jnp.zeros(25, jnp.float32),
                              eye(25))
    # 4 copies of 25 float32 per particle within 256 MiB
    assert smc.auto_chunk_size(wide, 1_000, 128) == 128
    assert smc.auto_chunk_size(wide, 10_000, 128) == 2**28 // (4 * 10_000 * 100)
    assert smc.auto_chunk_size(wide, 1_000_000, 128) == 1
    # on an accelerator: 1/8 of its memory, so the whole batch of 128 at N = 10^4 on 80 GB

    class Accelerator:
        platform = "gpu"

        def __init__(self, limit):
            self.limit = limit

        def memory_stats(self):
            return {"bytes_limit": self.limit}

    assert smc.auto_chunk_size(wide, 10_000, 128, device=Accelerator(80 * 2**30)) == 128
    assert smc.auto_chunk_size(wide, 1_000_000, 128, device=Accelerator(80 * 2**30)) == 26
    assert smc.auto_chunk_size(wide, 10_000, 128, device=Accelerator(None)) == 67
    keys = jr.split(jr.key(3), 2)
    batch = jnp.stack([observations, -observations])
    with pytest.raises(ValueError, match="chunk_size must be a positive int, 'auto' or None"):
        smc.run_batch(keys, model, batch, 16, chunk_size=0)


class CountingModel(smc.LinearGaussian):
    """Counts how often JAX traces the model's methods (a Python side effect runs at trace time)."""

    def propagate(self, key, particle, time):
        TRACES.append("propagate")
        return super().propagate(key, particle, time)


TRACES: list[str] = []


def test_no_retracing_across_frames_or_calls(problem):
    base, observations = problem
    model = rebuild(CountingModel, base)
    TRACES.clear()
    smc.run(jr.key(4), model, observations, 32)
    traced_once = len(TRACES)
    assert traced_once >= 1
    smc.run(jr.key(5), model, observations + 1.0, 32)  # new values, same shapes: cached
    assert len(TRACES) == traced_once
    # Online use: a jitted step reused frame after frame traces once.
    TRACES.clear()
    step = jax.jit(lambda key, state, y: smc.step(key, state, y, model))
    state, _ = smc.initialize(jr.key(6), model, observations[0], 32)
    for frame in range(1, observations.shape[0]):
        state, info = step(jr.fold_in(jr.key(7), frame), state, observations[frame])
    assert len(TRACES) == 1
    assert int(state.time) == observations.shape[0] - 1


def test_online_steps_equal_run(problem):
    model, observations = problem
    result = smc.run(jr.key(8), model, observations, 64)
    key_init, key_frames = jr.split(jr.key(8))
    state, _ = smc.initialize(key_init, model, observations[0], 64)
    for key, observation in zip(jr.split(key_frames, observations.shape[0] - 1), observations[1:],
                                strict=True):
        state, _ = smc.step(key, state, observation, model)
    np.testing.assert_allclose(state.log_evidence, result.log_evidence, rtol=1e-10)


class LineageWalk(smc.StateSpaceModel):
    """Random walk whose particles remember their frame-0 value (``origin``) unchanged."""

    def init(self, key):
        x = jr.normal(key)
        return {"x": x, "origin": x, "steps": jnp.asarray(0, jnp.int32)}

    def propagate(self, key, particle, time):
        return {"x": particle["x"] + 0.3 * jr.normal(key), "origin": particle["origin"],
                "steps": particle["steps"] + 1}

    def log_likelihood(self, particle, observation):
        return -0.5 * ((observation - particle["x"]) / 0.2) ** 2


def test_iterations_per_frame_compose_ancestors():
    observations = jnp.array([0.0, 0.5, 1.0, 0.8, 0.2])
    result = smc.run(jr.key(9), LineageWalk(), observations, 256, iterations_per_frame=3,
                     keep_history=True)
    # Mixed integer/float particle leaves: every particle made 3 moves per frame after frame 0.
    np.testing.assert_array_equal(result.particles["steps"][:, 0], [0, 3, 6, 9, 12])
    paths = smc.trace_ancestry(result).paths
    # Following the composed ancestors back to frame 0 reaches each particle's own origin.
    np.testing.assert_array_equal(paths["x"][0], result.particles["origin"][-1])
    assert result.mean["steps"].dtype == jnp.int32


def test_sharded_equals_unsharded():
    script = textwrap.dedent("""
        import json, jax, jax.numpy as jnp, jax.random as jr, numpy as np
        jax.config.update("jax_enable_x64", True)
        from jaxtrack import smc
        assert jax.device_count() == 4, jax.devices()
        model = smc.random_linear_gaussian(jr.key(0), 3, 2)
        _, y = model.sample(jr.key(1), 6)
        batch = jnp.stack([y * s for s in (1.0, 0.5, -1.0, 2.0, 0.1, 1.5, -0.5, 0.7)])
        keys = jr.split(jr.key(2), 8)
        mesh = jax.make_mesh((4,), ("devices",))
        sharded = smc.run(keys, model, batch, 256, mesh=mesh)
        plain = smc.run_batch(keys, model, batch, 256)
        print(json.dumps({
            "devices": len(sharded.log_evidence.sharding.device_set),
            "max_diff": float(jnp.max(jnp.abs(sharded.mean - plain.mean))),
            "evidence_diff": float(jnp.max(jnp.abs(sharded.log_evidence - plain.log_evidence))),
        }))
    """)
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=4",
               JAX_PLATFORMS="cpu")
    output = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                            text=True, timeout=300)
    assert output.returncode == 0, output.stderr[-3000:]
    report = json.loads(output.stdout.strip().splitlines()[-1])
    assert report["devices"] == 4
    assert report["max_diff"] < 1e-10 and report["evidence_diff"] < 1e-10


def test_mesh_batch_must_split_evenly(problem):
    model, observations = problem
    mesh = jax.make_mesh((1,), ("devices",))
    keys = jr.split(jr.key(0), 3)
    with pytest.raises(ValueError, match="keys"):
        smc.run_batch(keys[:2], model, jnp.stack([observations] * 3), 16, mesh=mesh)
