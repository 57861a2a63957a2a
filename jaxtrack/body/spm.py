"""The Scaled Prismatic Model (SPM) of the upper body: 25 numbers → 12 image markers.

Cham & Rehg (1999) model each body part as a link that rotates in the image plane and stretches
along its axis (a "scaled prism"); Tian, Li & Sclaroff (2005) use an upper body of 11 such links
and a 25-d state, learn a GPLVM over it and decode every particle through :func:`spm_forward`.

Markers (``SPM_MARKERS``, the order of ``body.markers.UPPER_BODY_12``)::

    0 head  1 neck  2 thorax  3 pelvis  4 right_shoulder  5 right_elbow  6 right_wrist
    7 right_hip  8 left_shoulder  9 left_elbow  10 left_wrist  11 left_hip

Links (``SPM_LINKS``, parent → child; the tree is rooted at the neck)::

    0 neck→head             4 right_shoulder→right_elbow   8 left_shoulder→left_elbow
    1 neck→thorax           5 right_elbow→right_wrist      9 left_elbow→left_wrist
    2 thorax→pelvis         6 pelvis→right_hip            10 pelvis→left_hip
    3 neck→right_shoulder   7 neck→left_shoulder

State layout (``SPM_STATE_NAMES``), image coordinates in pixels with y pointing down:

    ===========  =================  ======================================================
    index        name               meaning
    ===========  =================  ======================================================
    0            log_scale          log s; s = neck–pelvis distance in pixels (template unit)
    1, 2         translation_x, _y  the neck's pixel position
    3 + 2k       angle_<link k>     θ_k: the link's absolute image angle minus the template's
                                    reference angle for that link (radians)
    4 + 2k       log_length_<k>     ℓ_k: log of the link length over s·L_k
    ===========  =================  ======================================================

so that, for k = 0..10 (Cham & Rehg 1999, eq. 1: a prismatic link of length s·L_k·e^ℓ_k),

    end_k = start_k + s · L_k · exp(ℓ_k) · (cos(φ_k + θ_k), sin(φ_k + θ_k)),

where ``L_k`` and ``φ_k`` are the template's reference length and angle (:class:`SPMTemplate`).

Angles are **absolute** (each link's direction in the image, not relative to its parent) and
measured from the template's mean direction. Absolute angles decouple the links, so a pose is
converted in closed form and every state entry has a local meaning; measuring from the mean
direction keeps ordinary poses far from the ±π wrap, which matters for a GPLVM trained on them.
The 25 numbers hold one redundant degree of freedom (s against all ℓ_k); :func:`spm_fit` fixes it
by taking s to be the neck–pelvis distance.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, ArrayLike, Float

__all__ = [
    "SPM_LINKS",
    "SPM_MARKERS",
    "SPM_STATE_NAMES",
    "SPM_STATE_SIZE",
    "SPMFitInfo",
    "SPMTemplate",
    "build_template",
    "spm_fit",
    "spm_fit_with_info",
    "spm_forward",
    "spm_initial_state",
]

SPM_MARKERS = (
    "head", "neck", "thorax", "pelvis",
    "right_shoulder", "right_elbow", "right_wrist", "right_hip",
    "left_shoulder", "left_elbow", "left_wrist", "left_hip",
)
SPM_LINKS = (
    ("neck", "head"), ("neck", "thorax"), ("thorax", "pelvis"),
    ("neck", "right_shoulder"), ("right_shoulder", "right_elbow"), ("right_elbow", "right_wrist"),
    ("pelvis", "right_hip"),
    ("neck", "left_shoulder"), ("left_shoulder", "left_elbow"), ("left_elbow", "left_wrist"),
    ("pelvis", "left_hip"),
)
NUM_LINKS = len(SPM_LINKS)
SPM_STATE_SIZE = 3 + 2 * NUM_LINKS
_ROOT = SPM_MARKERS.index("neck")
# The module's constants are plain Python tuples, never NumPy arrays, and become arrays afresh where
# they are used. JAX (0.10) keeps the canonical form of a NumPy array it has converted (int64 →
# int32, float64 → float32 without x64) for as long as a traced function holds it, keyed on the
# array object and not on ``jax_enable_x64``: a module-level array used once under one setting would
# come back with that setting's dtype under the other (int32 indices beside int64 sizes fail
# inside the gather).
_PARENTS = tuple(SPM_MARKERS.index(parent) for parent, _ in SPM_LINKS)
_CHILDREN = tuple(SPM_MARKERS.index(child) for _, child in SPM_LINKS)
SPM_STATE_NAMES = ("log_scale", "translation_x", "translation_y") + tuple(
    name for parent, child in SPM_LINKS
    for name in (f"angle_{parent}_{child}", f"log_length_{parent}_{child}")
)


def _ancestry() -> tuple[tuple[float, ...], ...]:
    """``A[m, k] = 1`` when link k lies on the path from the neck to marker m."""
    link_of_child = {child: k for k, child in enumerate(_CHILDREN)}
    matrix = np.zeros((len(SPM_MARKERS), NUM_LINKS))
    for marker in range(len(SPM_MARKERS)):
        node = marker
        while node != _ROOT:
            k = link_of_child[node]
            matrix[marker, k] = 1.0
            node = _PARENTS[k]
    return tuple(map(tuple, matrix.tolist()))


# markers = neck + A @ link_vectors: the whole kinematic chain as one small matrix product.
_ANCESTRY = _ancestry()


class SPMTemplate(eqx.Module):
    """The SPM's static template: each link's reference length and direction.

    Attributes:
        reference_lengths: ``(11,)`` ``L_k`` in units of the neck–pelvis distance.
        reference_angles: ``(11,)`` ``φ_k``, mean image direction of each link (radians, y down).
    """

    reference_lengths: Float[Array, "11"]
    reference_angles: Float[Array, "11"]


def _check_markers(markers: Array) -> None:
    if markers.shape[-2:] != (len(SPM_MARKERS), 2):
        raise ValueError(
            f"SPM markers must have shape (..., {len(SPM_MARKERS)}, 2) in the order "
            f"{SPM_MARKERS}, got {markers.shape}"
        )


def _link_vectors(markers: Array) -> Array:
    return markers[..., jnp.asarray(_CHILDREN), :] - markers[..., jnp.asarray(_PARENTS), :]


def _torso_length(markers: Array) -> Array:
    torso = markers[..., SPM_MARKERS.index("pelvis"), :] - markers[..., _ROOT, :]
    return jnp.linalg.norm(torso, axis=-1)


@eqx.filter_jit
def build_template(markers_2d: Float[ArrayLike, "time markers 2"]) -> SPMTemplate:
    """The template of a training set: mean normalised link lengths and mean link directions.

    Args:
        markers_2d: ``(time, 12, 2)`` image markers (any leading axes), order ``SPM_MARKERS``.

    Returns:
        ``L_k`` = mean over frames of ``|link_k| / |pelvis − neck|``; ``φ_k`` = circular mean of
        the link's direction.
    """
    markers = jnp.asarray(markers_2d)
    _check_markers(markers)
    markers = markers.reshape(-1, len(SPM_MARKERS), 2)
    vectors = _link_vectors(markers)
    lengths = jnp.linalg.norm(vectors, axis=-1) / _torso_length(markers)[:, None]
    unit = vectors / jnp.maximum(jnp.linalg.norm(vectors, axis=-1, keepdims=True), 1e-12)
    mean_direction = jnp.mean(unit, axis=0)
    return SPMTemplate(
        reference_lengths=jnp.mean(lengths, axis=0),
        reference_angles=jnp.arctan2(mean_direction[:, 1], mean_direction[:, 0]),
    )


@eqx.filter_jit
def spm_forward(
    state: Float[ArrayLike, "25"], template: SPMTemplate
) -> Float[Array, "markers 2"]:
    """The 12 image markers ``(12, 2)`` of one SPM state ``(25,)`` (see the module's table).

    Pure JAX for one state; ``jax.vmap`` it over particles. Output dtype follows ``state``.
    """
    state = jnp.asarray(state)
    if state.shape != (SPM_STATE_SIZE,):
        raise ValueError(f"an SPM state has shape ({SPM_STATE_SIZE},), got {state.shape}")
    dtype = jnp.result_type(state, float)
    state = state.astype(dtype)
    scale = jnp.exp(state[0])
    angles = state[3::2] + template.reference_angles.astype(dtype)
    # Cham & Rehg (1999), eq. 1: each link is a prism of length s·L_k·e^ℓ_k at angle φ_k + θ_k.
    lengths = scale * template.reference_lengths.astype(dtype) * jnp.exp(state[4::2])
    vectors = lengths[:, None] * jnp.stack([jnp.cos(angles), jnp.sin(angles)], axis=-1)
    return spm_chain(state[1:3], vectors)


def spm_chain(neck: Float[Array, "2"], link_vectors: Float[Array, "11 2"]
              ) -> Float[Array, "markers 2"]:
    """The 12 markers ``(12, 2)`` of a neck position and the 11 links' image vectors (pixels):
    each marker is the neck plus the links on its path (the end of :func:`spm_forward`)."""
    return neck + jnp.asarray(_ANCESTRY, link_vectors.dtype) @ link_vectors


@eqx.filter_jit
def spm_initial_state(
    markers_2d: Float[ArrayLike, "*batch markers 2"],
    template: SPMTemplate,
    minimum_length: float = 1e-6,
) -> Float[Array, "*batch 25"]:
    """Closed-form SPM state of markers: link angles by atan2, log length ratios, scale = torso.

    Exact (up to floating point) whenever no link is shorter than ``minimum_length`` torso lengths;
    angles are wrapped to ``(−π, π]`` around the template's directions.
    """
    markers = jnp.asarray(markers_2d)
    _check_markers(markers)
    dtype = jnp.result_type(markers, float)
    markers = markers.astype(dtype)
    torso = jnp.maximum(_torso_length(markers), jnp.finfo(dtype).tiny)
    vectors = _link_vectors(markers)
    lengths = jnp.maximum(jnp.linalg.norm(vectors, axis=-1), minimum_length * torso[..., None])
    angles = jnp.arctan2(vectors[..., 1], vectors[..., 0]) - template.reference_angles.astype(dtype)
    angles = jnp.arctan2(jnp.sin(angles), jnp.cos(angles))  # wrap to (−π, π]
    log_lengths = jnp.log(lengths / (torso[..., None] * template.reference_lengths.astype(dtype)))
    links = jnp.stack([angles, log_lengths], axis=-1).reshape(*angles.shape[:-1], 2 * NUM_LINKS)
    return jnp.concatenate(
        [jnp.log(torso)[..., None], markers[..., _ROOT, :], links], axis=-1
    )


class SPMFitInfo(eqx.Module):
    """Per-frame diagnostics of :func:`spm_fit_with_info`.

    Attributes:
        result: ``(time,)`` optimistix ``RESULTS`` of each frame's least-squares solve.
        max_error: ``(time,)`` largest marker distance (pixels) between fit and data.
    """

    result: optx.RESULTS
    max_error: Float[Array, " time"]


def _residuals(state: Array, args: tuple[Array, SPMTemplate, Array]) -> Array:
    markers, template, length_weight = args
    marker_residuals = (spm_forward(state, template) - markers).reshape(-1)
    # A ridge on ℓ_k (weight 0 by default) pulls lengths toward the template when markers are noisy.
    return jnp.concatenate([marker_residuals, length_weight * state[4::2]])


def spm_fit_with_info(
    markers_2d: Float[ArrayLike, "time markers 2"],
    template: SPMTemplate,
    *,
    length_regularisation: float | Float[ArrayLike, ""] = 0.0,
    max_steps: int = 50,
    unwrap: bool = True,
) -> tuple[Float[Array, "time 25"], SPMFitInfo]:
    """:func:`spm_fit`, also returning the solver status and the fit error per frame."""
    markers = jnp.asarray(markers_2d)
    _check_markers(markers)
    if markers.ndim != 3:
        raise ValueError(f"spm_fit expects (time, 12, 2) markers, got shape {markers.shape}")
    # an array, so that changing the weight does not recompile
    weight = jnp.asarray(length_regularisation, jnp.result_type(markers, float))
    return _fit(markers, template, weight, max_steps=max_steps, unwrap=unwrap)


@eqx.filter_jit
def _fit(
    markers: Array, template: SPMTemplate, length_regularisation: Array, *, max_steps: int,
    unwrap: bool,
) -> tuple[Array, SPMFitInfo]:
    output_dtype = jnp.result_type(markers, float)
    # optimistix's LM keeps its damping in the default float type, and a float32 problem under
    # jax_enable_x64 then mixes dtypes; solving in the wider type (cast back below) avoids that.
    dtype = jnp.promote_types(output_dtype, jnp.result_type(float))
    markers = markers.astype(dtype)
    template = jax.tree.map(lambda leaf: jnp.asarray(leaf, dtype), template)
    initial = spm_initial_state(markers, template)
    tolerance = 1e-10 if dtype == jnp.float64 else 1e-5
    solver = optx.LevenbergMarquardt(rtol=tolerance, atol=tolerance)
    length_weight = jnp.sqrt(jnp.asarray(length_regularisation, dtype))

    def solve_frame(state: Array, frame: Array):
        solution = optx.least_squares(
            _residuals, solver, state, args=(frame, template, length_weight),
            max_steps=max_steps, throw=False,
        )
        return solution.value, solution.result

    states, results = jax.vmap(solve_frame)(initial, markers)
    if unwrap:
        states = _unwrap_angles(states)
    fitted = jax.vmap(spm_forward, in_axes=(0, None))(states, template)
    max_error = jnp.max(jnp.linalg.norm(fitted - markers, axis=-1), axis=-1)
    info = SPMFitInfo(result=results, max_error=max_error.astype(output_dtype))
    return states.astype(output_dtype), info


def _unwrap_angles(states: Array) -> Array:
    """Remove 2π jumps of each angle over time, then shift each track so its mean is in (−π, π]."""
    angles = jnp.unwrap(states[:, 3::2], axis=0)
    turns = jnp.round(jnp.mean(angles, axis=0) / (2 * jnp.pi))
    return states.at[:, 3::2].set(angles - 2 * jnp.pi * turns)


def spm_fit(
    markers_2d: Float[ArrayLike, "time markers 2"],
    template: SPMTemplate,
    *,
    length_regularisation: float = 0.0,
    max_steps: int = 50,
    unwrap: bool = True,
) -> Float[Array, "time 25"]:
    """Convert image markers ``(time, 12, 2)`` into SPM states ``(time, 25)``.

    The closed-form :func:`spm_initial_state` is refined per frame by Levenberg–Marquardt
    (optimistix, vmapped over frames, ``throw=False``) on the marker residuals plus, when
    ``length_regularisation > 0``, a ridge ``λ Σ ℓ_k²`` toward the template's lengths. With
    ``length_regularisation = 0`` and clean markers the closed form is already exact and the solver
    stops at once. With ``unwrap`` each angle is made continuous over time (no 2π jumps), keeping
    each track's mean within (−π, π]. Use :func:`spm_fit_with_info` for the solver status.
    """
    states, _ = spm_fit_with_info(
        markers_2d, template, length_regularisation=length_regularisation,
        max_steps=max_steps, unwrap=unwrap,
    )
    return states
