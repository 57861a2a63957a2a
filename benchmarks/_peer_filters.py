"""The peer particle filters the engine is timed against, each run by its own venv's python
and never imported by jaxtrack (``benchmarks/_peers.py`` runs them):

    .venv-peers-<library>/bin/python benchmarks/_peer_filters.py LIBRARY IN.npz OUT.json

with LIBRARY ``particles`` (N. Chopin, NumPy), ``cuthbert`` (JAX) or ``pydpf`` (Brady et al.,
PyTorch). IN.npz (written by ``_peers.py``): the linear-Gaussian model's ``transition``,
``transition_covariance``, ``observation``, ``observation_covariance``, ``initial_mean``,
``initial_covariance``, the ``observations`` (sequences, frames, observation dim),
``particle_counts`` and ``seed``. OUT.json (written atomically): ``library``, ``version`` and
``runs``, per particle count the seconds and log-evidence of each sequence. This file imports
only NumPy and the standard library at its top; each library is imported by its own function.

**particles.** Each sequence runs ``particles.SMC`` on ``state_space_models.Bootstrap`` with
systematic resampling at every frame (``ESSrmin=1``) and no history; its log-evidence is
``logLt``.

**cuthbert.** ``particle_filter.build_filter`` with systematic resampling at every step, run by
``cuthbert.filter`` over the frames. cuthbert weights only after a propagation, so frame 0 is a
step whose propagation keeps the initial sample (model inputs ``(y_t, t == 0)``); its
log-evidence is the last state's ``log_normalizing_constant``. One ``jit`` per particle count,
lowered and compiled before any timed run (``compile_s``) and called once (``first_call_s``:
numba compiles cuthbert's CPU resampling callback then); each sequence is then timed on its own
(float32, as JAX defaults).

**pydpf.** pydpf filters a batch of sequences in one call, as its own benchmark does (its
notebook ``Comparison_to_Kalman``: ``pydpf.ParticleFilter`` over a data loader's batches under
``torch.inference_mode``), so the whole batch goes through ``ParticleFilter`` at once, with
pydpf's own ``LinearGaussian`` dynamic and observation models, a ``MultivariateGaussian`` prior
and ``SystematicResampler`` (resampling every frame, as the engine's benchmark does). Its
log-evidence per sequence is the sum over frames of ``LogLikelihoodFactors``; one warm-up call
on two frames comes first; OUT.json adds torch's thread count, the batch's seconds
(``batch_seconds``) and the same divided by the batch size (``seconds``, one entry).
"""

from __future__ import annotations

import json
import os
import sys
import time
import warnings
from importlib import metadata

import numpy as np


def run_particles(inputs) -> dict:
    import particles
    from particles import distributions, state_space_models

    A, Q = inputs["transition"].astype(np.float64), inputs["transition_covariance"]
    H, R = inputs["observation"].astype(np.float64), inputs["observation_covariance"]
    m0, P0 = inputs["initial_mean"], inputs["initial_covariance"]

    class LinearGaussian(state_space_models.StateSpaceModel):
        def PX0(self):
            return distributions.MvNormal(loc=m0.astype(np.float64), cov=P0.astype(np.float64))

        def PX(self, t, xp):
            return distributions.MvNormal(loc=xp @ A.T, cov=Q.astype(np.float64))

        def PY(self, t, xp, x):
            return distributions.MvNormal(loc=x @ H.T, cov=R.astype(np.float64))

    model = LinearGaussian()
    observations = np.asarray(inputs["observations"], np.float64)
    seed = int(inputs["seed"])

    def filter_once(sequence, num_particles):
        algorithm = particles.SMC(
            fk=state_space_models.Bootstrap(ssm=model, data=list(sequence)), N=num_particles,
            resampling="systematic", ESSrmin=1.0, store_history=False, verbose=False)
        algorithm.run()
        return float(algorithm.logLt)

    filter_once(observations[0, :2], 10)  # warm: numba compiles the resampling on first use
    runs = []
    for num_particles in (int(n) for n in inputs["particle_counts"]):
        seconds, log_evidence = [], []
        for index, sequence in enumerate(observations):
            np.random.seed(seed + index)  # particles draws from NumPy's global generator
            start = time.perf_counter()
            log_evidence.append(filter_once(sequence, num_particles))
            seconds.append(time.perf_counter() - start)
        runs.append({"particles": num_particles, "seconds": seconds,
                     "log_evidence": log_evidence})
    return {"library": "particles", "version": metadata.version("particles"), "runs": runs}

def run_cuthbert(inputs) -> dict:
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

def run_pydpf(inputs) -> dict:
    import torch
    with warnings.catch_warnings():  # pydpf warns on import that no CUDA GPU was found
        warnings.simplefilter("ignore")
        import pydpf

    def tensor(name):
        return torch.as_tensor(np.asarray(inputs[name], np.float32))

    A, H = tensor("transition"), tensor("observation")
    chol_q = torch.linalg.cholesky(tensor("transition_covariance"))
    chol_r = torch.linalg.cholesky(tensor("observation_covariance"))
    chol_p0 = torch.linalg.cholesky(tensor("initial_covariance"))
    m0 = tensor("initial_mean")
    # pydpf wants (frames, batch, observation dim)
    observations = torch.as_tensor(np.asarray(inputs["observations"], np.float32)).transpose(0, 1)
    observations = observations.contiguous()
    frames, batch = observations.shape[:2]
    generator = torch.Generator().manual_seed(int(inputs["seed"]))

    model = pydpf.FilteringModel(
        prior_model=pydpf.MultivariateGaussian(m0, chol_p0, generator=generator),
        dynamic_model=pydpf.LinearGaussian(A, torch.zeros(A.shape[0]), chol_q,
                                           generator=generator),
        observation_model=pydpf.LinearGaussian(H, torch.zeros(H.shape[0]), chol_r,
                                               generator=generator))
    particle_filter = pydpf.ParticleFilter(resampler=pydpf.SystematicResampler(generator),
                                           SSM=model)
    factors = pydpf.LogLikelihoodFactors()

    def filter_batch(data, num_particles):
        with torch.inference_mode():
            output = particle_filter(observation=data, n_particles=num_particles,
                                     aggregation_function=factors,
                                     time_extent=data.shape[0] - 1)
        return output.reshape(data.shape[0], -1).sum(dim=0).double().numpy()

    filter_batch(observations[:2], 10)  # warm: first-call allocations
    runs = []
    for num_particles in (int(n) for n in inputs["particle_counts"]):
        start = time.perf_counter()
        log_evidence = filter_batch(observations, num_particles)
        seconds = time.perf_counter() - start
        runs.append({"particles": num_particles, "batch_seconds": seconds,
                     "seconds": [seconds / batch],
                     "log_evidence": [float(value) for value in log_evidence]})
    return {"library": "pydpf", "version": metadata.version("pydpf"),
            "torch": torch.__version__, "threads": torch.get_num_threads(),
            "batch": int(batch), "frames": int(frames), "runs": runs}


def main(argv: list[str]) -> int:
    """``LIBRARY IN.npz OUT.json``: read IN.npz into a dict of arrays, run LIBRARY's filter on
    it, write OUT.json atomically, and print a line per particle count."""
    runs = {"particles": (run_particles, DESCRIBE["particles"]),
            "cuthbert": (run_cuthbert, DESCRIBE["cuthbert"]),
            "pydpf": (run_pydpf, DESCRIBE["pydpf"])}
    if len(argv) != 3 or argv[0] not in runs:
        print(f"usage: _peer_filters.py {{{'|'.join(runs)}}} IN.npz OUT.json", file=sys.stderr)
        return 2
    library, in_path, out_path = argv
    run, describe = runs[library]
    with np.load(in_path, allow_pickle=False) as data:
        inputs = {key: data[key] for key in data.files}
    result = run(inputs)
    with open(out_path + ".tmp", "w") as handle:
        json.dump(result, handle)
    os.replace(out_path + ".tmp", out_path)
    for entry in result["runs"]:
        print(describe(entry))
    return 0


DESCRIBE = {
    "particles": lambda entry: (f"particles N={entry['particles']}: "
                       f"{np.median(entry['seconds']):.3f} s/seq"),
    "cuthbert": lambda entry: (
        f"cuthbert N={entry['particles']}: compile {entry['compile_s']:.2f} s, "
        f"{np.median(entry['seconds']):.3f} s/seq"),
    "pydpf": lambda entry: (
        f"pydpf N={entry['particles']}: {entry['batch_seconds']:.2f} s for the batch"),
}

if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
