"""Five postures: labels from 3-D mocap, a Gaussian per posture over silhouette features, and the
posture transition matrix (Kwatra, Bobick & Johnson 2002, §3.1; the extended Ghost system).

Postures (this order everywhere): standing, sitting, crawling/bending, lying facing left (head
toward the image's left), lying facing right.

**Labels** (:func:`posture_labels`) come from the real 3-D motion by one written rule. Per frame,
with θ the torso's angle from vertical (neck − pelvis against world up) and r the pelvis height
above the clip's floor (its lowest joint over the whole clip) in leg lengths (hip → knee → ankle,
the clip's median):

    lying             θ > 55°  and r < 0.30
    standing          θ < 30°  and r ≥ 0.85
    sitting           θ < 45°  and r < 0.85        (kneeling upright counts as sitting)
    crawling/bending  otherwise                    (stooping on straight legs, all fours, crouch)

and a lying frame faces left when the head's image x is left of the pelvis's, right otherwise.

**Posture likelihood** (§3.1): per posture a Gaussian over the histogram features h
(:mod:`jaxtrack.vision.histograms`), mean μ_q and covariance Σ_q = S_q + λ (tr S / D) I (S_q the
posture's sample covariance, S the pooled one, λ the ``regularisation``), truncated so that no
posture is ever ruled out by a single silhouette:

    log p(h | q) = −½ min((h − μ_q)ᵀ Σ_q⁻¹ (h − μ_q), c) − ½ log |Σ_q|

with the cutoff c (``cutoff``, default the χ²_D 99.9 % quantile). The instantaneous (extended
Ghost) posture is argmax_q log p(h | q).

**Mixture components.** The paper learned each posture's Gaussian from one camera. Seen from
several sides, and done in several ways (a stoop, a crouch, all fours), one posture's
silhouettes fall in separate groups that one Gaussian covers only with a broad covariance that
also takes in the other postures. With ``components = K > 1`` each posture's frames are split
by k-means (:func:`jaxtrack.priors.clustering.kmeans`) into up to K groups, each with its own
truncated, regularised Gaussian as above, weighted by its share of the posture's frames:

    log p(h | q) = log Σ_k w_qk exp(−½ min(d_qk(h), c) − ½ log |Σ_qk|)

K = 1 is the paper's model. A posture with fewer than :data:`FRAMES_PER_COMPONENT` frames per
component gets fewer components.

**Transitions**: T_ij = (n_ij + α) / Σ_j (n_ij + α) from the label sequences' frame-to-frame
counts n_ij; the pseudocount α (``pseudocount``) gives every transition the training data never
showed (lying → standing directly, say) a small nonzero probability instead of zero, so the
tracker can still follow a posture change faster than the training frame rate saw.

Files: ``.npz`` + JSON metadata with a format version, written atomically (as the GPLVM's).
See ``docs/mixed-state.md``.
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from jaxtrack._files import write_npz_atomically
from jaxtrack.priors.clustering import kmeans

__all__ = ["COVARIANCES", "CRAWLING", "LYING_LEFT", "LYING_RIGHT", "NUM_POSTURES", "POSTURE_NAMES",
           "SITTING", "STANDING", "LabelRule", "PostureFormatError", "PostureModel",
           "SavedPostureModel", "fit_posture_model", "load_posture_model", "posture_labels",
           "save_posture_model", "transition_counts"]

POSTURE_NAMES = ("standing", "sitting", "crawling_bending", "lying_left", "lying_right")
STANDING, SITTING, CRAWLING, LYING_LEFT, LYING_RIGHT = range(5)
NUM_POSTURES = len(POSTURE_NAMES)
FORMAT_NAME = "jaxtrack.postures"
FORMAT_VERSION = 2
_ARRAYS = ("means", "precisions", "log_determinants", "log_transition", "log_initial", "cutoff",
           "log_weights")
FRAMES_PER_COMPONENT = 20
"""A posture gets at most one mixture component per this many of its training frames."""


@dataclass(frozen=True)
class LabelRule:
    """The thresholds of the labelling rule (module docstring)."""

    lying_angle: float = 55.0
    lying_height: float = 0.30
    standing_angle: float = 30.0
    standing_height: float = 0.85
    sitting_angle: float = 45.0


def _marker(names: Sequence[str], name: str) -> int:
    if name not in names:
        raise ValueError(f"posture labels need the marker {name!r}; marker_names has "
                         f"{tuple(names)}")
    return list(names).index(name)


def posture_labels(joints_3d: np.ndarray, markers_2d: np.ndarray, marker_names: Sequence[str],
                   rule: LabelRule = LabelRule()) -> np.ndarray:
    """The posture of every frame of one clip by the written rule (module docstring).

    Args:
        joints_3d: ``(time, markers, 3)`` world metres, Y up: the whole clip (the floor and
            the leg length are taken over all its frames).
        markers_2d: ``(time, markers, 2)`` the same markers in the image (x right).
        marker_names: names of the markers; needs head, neck, pelvis, left/right hip, knee,
            ankle (the renderer's HumanEva-15 set has them).

    Returns:
        ``(time,)`` int32 posture indices.
    """
    joints_3d = np.asarray(joints_3d, np.float64)
    markers_2d = np.asarray(markers_2d, np.float64)
    if joints_3d.ndim != 3 or joints_3d.shape[2] != 3 or markers_2d.shape != (
            *joints_3d.shape[:2], 2):
        raise ValueError(f"joints_3d must be (time, markers, 3) and markers_2d (time, markers, "
                         f"2), got {joints_3d.shape} and {markers_2d.shape}")
    if not (np.all(np.isfinite(joints_3d)) and np.all(np.isfinite(markers_2d))):
        raise ValueError("joints_3d and markers_2d must be finite")
    index = {name: _marker(marker_names, name) for name in (
        "head", "neck", "pelvis", "left_hip", "left_knee", "left_ankle", "right_hip",
        "right_knee", "right_ankle")}
    torso = joints_3d[:, index["neck"]] - joints_3d[:, index["pelvis"]]
    cosine = torso[:, 1] / np.maximum(np.linalg.norm(torso, axis=1), 1e-12)
    angle = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
    legs = [np.linalg.norm(joints_3d[:, index[f"{side}_hip"]] - joints_3d[:, index[f"{side}_knee"]],
                           axis=1)
            + np.linalg.norm(joints_3d[:, index[f"{side}_knee"]]
                             - joints_3d[:, index[f"{side}_ankle"]], axis=1)
            for side in ("left", "right")]
    leg_length = float(np.median(np.concatenate(legs)))
    floor = joints_3d[..., 1].min()
    height = (joints_3d[:, index["pelvis"], 1] - floor) / leg_length
    head_left = markers_2d[:, index["head"], 0] < markers_2d[:, index["pelvis"], 0]
    labels = np.full(len(joints_3d), CRAWLING, dtype=np.int32)
    labels[(angle < rule.sitting_angle) & (height < rule.standing_height)] = SITTING
    labels[(angle < rule.standing_angle) & (height >= rule.standing_height)] = STANDING
    lying = (angle > rule.lying_angle) & (height < rule.lying_height)
    labels[lying & head_left] = LYING_LEFT
    labels[lying & ~head_left] = LYING_RIGHT
    return labels


class PostureModel(eqx.Module):
    """p(h | q) per posture, a mixture of K truncated Gaussians (K = 1: the paper's one), and
    the transition matrix T (module docstring).

    Attributes:
        means: ``(postures, components, features)`` μ_qk.
        precisions: ``(postures, components, features, features)`` Σ_qk⁻¹.
        log_determinants: ``(postures, components)`` log |Σ_qk|.
        log_transition: ``(postures, postures)`` log T_ij (rows sum to one).
        log_initial: ``(postures,)`` log of the first frames' posture frequencies.
        cutoff: the truncation c of the Mahalanobis distance.
        log_weights: ``(postures, components)`` log w_qk, each posture's summing to one; −inf
            for a component a posture does not use (it had too few frames).

    One Gaussian per posture may be given without the components axis (``means`` ``(postures,
    features)``, ``precisions`` ``(postures, features, features)``, ``log_determinants``
    ``(postures,)``, no ``log_weights``).
    """

    means: Float[Array, "postures components features"]
    precisions: Float[Array, "postures components features features"]
    log_determinants: Float[Array, "postures components"]
    log_transition: Float[Array, "postures postures"]
    log_initial: Float[Array, " postures"]
    cutoff: Float[Array, ""]
    log_weights: Float[Array, "postures components"]

    def __init__(self, means, precisions, log_determinants, log_transition, log_initial, cutoff,
                 log_weights=None):
        means, precisions = jnp.asarray(means), jnp.asarray(precisions)
        log_determinants = jnp.asarray(log_determinants)
        if means.ndim == 2:  # one Gaussian per posture
            means, precisions = means[:, None], precisions[:, None]
            log_determinants = log_determinants[:, None]
        self.means, self.precisions, self.log_determinants = means, precisions, log_determinants
        self.log_transition = jnp.asarray(log_transition)
        self.log_initial = jnp.asarray(log_initial)
        self.cutoff = jnp.asarray(cutoff)
        self.log_weights = (jnp.zeros(means.shape[:2], means.dtype) if log_weights is None
                            else jnp.asarray(log_weights))

    @property
    def num_features(self) -> int:
        return self.means.shape[-1]

    @property
    def num_components(self) -> int:
        return self.means.shape[1]

    def log_likelihoods(self, features: Float[Array, " features"]) -> Float[Array, " postures"]:
        """log p(h | q) for every posture q: the truncated Gaussians of §3.1, mixed."""
        difference = features[None, None, :] - self.means
        distance = jnp.einsum("qki,qkij,qkj->qk", difference, self.precisions, difference)
        per_component = (-0.5 * jnp.minimum(distance, self.cutoff)
                         - 0.5 * self.log_determinants + self.log_weights)
        return jax.nn.logsumexp(per_component, axis=1)

    def classify(self, features: Float[Array, "*batch features"]) -> Int[Array, "*batch"]:
        """The instantaneous (extended Ghost) posture, argmax_q p(h | q)."""
        flat = jnp.reshape(features, (-1, self.num_features))
        labels = jnp.argmax(jax.vmap(self.log_likelihoods)(flat), axis=-1)
        return jnp.reshape(labels, jnp.shape(features)[:-1])


def transition_counts(sequences: Sequence[np.ndarray]) -> np.ndarray:
    """``(postures, postures)`` counts n_ij of frame-to-frame label changes i → j."""
    counts = np.zeros((NUM_POSTURES, NUM_POSTURES))
    for labels in sequences:
        labels = np.asarray(labels)
        if labels.ndim != 1 or (labels.size and (labels.min() < 0
                                                 or labels.max() >= NUM_POSTURES)):
            raise ValueError(f"label sequences must be 1-D posture indices in [0, "
                             f"{NUM_POSTURES}), got shape {labels.shape}")
        np.add.at(counts, (labels[:-1], labels[1:]), 1)
    return counts


COVARIANCES = ("per-posture", "pooled")
"""``fit_posture_model``'s ``covariance``: each posture's (each component's) own sample
covariance (Ghost's), or one within-posture (within-component) covariance shared by all
(linear discriminant analysis's), which needs fewer frames of each posture to estimate."""


def fit_posture_model(features: Sequence[np.ndarray], labels: Sequence[np.ndarray], *,
                      regularisation: float = 0.2, pseudocount: float = 0.5,
                      cutoff: float | None = None, covariance: str = "per-posture",
                      components: int = 1, seed: int = 0) -> PostureModel:
    """Fit the per-posture Gaussians and T from labelled training sequences.

    Args:
        features: per sequence, ``(time, features)`` silhouette features (frames whose status
            was not ok left out, or the sequence cut there).
        labels: per sequence, ``(time,)`` posture indices (:func:`posture_labels`).
        regularisation: λ, the ridge added to each covariance relative to the pooled variance
            (0.2 chosen on the validation clips: ``jaxtrack.experiments.mixed_state.train``).
        pseudocount: α added to every transition count (unseen transitions stay possible).
        cutoff: the Mahalanobis truncation c; None takes the χ²_D 99.9 % quantile.
        covariance: ``"per-posture"`` (S_q, the extended Ghost's) or ``"pooled"``: every
            posture's Gaussian takes the within-posture covariance Σ_q (n_q − 1) S_q / (N − 5),
            plus the same ridge (:data:`COVARIANCES`); with components, the within-component
            covariance, pooled the same way.
        components: K, the most Gaussians per posture (module docstring; 1: the paper's).
        seed: the k-means seeding's seed (with ``components > 1``).

    Raises:
        ValueError: mismatched lengths, non-finite features, or a posture with fewer than two
            training frames (its covariance cannot be estimated).
    """
    from scipy import stats

    if len(features) != len(labels) or not features:
        raise ValueError(f"features and labels must be equally many non-empty lists of "
                         f"sequences, got {len(features)} and {len(labels)}")
    stacked_features = []
    for index, (values, names) in enumerate(zip(features, labels, strict=True)):
        values, names = np.asarray(values, np.float64), np.asarray(names)
        if values.ndim != 2 or names.shape != values.shape[:1]:
            raise ValueError(f"sequence {index}: features must be (time, features) and labels "
                             f"(time,), got {values.shape} and {names.shape}")
        if not np.all(np.isfinite(values)):
            raise ValueError(f"sequence {index}: features hold non-finite values")
        stacked_features.append(values)
    values = np.concatenate(stacked_features)
    names = np.concatenate([np.asarray(names) for names in labels])
    dimension = values.shape[1]
    if regularisation <= 0 or pseudocount < 0:
        raise ValueError(f"regularisation must be positive and pseudocount non-negative, got "
                         f"{regularisation} and {pseudocount}")
    if covariance not in COVARIANCES:
        raise ValueError(f"covariance must be one of {', '.join(COVARIANCES)}, got "
                         f"{covariance!r}")
    if not (isinstance(components, int | np.integer) and components >= 1):
        raise ValueError(f"components must be a whole number >= 1, got {components!r}")
    ridge = regularisation * np.trace(np.cov(values.T)) / dimension
    groups = []  # per posture: (frames, mean, sample covariance) of each component
    for posture, name in enumerate(POSTURE_NAMES):
        chosen = values[names == posture]
        if len(chosen) < 2:
            raise ValueError(f"posture {name!r} has {len(chosen)} training frames; at least 2 "
                             "are needed to estimate its covariance (add clips that show it)")
        count = int(min(components, max(1, len(chosen) // FRAMES_PER_COMPONENT)))
        split = (np.zeros(len(chosen), int) if count == 1
                 else kmeans(chosen, count, seed=seed + posture)[1])
        members = [chosen[split == k] for k in range(count)]
        groups.append([(len(part), part.mean(axis=0),
                        np.cov(part.T) if len(part) > 1 else np.zeros((dimension, dimension)))
                       for part in members])
    if covariance == "pooled":
        parts = [part for group in groups for part in group]
        shared = (sum((count - 1) * sample for count, _, sample in parts)
                  / (len(values) - len(parts)))
        groups = [[(count, mean, shared) for count, mean, _ in group] for group in groups]
    size = max(len(group) for group in groups)
    means = np.zeros((NUM_POSTURES, size, dimension))
    precisions = np.broadcast_to(np.eye(dimension), (NUM_POSTURES, size, dimension,
                                                     dimension)).copy()
    log_determinants = np.zeros((NUM_POSTURES, size))
    log_weights = np.full((NUM_POSTURES, size), -np.inf)
    for posture, group in enumerate(groups):
        total = sum(count for count, _, _ in group)
        for k, (count, mean, sample) in enumerate(group):
            regularised = sample + ridge * np.eye(dimension)
            means[posture, k], precisions[posture, k] = mean, np.linalg.inv(regularised)
            log_determinants[posture, k] = np.linalg.slogdet(regularised)[1]
            log_weights[posture, k] = np.log(count / total)
    counts = transition_counts(labels) + pseudocount
    transition = counts / counts.sum(axis=1, keepdims=True)
    first = np.bincount([int(np.asarray(seq)[0]) for seq in labels], minlength=NUM_POSTURES)
    initial = (first + pseudocount + 1e-12) / (first + pseudocount + 1e-12).sum()
    if cutoff is None:
        cutoff = float(stats.chi2.ppf(0.999, dimension))
    return PostureModel(jnp.asarray(means), jnp.asarray(precisions),
                        jnp.asarray(log_determinants), jnp.asarray(np.log(transition)),
                        jnp.asarray(np.log(initial)), jnp.asarray(float(cutoff)),
                        jnp.asarray(log_weights))


class PostureFormatError(ValueError):
    """A file is not a readable jaxtrack posture model (wrong kind, damaged, or newer)."""


@dataclass(frozen=True)
class SavedPostureModel:
    """A loaded posture model with the description saved beside it."""

    model: PostureModel
    description: dict = field(default_factory=dict)


def save_posture_model(path: str | os.PathLike, model: PostureModel, *,
                       description: dict | None = None) -> Path:
    """Write ``model`` to ``path`` (``.npz`` + JSON metadata), atomically. Returns the path."""
    path = Path(path)
    metadata = {"format": FORMAT_NAME, "format_version": FORMAT_VERSION,
                "postures": list(POSTURE_NAMES), "num_features": model.num_features,
                "num_components": model.num_components, "description": description or {}}
    contents = {name: np.asarray(getattr(model, name)) for name in _ARRAYS}
    return write_npz_atomically(path, contents, metadata)


def load_posture_model(path: str | os.PathLike) -> SavedPostureModel:
    """Read a file written by :func:`save_posture_model`.

    Raises:
        FileNotFoundError: no such file.
        PostureFormatError: damaged or truncated, not a posture model, a newer format version,
            or arrays of inconsistent shape or non-finite values.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such posture-model file")
    fail = lambda reason: PostureFormatError(f"{path}: {reason}")  # noqa: E731
    if not zipfile.is_zipfile(path):
        with open(path, "rb") as file:
            if file.read(4) == b"PK\x03\x04":
                raise fail("damaged or truncated posture-model file (a .npz archive without "
                           "its end; copy or train it again)")
        raise fail("not a jaxtrack posture-model file (not a .npz archive)")
    try:
        with np.load(path, allow_pickle=False) as archive:
            if "metadata" not in archive.files:
                raise fail("not a jaxtrack posture-model file (no metadata)")
            metadata = json.loads(str(archive["metadata"]))
            if metadata.get("format") != FORMAT_NAME:
                raise fail(f"not a jaxtrack posture-model file (format "
                           f"{metadata.get('format')!r}, expected {FORMAT_NAME!r})")
            if metadata.get("format_version", 0) > FORMAT_VERSION:
                raise fail(f"format version {metadata['format_version']} is newer than this "
                           f"jaxtrack reads ({FORMAT_VERSION}); upgrade jaxtrack")
            # version 1 held one Gaussian per posture and no weights
            needed = _ARRAYS if metadata.get("format_version", 0) >= 2 else _ARRAYS[:-1]
            missing = [name for name in needed if name not in archive.files]
            if missing:
                raise fail(f"missing arrays {missing}")
            values = {name: np.array(archive[name], np.float64) for name in needed}
    except PostureFormatError:
        raise
    except (zipfile.BadZipFile, EOFError, OSError, ValueError, KeyError) as error:
        raise fail(f"damaged or truncated posture-model file ({type(error).__name__}: "
                   f"{error})") from None
    dimension = metadata.get("num_features")
    if "log_weights" not in values:
        values["means"], values["precisions"] = values["means"][:, None], values[
            "precisions"][:, None]
        values["log_determinants"] = values["log_determinants"][:, None]
        values["log_weights"] = np.zeros(values["log_determinants"].shape)
    size = metadata.get("num_components", 1)
    expected = {"means": (NUM_POSTURES, size, dimension),
                "precisions": (NUM_POSTURES, size, dimension, dimension),
                "log_determinants": (NUM_POSTURES, size), "log_transition": (NUM_POSTURES,) * 2,
                "log_initial": (NUM_POSTURES,), "cutoff": (), "log_weights": (NUM_POSTURES, size)}
    for name, shape in expected.items():
        if values[name].shape != shape:
            raise fail(f"array {name!r} has shape {values[name].shape}, expected {shape}")
        finite = np.isfinite(values[name])
        if name == "log_weights":  # −inf marks a component a posture does not use
            finite |= values[name] == -np.inf
            if not np.all(np.any(np.isfinite(values[name]), axis=1)):
                raise fail("array 'log_weights' gives a posture no component")
        if not np.all(finite):
            raise fail(f"array {name!r} holds non-finite values")
    model = PostureModel(*(jnp.asarray(values[name]) for name in _ARRAYS))
    return SavedPostureModel(model, metadata.get("description", {}))
