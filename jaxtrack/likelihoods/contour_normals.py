"""Ong & Gong's (2002, §5.2) fitness of a hybrid vector to a frame: contour normals and hands.

    f_C = 1/N_C Σ_i d_i²        d_i: distance along vertex i's normal to the strongest edge
    f_S = ½ Σ_h |x_h − y_h|²    the model's hands x_h against the observed skin blobs y_h (eq. 8)
    f   = O exp(−f_C / 2P) + R exp(−f_S / 2Q)                                        (eq. 9)

Contour and hands are relative to the head; the observed head (the top skin blob) places them
in the image. For each model contour vertex the search samples the frame's gradient-magnitude
map (``jaxtrack.vision.normals.gradient_magnitude``) at fixed offsets ``−L … L`` along the
vertex's normal (the offsets are precomputed; only the normal's direction depends on the
particle, so a particle costs N_C × offsets gathers and no whole-image work) and takes the
offset of the largest magnitude. A vertex whose strongest sample is below ``edge_threshold``
(no edge within reach), or all of whose samples fall outside the frame, is given the search
range L as its distance. The two hands are matched to the two blobs in whichever order is
nearer (f_S's minimum over the two assignments), so a mislabelled blob pair costs nothing.

A frame without a silhouette or without three skin blobs (``ContourObservation.found`` False)
scores every hybrid vector alike (log-fitness 0): the filter predicts through it and the
tracker reports the frame's status. ``docs/linear-combination.md`` says how P and Q were chosen.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

__all__ = ["ContourObservation", "FitnessSettings", "contour_distances", "contour_normals",
           "hand_distance", "log_fitness", "normal_offsets"]


class ContourObservation(eqx.Module):
    """One frame as the linear-combination tracker sees it (a leading ``time`` axis on every
    leaf for a sequence).

    Attributes:
        gradient: ``(height, width)`` gradient magnitude in [0, 1].
        head: ``(2,)`` the head blob, pixels.
        hands: ``(2, 2)`` the hand blobs, left-most first.
        found: the frame has a silhouette and three skin blobs (else head and hands are
            meaningless and the frame is scored flat).
    """

    gradient: Float[Array, "height width"]
    head: Float[Array, " 2"]
    hands: Float[Array, "2 2"]
    found: Bool[Array, ""]


class FitnessSettings(eqx.Module):
    """Eq. 9's weights and tolerances and the normal search's reach.

    The weights, tolerances and threshold are numbers a compiled tracker takes as inputs: give
    them as JAX scalars to sweep them without recompiling (Python floats compile per value).

    Attributes:
        contour_weight, hands_weight: O and R (Ong & Gong: 0.5 each).
        contour_tolerance, hands_tolerance: P and Q, squared pixels (64 and 16: chosen on
            the validation subject, docs/defaults.md).
        search_range: L, pixels searched on each side of a vertex.
        edge_threshold: the weakest gradient magnitude (of [0, 1]) that counts as an edge.
    """

    contour_weight: float = 0.5
    hands_weight: float = 0.5
    contour_tolerance: float = 64.0
    hands_tolerance: float = 16.0
    search_range: int = eqx.field(static=True, default=10)
    edge_threshold: float = 0.05

    def __check_init__(self):
        for name in ("contour_weight", "hands_weight"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        if self.contour_weight + self.hands_weight <= 0:
            raise ValueError("contour_weight and hands_weight cannot both be 0")
        for name in ("contour_tolerance", "hands_tolerance"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0 (squared pixels), got "
                                 f"{getattr(self, name)!r}")
        if not isinstance(self.search_range, int) or self.search_range < 1:
            raise ValueError(f"search_range must be a positive integer (pixels), got "
                             f"{self.search_range!r}")
        if not 0 <= self.edge_threshold < 1:
            raise ValueError(f"edge_threshold must be in [0, 1), got {self.edge_threshold!r}")

    def record(self) -> dict:
        """The settings as JSON-able numbers."""
        return {name: float(getattr(self, name)) if name != "search_range"
                else int(self.search_range) for name in (
                    "contour_weight", "hands_weight", "contour_tolerance", "hands_tolerance",
                    "search_range", "edge_threshold")}


def normal_offsets(search_range: int) -> Float[Array, " offsets"]:
    """The offsets ``−L, …, L`` (pixels) sampled along each normal, nearest first on ties."""
    return jnp.arange(-search_range, search_range + 1, dtype=jnp.float32)


def contour_normals(contour: Float[Array, "contour 2"]) -> Float[Array, "contour 2"]:
    """Unit normals of a closed contour: each vertex's neighbour chord turned by 90°."""
    chord = jnp.roll(contour, -1, axis=0) - jnp.roll(contour, 1, axis=0)
    normal = jnp.stack([chord[:, 1], -chord[:, 0]], axis=-1)
    length = jnp.linalg.norm(normal, axis=-1, keepdims=True)
    return normal / jnp.where(length > 0, length, 1.0)


def contour_distances(gradient: Float[Array, "height width"], contour: Float[Array, "contour 2"],
                      search_range: int, edge_threshold: float) -> Float[Array, " contour"]:
    """d_i of every vertex: the distance along its normal to the pixel of greatest gradient.

    Args:
        gradient: ``(height, width)`` gradient magnitude.
        contour: ``(contour, 2)`` vertices in image coordinates ``(x, y)``.
        search_range: L (pixels).
        edge_threshold: below this the vertex has no edge in reach and gets L.
    """
    height, width = gradient.shape
    offsets = normal_offsets(search_range).astype(contour.dtype)
    normals = contour_normals(contour)
    samples = contour[:, None, :] + offsets[None, :, None] * normals[:, None, :]
    columns = jnp.round(samples[..., 0]).astype(jnp.int32)
    rows = jnp.round(samples[..., 1]).astype(jnp.int32)
    inside = (columns >= 0) & (columns < width) & (rows >= 0) & (rows < height)
    flat = jnp.clip(rows, 0, height - 1) * width + jnp.clip(columns, 0, width - 1)
    values = jnp.where(inside, gradient.reshape(-1)[flat], 0.0)
    # ties go to the nearest offset: rank by magnitude, then by closeness to the vertex
    score = values - 1e-6 * jnp.abs(offsets)[None, :]
    best = jnp.argmax(score, axis=1)
    strongest = jnp.take_along_axis(values, best[:, None], axis=1)[:, 0]
    distance = jnp.abs(offsets)[best]
    return jnp.where(strongest >= edge_threshold, distance,
                     jnp.asarray(search_range, contour.dtype))


def hand_distance(model_hands: Float[Array, "2 2"], observed_hands: Float[Array, "2 2"]
                  ) -> Float[Array, ""]:
    """Ong & Gong eq. 8: f_S = ½ Σ_h |x_h − y_h|², over the nearer of the two pairings."""
    straight = jnp.sum((model_hands - observed_hands) ** 2)
    swapped = jnp.sum((model_hands - observed_hands[::-1]) ** 2)
    return 0.5 * jnp.minimum(straight, swapped)


def log_fitness(contour: Float[Array, "contour 2"], hands: Float[Array, "2 2"],
                observation: ContourObservation, settings: FitnessSettings) -> Float[Array, ""]:
    """log f of one hybrid vector's contour and hands (relative to the head) on one frame.

    Ong & Gong eq. 9: f = O exp(−f_C/2P) + R exp(−f_S/2Q), evaluated in log space so that a
    poor fit gives a finite, very negative number instead of log 0; 0 on a frame without
    observations (``observation.found`` False).
    """
    head = observation.head.astype(contour.dtype)
    safe_head = jnp.where(observation.found, head, 0.0)  # NaN-free on a frame without blobs
    distances = contour_distances(observation.gradient, contour + safe_head,
                                  settings.search_range, settings.edge_threshold)
    f_contour = jnp.mean(distances**2)
    safe_hands = jnp.where(observation.found, observation.hands.astype(contour.dtype) - head,
                           0.0)
    f_hands = hand_distance(hands, safe_hands)
    # Ong & Gong eq. (9), in log space
    terms = jnp.stack([
        jnp.log(jnp.asarray(settings.contour_weight, contour.dtype))
        - f_contour / (2 * settings.contour_tolerance),
        jnp.log(jnp.asarray(settings.hands_weight, contour.dtype))
        - f_hands / (2 * settings.hands_tolerance)])
    value = jax.nn.logsumexp(terms)
    return jnp.where(observation.found, value, jnp.zeros_like(value))
