"""pydpf's bootstrap particle filter (Brady et al., PyTorch); run with its own venv's python,
never imported by jaxtrack.

    .venv-peers-pydpf/bin/python benchmarks/_peer_pydpf.py IN.npz OUT.json

IN.npz (written by ``benchmarks/_peers.py``): the linear-Gaussian model's arrays, the
``observations`` (sequences, frames, observation dim), ``particle_counts`` and ``seed``.
pydpf filters a batch of sequences in one call, as its own benchmark does (its notebook
``Comparison_to_Kalman``: ``pydpf.ParticleFilter`` over a data loader's batches under
``torch.inference_mode``), so the whole batch goes through ``ParticleFilter`` at once, with
pydpf's own ``LinearGaussian`` dynamic and observation models, a ``MultivariateGaussian``
prior and ``SystematicResampler`` (resampling every frame, as the engine's benchmark does).
Its log-evidence per sequence is the sum over frames of ``LogLikelihoodFactors``. One warm-up
call on two frames comes first. OUT.json: ``library``, ``version``, torch's thread count, and per
particle count the batch's seconds (``batch_seconds``), the same divided by the batch size
(``seconds``, one entry: the batch's time per sequence) and the log-evidence of each
sequence. Imports only NumPy, torch and pydpf.
"""

from __future__ import annotations

import sys
import time
import warnings
from importlib import metadata

import numpy as np
from _peer_script import main  # this folder: the script runs in the peer's venv


def run(inputs) -> dict:
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


if __name__ == "__main__":
    raise SystemExit(main(sys.argv, run, lambda entry: (
        f"pydpf N={entry['particles']}: {entry['batch_seconds']:.2f} s for the batch")))
