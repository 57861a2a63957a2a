"""The ``particles`` library's bootstrap filter (N. Chopin); run with its own venv's python,
never imported by jaxtrack.

    .venv-peers-particles/bin/python benchmarks/_peer_particles.py IN.npz OUT.json

IN.npz (written by ``benchmarks/_peers.py``): the linear-Gaussian model's ``transition``,
``transition_covariance``, ``observation``, ``observation_covariance``, ``initial_mean``,
``initial_covariance``, the ``observations`` (sequences, frames, observation dim),
``particle_counts`` and ``seed``. Each sequence runs ``particles.SMC`` on
``state_space_models.Bootstrap`` with systematic resampling at every frame (``ESSrmin=1``) and
no history; its log-evidence is ``logLt``. OUT.json: ``library``, ``version`` and per particle
count the seconds and log-evidence of each sequence. Imports only NumPy and ``particles``.
"""

from __future__ import annotations

import sys
import time
from importlib import metadata

import numpy as np
from _peer_script import main  # this folder: the script runs in the peer's venv


def run(inputs) -> dict:
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


if __name__ == "__main__":
    raise SystemExit(main(sys.argv, run, lambda entry: (f"particles N={entry['particles']}: "
                                     f"{np.median(entry['seconds']):.3f} s/seq")))
