"""The latent tracker's candidate priors and its automatic start, as the studies of
``papers/tian2005`` run them.

- :func:`candidate_prior`: a GPLVM trained on one of :data:`jaxtrack.data.clip_sets.PRIOR_CLIPS`'
  sets (optionally mirrored, one per body part, back-constrained, or with more latent
  dimensions), cached under its :func:`prior_tag`.
- :func:`auto_initial_pose`: ``jaxtrack track --init face`` on one frame, with a record of how
  far its pose is from the frame's truth.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from jaxtrack.data.clip_sets import PRIOR_CLIPS


def prior_tag(name: str, mirror: bool, parts: bool,
              back_constraint: float | None = None, latent_dim: int = 2) -> str:
    """The name of a candidate prior (its results folder and cache): ``gestures_mirrored_parts``,
    ``waves_bc0.5`` (back-constrained, width 0.5), ``waves_q3`` (3-D latent spaces)."""
    return (name + ("_mirrored" if mirror else "") + ("_parts" if parts else "")
            + ("" if back_constraint is None else f"_bc{back_constraint:g}")
            + ("" if latent_dim == 2 else f"_q{latent_dim}"))


def candidate_prior(name: str, mirror: bool = False, parts: bool = False,
                    back_constraint: float | None = None, latent_dim: int = 2, *,
                    cache_folder: str | Path | None = None, **training):
    """The candidate prior ``name`` of :data:`~jaxtrack.data.clip_sets.PRIOR_CLIPS`.

    Args:
        name: a key of ``PRIOR_CLIPS`` (``"waves"``, ``"gestures"``).
        mirror: train on the clips' left-right mirror images too.
        parts: one GPLVM per body part (``UPPER_BODY_PARTS``) instead of one.
        back_constraint: kernel width of a back-constrained GPLVM (None: free latents).
        latent_dim: the latent dimension (of each part's with ``parts``).
        cache_folder: where the trained prior is cached as
            ``prior_training_<tag>[_quick].npz`` (None: not cached).
        **training: further ``train_prior`` settings (a smaller prior's; the cache name then
            ends in ``_quick``).

    Returns:
        the :class:`~jaxtrack.priors.train.TrainedPrior`.

    Raises:
        ValueError: ``name`` is not a candidate set.
    """
    from jaxtrack.priors.gplvm import UPPER_BODY_PARTS
    from jaxtrack.priors.train import train_prior

    if name not in PRIOR_CLIPS:
        raise ValueError(f"prior {name!r} is not one of {', '.join(PRIOR_CLIPS)}")
    suffix = "_quick" if training else ""
    tag = prior_tag(name, mirror, parts, back_constraint, latent_dim)
    cache = (None if cache_folder is None
             else Path(cache_folder) / f"prior_training_{tag}{suffix}.npz")
    return train_prior(PRIOR_CLIPS[name], progress=False, mirror=mirror,
                       parts=UPPER_BODY_PARTS if parts else None,
                       back_constraint=back_constraint, latent_dim=latent_dim, **training,
                       cache=cache)


def auto_initial_pose(prior, image: np.ndarray, background_rgb: np.ndarray,
                      truth: np.ndarray, mask: np.ndarray | None = None
                      ) -> tuple[np.ndarray | None, dict]:
    """``jaxtrack track --init face`` on one frame, scored against the frame's truth.

    Args:
        prior: a :class:`~jaxtrack.priors.train.TrainedPrior` (one GPLVM).
        image: ``(H, W, 3)`` RGB frame.
        background_rgb: ``(H, W, 3)`` the scene without the person; the foreground is taken
            against it unless ``mask`` is given.
        truth: ``(12, 2)`` the frame's true markers (``UPPER_BODY_12``), pixels.
        mask: ``(H, W)`` the person's mask of the frame (``--masks``), or None.

    Returns:
        the initial markers ``(12, 2)`` (None when it finds no one) and a record: the winning
        box's source, its overlap, the pose's error against ``truth`` in torso lengths and the
        seconds taken; or ``{"failed": why}``.
    """
    from jaxtrack.body import UPPER_BODY_12
    from jaxtrack.evaluation import marker_errors, torso_lengths
    from jaxtrack.trackers.autoinit import AutoInitError, auto_initialise
    from jaxtrack.vision import FaceDetectorUnavailableError, foreground_mask

    started = time.perf_counter()
    foreground = (foreground_mask(image, background_rgb) if mask is None
                  else np.asarray(mask, bool))
    try:
        found = auto_initialise(prior.model, prior.template, image, foreground)
    except (AutoInitError, FaceDetectorUnavailableError) as error:
        return None, {"failed": " ".join(str(error).split())}
    markers = np.asarray(found.markers, np.float64)
    error = marker_errors(markers[None], truth[None])[0]
    torso = torso_lengths(truth[None], UPPER_BODY_12)[0]
    return markers, {"source": found.source, "overlap": float(found.score),
                     "error_torso": float(error / torso),
                     "seconds": time.perf_counter() - started}


__all__ = ["auto_initial_pose", "candidate_prior", "prior_tag"]
