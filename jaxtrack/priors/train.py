"""Training the GPLVM pose prior of the latent-space tracker from clips (names or files), cached.

Upper-body SPM poses of real clips seen from several viewpoints (``jaxtrack.priors.poses``) are
fitted with Algorithm 1 of Tian et al. (``jaxtrack.priors.gplvm.fit_gplvm``); the result is saved
with its SPM template and reused when a later call asks for the same settings.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.body import SPMTemplate
from jaxtrack.priors.gplvm import (
    GPLVM,
    GPLVMFormatError,
    PartsGPLVM,
    fit_gplvm,
    load_gplvm,
    part_features,
    save_gplvm,
)
from jaxtrack.priors.poses import clip_motions, pose_features, pose_set

__all__ = ["TrainedPrior", "load_prior", "train_prior"]


@dataclass(frozen=True)
class TrainedPrior:
    """A GPLVM with the SPM template its poses are expressed in.

    ``training_states`` (``(n, 25)`` SPM states) and ``training_sequence_ids`` (``(n,)``, one id
    per clip × view) are the poses it was trained on, in order: the baselines' dynamics are
    learned from them (``jaxtrack.experiments.build_tracker``), so that no method learns
    anything from the clip it is scored on. None for a prior saved before they were kept.
    """

    model: GPLVM | PartsGPLVM
    template: SPMTemplate
    description: dict
    seconds: float = 0.0
    labels: tuple[str, ...] = ()
    training_states: np.ndarray | None = None
    training_sequence_ids: np.ndarray | None = None


_TEMPLATE_ARRAYS = ("reference_lengths", "reference_angles")


def _settings_key(settings: dict) -> str:
    return hashlib.sha256(json.dumps(settings, sort_keys=True).encode()).hexdigest()[:16]


def load_prior(path: str | Path) -> TrainedPrior:
    """A prior saved by :func:`train_prior` (its GPLVM, SPM template and clip labels).

    Raises:
        FileNotFoundError: no such file.
        GPLVMFormatError: the file is damaged, not a GPLVM, or a GPLVM saved without the SPM
            template a trained prior keeps.
    """
    saved = load_gplvm(path)
    missing = [name for name in _TEMPLATE_ARRAYS if name not in saved.arrays]
    if missing:
        raise GPLVMFormatError(f"{path}: a GPLVM without the SPM template of a trained prior "
                               f"(missing {', '.join(missing)}); not written by train_prior")
    template = SPMTemplate(*(jnp.asarray(saved.arrays[name]) for name in _TEMPLATE_ARRAYS))
    return TrainedPrior(saved.model, template, saved.description,
                        labels=tuple(saved.arrays.get("labels", ())),
                        training_states=saved.arrays.get("training_states"),
                        training_sequence_ids=saved.arrays.get("training_sequence_ids"))


def train_prior(clips: Sequence[str], *, views: int = 5, fps: float = 30.0,
                active_size: int = 200, iterations: int = 3, active_steps: int = 300,
                optimiser: str = "bfgs", seed: int = 0, cache: str | Path | None = None,
                progress: bool = True, asf: str | os.PathLike | None = None,
                mirror: bool = False,
                parts: Mapping[str, Sequence[int]] | None = None,
                back_constraint: float | None = None, latent_dim: int = 2) -> TrainedPrior:
    """Train (or load from ``cache`` when it was trained with the same settings) a GPLVM.

    Args:
        clips: catalogue clip names (``jaxtrack.data.list_clips()``) or paths to ``.bvh`` or
            ``.amc`` files; a file is keyed in the cache by its name and the SHA-256 of its
            bytes (``jaxtrack.data.clip_identity``), a name by itself.
        views: training viewpoints per clip, spread over ±45° in front of the subject.
        iterations: Algorithm 1's outer iterations.
        active_steps: eq. 1 steps per iteration. The protocol keeps the 3 × 300 steps and
            float64 non-active solves that its tracking results were measured with
            (``fit_gplvm``'s faster defaults track as well: see docs/gplvm.md, "Training").
        optimiser: eq. 1's minimiser in Algorithm 1 (``fit_gplvm``'s ``"bfgs"``, what every
            tracking result was measured with, or ``"lbfgs"``).
        cache: ``.npz`` path; reused when its settings match, (re)written otherwise.
        asf: the skeleton of every ``.amc`` path among ``clips`` (default: the one beside each).
        mirror: also train on each clip's left-right mirror image (:meth:`Motion.mirror`: a
            right-hand wave becomes a left-hand one), named ``<clip> (mirrored)``.
        parts: None (Tian et al.: one GPLVM of the whole upper body), or part name → its links
            (indices into ``SPM_LINKS``, e.g. :data:`~jaxtrack.priors.gplvm.UPPER_BODY_PARTS`):
            one GPLVM per part over the same poses, a :class:`~jaxtrack.priors.gplvm.PartsGPLVM`
            (why: papers/tian2005/history.md, "A prior that generalises").
        back_constraint: None (free latents, Tian et al.), or the width of a back-constrained
            GPLVM (``fit_gplvm``'s ``back_constraint``: every latent a smooth function of its
            pose; papers/tian2005/history.md, "A prior that generalises").
        latent_dim: the latent dimension of each GPLVM (2, Tian et al.'s).

    Raises:
        jaxtrack.priors.gplvm.GPLVMFormatError: ``cache`` exists but is damaged or not a GPLVM.
    """
    if not clips:
        raise ValueError("train_prior needs at least one training clip")
    from jaxtrack.data import clip_identity

    identities = sorted(clip_identity(clip, asf=asf) for clip in clips)
    settings = {"clips": identities, "views": views, "fps": fps, "active_size": active_size,
                "iterations": iterations, "active_steps": active_steps,
                "inactive_dtype": "float64", "seed": seed, "features": "spm_link_vectors",
                # 2: μ from all poses through the active set; 3: fit_gplvm's faster defaults;
                # 4: the training poses kept for the baselines' dynamics
                "version": 4}
    if optimiser != "bfgs":  # absent for BFGS, so that existing caches of it stay valid
        settings["optimiser"] = optimiser
    if mirror:  # absent without, likewise
        settings["mirror"] = True
    if back_constraint is not None:  # absent without, likewise
        settings["back_constraint"] = float(back_constraint)
    if latent_dim != 2:  # absent for the paper's 2, likewise
        settings["latent_dim"] = int(latent_dim)
    if parts is not None:
        parts = {str(name): tuple(int(link) for link in links) for name, links in parts.items()}
        settings["parts"] = {name: list(links) for name, links in parts.items()}
    key = _settings_key(settings)
    if cache is not None and Path(cache).is_file():
        saved = load_prior(cache)
        if saved.description.get("settings_key") == key:
            return saved
    motions = clip_motions(clips, asf=asf)
    if mirror:
        motions |= {f"{name} (mirrored)": motion.mirror() for name, motion in motions.items()}
    poses = pose_set(motions, views=views, fps=fps)
    with jax.enable_x64(True):
        features = np.asarray(pose_features(poses.states, poses.template))
    fit_options = dict(active_size=active_size, iterations=iterations, active_steps=active_steps,
                       optimiser=optimiser, inactive_dtype=jnp.float64,
                       sequence_ids=poses.sequence_ids, fps=poses.fps, seed=seed,
                       back_constraint=back_constraint, latent_dim=latent_dim,
                       progress=progress)
    if parts is None:
        fit = fit_gplvm(features, **fit_options)
        model, trace, init, seconds = fit.model, fit.trace, fit.init, fit.seconds
    else:
        fits = {name: fit_gplvm(part_features(features, links), **fit_options)
                for name, links in parts.items()}
        model = PartsGPLVM(tuple(fit.model for fit in fits.values()), tuple(parts.values()),
                           tuple(parts))
        trace = [{"part": name, **entry} for name, fit in fits.items() for entry in fit.trace]
        init = "; ".join(f"{name}: {fit.init}" for name, fit in fits.items())
        seconds = sum(fit.seconds for fit in fits.values())
    labels = tuple(str(name) for name in poses.clip_names)
    description = {"settings": settings, "settings_key": key, "num_poses": len(features),
                   "init": init, "train_seconds": seconds}
    if cache is not None:
        Path(cache).parent.mkdir(parents=True, exist_ok=True)
        save_gplvm(cache, model, description=description, trace=trace, arrays={
            "reference_lengths": np.asarray(poses.template.reference_lengths),
            "reference_angles": np.asarray(poses.template.reference_angles),
            "labels": np.array(labels),
            "training_states": np.asarray(poses.states, np.float64),
            "training_sequence_ids": np.asarray(poses.sequence_ids),
        })
    return TrainedPrior(model, poses.template, description, seconds, labels,
                        training_states=np.asarray(poses.states, np.float64),
                        training_sequence_ids=np.asarray(poses.sequence_ids))
