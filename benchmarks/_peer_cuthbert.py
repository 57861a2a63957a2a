"""cuthbert's particle filter (``cuthbert.smc.particle_filter``, JAX); run with its own venv's
python, never imported by jaxtrack.

    .venv-peers-cuthbert/bin/python benchmarks/_peer_cuthbert.py IN.npz OUT.json

IN.npz as for ``_peer_particles.py``. The filter is ``particle_filter.build_filter`` with
systematic resampling at every step, run by ``cuthbert.filter`` over the frames. cuthbert
weights only after a propagation, so frame 0 is a step whose propagation keeps the initial
sample (model inputs ``(y_t, t == 0)``); its log-evidence is the last state's
``log_normalizing_constant``. One ``jit`` per particle count, lowered and compiled before any
timed run (``compile_s``) and called once (``first_call_s``: numba compiles cuthbert's CPU
resampling callback then); each sequence is then timed on its own (float32, as JAX defaults).
OUT.json: ``library``, ``version`` and per particle count ``compile_s`` and the seconds and
log-evidence of each sequence. Imports only NumPy, JAX and cuthbert.
"""

from __future__ import annotations

import sys
import time
from importlib import metadata

import numpy as np
from _peer_script import main  # this folder: the script runs in the peer's venv


def run(inputs) -> dict:
    import jax
    import jax.numpy as jnp
    import jax.random as jr
    from cuthbert import filter as run_filter
    from cuthbert.smc import particle_filter
    from cuthbertlib.resampling import systematic

    def array(name):
        return jnp.asarray(inputs[name], jnp.float32)

    A, H, m0 = array("transition"), array("observation"), array("initial_mean")
    chol_q = jnp.linalg.cholesky(array("transition_covariance"))
    chol_p = jnp.linalg.cholesky(array("initial_covariance"))
    chol_r = jnp.linalg.cholesky(array("observation_covariance"))
    log_norm = -jnp.sum(jnp.log(jnp.diag(chol_r))) - 0.5 * chol_r.shape[0] * np.log(2 * np.pi)

    def init_sample(key):
        return m0 + chol_p @ jr.normal(key, m0.shape)

    def propagate_sample(key, x, model_inputs):
        _, first = model_inputs
        moved = A @ x + chol_q @ jr.normal(key, x.shape)
        return jnp.where(first, x, moved)

    def log_potential(x_prev, x, model_inputs):
        y, _ = model_inputs
        residual = jax.scipy.linalg.solve_triangular(chol_r, y - H @ x, lower=True)
        return log_norm - 0.5 * jnp.sum(residual * residual)

    observations = jnp.asarray(inputs["observations"], jnp.float32)
    frames = observations.shape[1]
    first = jnp.arange(frames) == 0
    seed = int(inputs["seed"])
    runs = []
    for num_particles in (int(n) for n in inputs["particle_counts"]):
        pf = particle_filter.build_filter(init_sample, propagate_sample, log_potential,
                                          num_particles, systematic.resampling)

        def log_evidence_of(key, sequence, pf=pf):
            key_init, key_filter = jr.split(key)
            states = run_filter(pf, (sequence, first), pf.init_prepare(key=key_init),
                                key=key_filter)
            return states.log_normalizing_constant[-1]

        start = time.perf_counter()
        compiled = jax.jit(log_evidence_of).lower(jr.key(seed), observations[0]).compile()
        compile_s = time.perf_counter() - start
        start = time.perf_counter()  # the first call also compiles numba's resampling callback
        jax.block_until_ready(compiled(jr.key(seed), observations[0]))
        first_call_s = time.perf_counter() - start
        seconds, log_evidence = [], []
        for index, sequence in enumerate(observations):
            key = jr.key(seed + index)
            start = time.perf_counter()
            value = jax.block_until_ready(compiled(key, sequence))
            seconds.append(time.perf_counter() - start)
            log_evidence.append(float(value))
        runs.append({"particles": num_particles, "compile_s": compile_s,
                     "first_call_s": first_call_s, "seconds": seconds,
                     "log_evidence": log_evidence})
    return {"library": "cuthbert", "version": metadata.version("cuthbert"),
            "device": str(jax.devices()[0]), "runs": runs}


if __name__ == "__main__":
    raise SystemExit(main(sys.argv, run, lambda entry: (
        f"cuthbert N={entry['particles']}: compile {entry['compile_s']:.2f} s, "
        f"{np.median(entry['seconds']):.3f} s/seq")))
