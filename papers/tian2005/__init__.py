"""Tian, Li & Sclaroff (2005), "Tracking Human Body Pose on a Learned Smooth Space": the latent
tracker in the paper's protocol and on people the prior never saw, and the studies behind it
(README.md)."""

from pathlib import Path

RUNS = Path("papers/tian2005/results/runs")
"""Where the studies write their runs and cache their priors (ignored by git; run from the
repository root). The results the README quotes are committed beside it in ``results/``."""


def candidate_prior(name: str, mirror: bool = False, parts: bool = False,
                    back_constraint: float | None = None, latent_dim: int = 2, **training):
    """The candidate prior ``name`` of :data:`jaxtrack.data.clip_sets.PRIOR_CLIPS`
    (:func:`jaxtrack.experiments.priors.candidate_prior`), cached in ``RUNS/tracking``."""
    from jaxtrack.experiments.priors import candidate_prior as train

    return train(name, mirror, parts, back_constraint, latent_dim,
                 cache_folder=RUNS / "tracking", **training)
