"""A normalised observation model of a detector's output: p(detections | pose) for one frame.

A per-frame detector (:mod:`jaxtrack.vision.detections`) reports, in frame t, ``n`` people
``D_1 … D_n``, person j with keypoints ``d_jk`` (pixels) at the body's markers k and
confidences ``c_jk`` in ``[0, 1]`` (``c_jk = 0``: not found). Given a hypothesised pose, its
markers ``μ_k`` (pixels), the density of the keypoint positions found (the counts, which
keypoints were found and their confidences are given, not modelled) is

    p(D_1..D_n | μ) = ρ Π_j B(D_j) + (1 − ρ) (1/n) Σ_j L(D_j | μ) Π_{i≠j} B(D_i)      (n ≥ 1)

and 1 when ``n = 0``: one of the people detected is ours (each equally likely a priori), or,
with probability ρ, none is (ours was missed and all are others); a person that is not ours is
a passer-by, explained by ``B(D) = Π_k U`` with ``U = 1 / (W H)`` uniform over the image, not a
pull on the pose. Ours is

    L(D | μ) = (1 − s) Π_k p(d_k | μ_k, c_k) + s Π_k p(d_k | μ_{swap(k)}, c_k),

the second term the detector's left/right swap (probability s): the keypoint labelled
``left_wrist`` is the body's right wrist, and so on (``swap`` exchanges ``left_*`` and
``right_*``). Each keypoint found is the detector's Gaussian or an outlier anywhere in the
image, the confidence being the Gaussian's share of the mixture:

    p(d_k | μ, c_k) = w_k N_I(d_k; μ, σ_k² I) + (1 − w_k) U,      w_k = (1 − ε) c_k,

``ε`` the outlier rate, ``N_I`` the Gaussian truncated to the image
``I = [−½, W − ½] × [−½, H − ½]`` (pixel centres at integers), so that each factor integrates
to 1 over the image, and hence p over the positions of all keypoints found. The scale is
proportional to the pose's size: ``σ_k = sqrt((f_k T)² + σ₀²)`` with ``T`` the hypothesised
pose's neck–pelvis distance, ``f_k`` a per-marker factor and σ₀ a floor in pixels (a
detector's pixel noise, and a size-0 pose kept proper). Keypoints not found (``c = 0``) and
people past ``n`` contribute no factor. All numeric parameters (``f_k``, σ₀, ε, s, ρ) are
arrays of :class:`DetectionModel`, so ``jax.grad`` of a log-evidence reaches them.

Computed in logs as ``log p = −N log(W H) + log[ρ' + (1 − ρ)/n Σ_j exp ℓ_j]`` with
``ℓ_j = log L(D_j | μ) − log B(D_j)``, ``N`` the number of keypoints found, ρ' = ρ (n ≥ 1).
Design and defaults: ``docs/detections.md``.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import log_ndtr
from jaxtyping import Array, ArrayLike, Float, Int

from jaxtrack.body import SPM_MARKERS

__all__ = ["DEFAULT_JOINT_SCALES", "DetectionModel", "DetectionsFrame", "detection_model",
           "detections_frames", "log_density", "swap_order"]

DEFAULT_JOINT_SCALES: dict[str, float] = {
    "head": 0.15, "neck": 0.25, "thorax": 0.3, "pelvis": 0.35,
    "right_shoulder": 0.33, "left_shoulder": 0.33, "right_elbow": 0.3, "left_elbow": 0.3,
    "right_wrist": 0.26, "left_wrist": 0.26, "right_hip": 0.45, "left_hip": 0.45,
    "right_knee": 0.37, "left_knee": 0.37, "right_ankle": 0.37, "left_ankle": 0.37,
}
"""Default f_k, the detector's spread per marker in torso lengths: COCO's per-keypoint
constants κ_k (the keypoint similarity's, 2σ_k) times √area ≈ 2.1 torso lengths for a standing
adult (``docs/detections.md``); derived markers take their sources' spread. A start, to be
fitted by the gradient of the log-evidence."""


def swap_order(markers: tuple[str, ...]) -> tuple[int, ...]:
    """For each marker, the index of its mirror (``left_x`` ↔ ``right_x``; itself otherwise)."""
    def mirror(name: str) -> str:
        for one, other in (("left_", "right_"), ("right_", "left_")):
            if name.startswith(one):
                return other + name[len(one):]
        return name

    index = {name: i for i, name in enumerate(markers)}
    return tuple(index.get(mirror(name), i) for i, name in enumerate(markers))


class DetectionsFrame(eqx.Module):
    """One frame's detections as arrays (or a sequence's, with a leading time axis on every
    field): what :func:`log_density` reads.

    Attributes:
        points: ``(people, markers, 2)`` pixels; 0 where absent.
        confidence: ``(people, markers)`` in ``[0, 1]``; 0 where absent and for people past
            ``num_people`` (a keypoint outside the image counts as absent).
        num_people: ``()`` how many people the frame holds.
        image_size: ``(2,)`` the frame's width and height in pixels.
    """

    points: Float[Array, "*time people markers 2"]
    confidence: Float[Array, "*time people markers"]
    num_people: Int[Array, "*time"]
    image_size: Float[Array, "*time 2"]


def detections_frames(detections, *, markers: tuple[str, ...] | None = None,
                      frame_size: tuple[float, float] | None = None,
                      dtype=None) -> DetectionsFrame:
    """The :class:`DetectionsFrame` of every frame of ``detections``, stacked on a time axis.

    Keypoints outside the image (``[−½, W − ½] × [−½, H − ½]``, the model's support) are taken
    as not found: the model has no density there.

    Args:
        detections: a :class:`jaxtrack.vision.detections.Detections`.
        markers: the markers, in the pose's order, to take from ``detections`` (default all of
            them, in their order).
        frame_size: ``(width, height)`` in pixels; default ``detections.frame_size``.
        dtype: the floating dtype (default JAX's default float).

    Returns:
        Leaves ``(time, people, markers, 2)``, ``(time, people, markers)``, ``(time,)``,
        ``(time, 2)``; one frame is ``jax.tree.map(lambda a: a[t], frames)``.
    """
    size = detections.frame_size if frame_size is None else frame_size
    if size is None:
        raise ValueError(f"{detections.source or 'detections'}: the frame size is unknown; "
                         f"pass frame_size=(width, height) in pixels")
    width, height = (float(value) for value in size)
    if not (width > 0 and height > 0):
        raise ValueError(f"frame_size must be a positive (width, height), got {size}")
    columns = slice(None) if markers is None else \
        [detections.marker(marker) for marker in markers]
    points = np.nan_to_num(np.asarray(detections.points, np.float64)[:, :, columns])
    confidence = np.asarray(detections.confidence, np.float64)[:, :, columns]
    inside = np.all((points >= -0.5) & (points <= np.array([width, height]) - 0.5), -1)
    confidence = np.where(inside, confidence, 0.0)
    points = np.where((confidence > 0)[..., None], points, 0.0)
    frames = points.shape[0]
    dtype = dtype or jnp.result_type(float)
    return DetectionsFrame(jnp.asarray(points, dtype), jnp.asarray(confidence, dtype),
                           jnp.asarray(detections.people, jnp.int32),
                           jnp.broadcast_to(jnp.asarray([width, height], dtype), (frames, 2)))


class DetectionModel(eqx.Module):
    """The parameters of the detections' observation model (module docstring).

    Attributes:
        joint_scales: ``(markers,)`` f_k, each marker's spread in neck–pelvis lengths.
        pixel_noise: ``()`` σ₀, the spread's floor in pixels.
        outlier_rate: ``()`` ε, the share of a keypoint's density that is uniform over the
            image at confidence 1.
        swap_probability: ``()`` s, the probability the detector swapped the person's left
            and right.
        absent_probability: ``()`` ρ, the probability none of the people detected is ours.
        swap: for each marker, its mirror's index (static).
        spine: the neck's and the pelvis' indices, whose distance sizes the pose (static).
    """

    joint_scales: Float[Array, " markers"]
    pixel_noise: Float[Array, ""]
    outlier_rate: Float[Array, ""]
    swap_probability: Float[Array, ""]
    absent_probability: Float[Array, ""]
    swap: tuple[int, ...] = eqx.field(static=True)
    spine: tuple[int, int] = eqx.field(static=True)


def detection_model(markers: tuple[str, ...] = SPM_MARKERS, *,
                    joint_scales: ArrayLike | None = None, pixel_noise: float = 2.0,
                    outlier_rate: float = 0.05, swap_probability: float = 0.05,
                    absent_probability: float = 0.05, dtype=None) -> DetectionModel:
    """A :class:`DetectionModel` for poses with ``markers`` (default the tracker's 12).

    Args:
        markers: the markers, in the order of the pose's and the detections' markers axis;
            must include ``neck`` and ``pelvis``.
        joint_scales: ``(markers,)`` f_k; default :data:`DEFAULT_JOINT_SCALES`.
        pixel_noise: σ₀ in pixels (positive).
        outlier_rate, swap_probability, absent_probability: ε, s, ρ, each in ``[0, 1]``
            (ε, ρ below 1; inside ``(0, 1)`` where their gradients are wanted).
        dtype: the floating dtype of the arrays (default JAX's default float).
    """
    markers = tuple(markers)
    if "neck" not in markers or "pelvis" not in markers:
        raise ValueError(f"markers must include neck and pelvis (the pose's size is their "
                         f"distance), got {markers}")
    if joint_scales is None:
        unknown = [marker for marker in markers if marker not in DEFAULT_JOINT_SCALES]
        if unknown:
            raise ValueError(f"no default joint scale for {', '.join(unknown)}; pass "
                             f"joint_scales")
        joint_scales = [DEFAULT_JOINT_SCALES[marker] for marker in markers]
    scales = np.asarray(joint_scales, np.float64)
    if scales.shape != (len(markers),) or not np.all(scales > 0) or \
            not np.all(np.isfinite(scales)):
        raise ValueError(f"joint_scales must be {len(markers)} positive numbers, got {scales}")
    if not pixel_noise > 0:
        raise ValueError(f"pixel_noise must be positive, got {pixel_noise}")
    for name, value, top in (("outlier_rate", outlier_rate, 1.0),
                             ("swap_probability", swap_probability, 1.0 + 1e-12),
                             ("absent_probability", absent_probability, 1.0)):
        if not 0.0 <= value < top:
            raise ValueError(f"{name} must lie in [0, 1{']' if top > 1 else ')'}, got {value}")
    dtype = dtype or jnp.result_type(float)
    array = lambda value: jnp.asarray(value, dtype)  # noqa: E731
    return DetectionModel(array(scales), array(pixel_noise), array(outlier_rate),
                          array(swap_probability), array(absent_probability),
                          swap_order(markers),
                          (markers.index("neck"), markers.index("pelvis")))


def _log1mexp(x):
    """log(1 − eˣ) for x < 0, accurate at both ends (Mächler 2012), with gradients safe on the
    branch not taken."""
    near = x > -0.6931471805599453
    safe_near, safe_far = jnp.where(near, x, -1.0), jnp.where(near, -1.0, x)
    return jnp.where(near, jnp.log(-jnp.expm1(safe_near)), jnp.log1p(-jnp.exp(safe_far)))


def _log_normal_mass(lower, upper):
    """log(Φ(upper) − Φ(lower)) for lower < upper, reflected into the lower tail, where
    ``log_ndtr`` keeps its digits."""
    flip = lower > 0
    low, high = jnp.where(flip, -upper, lower), jnp.where(flip, -lower, upper)
    log_high = log_ndtr(high)
    return log_high + _log1mexp(log_ndtr(low) - log_high)


def log_density(pose_markers: Float[ArrayLike, "markers 2"], detections_frame: DetectionsFrame,
                params: DetectionModel) -> Float[Array, ""]:
    """log p(detections | pose) of one pose and one frame (module docstring), normalised over
    the positions of the keypoints found.

    Args:
        pose_markers: ``(markers, 2)`` the hypothesised pose's markers in pixels, in the
            detections' marker order.
        detections_frame: one frame's :class:`DetectionsFrame` (no time axis).
        params: the :class:`DetectionModel`.

    Returns:
        A scalar; 0 when the frame holds no one.
    """
    pose = jnp.asarray(pose_markers)
    frame = detections_frame
    if pose.shape != frame.points.shape[1:] or pose.shape[0] != params.joint_scales.shape[0]:
        raise ValueError(f"pose_markers {pose.shape}, the detections' markers "
                         f"{frame.points.shape[1:]} and the model's joint_scales "
                         f"{params.joint_scales.shape} must agree on the markers")
    dtype = jnp.result_type(pose, frame.points, params.joint_scales)
    pose = pose.astype(dtype)
    neck, pelvis = params.spine
    torso = jnp.sqrt(jnp.sum((pose[neck] - pose[pelvis]) ** 2) + jnp.finfo(dtype).tiny)
    sigma = jnp.sqrt((params.joint_scales * torso) ** 2 + params.pixel_noise ** 2)
    size = frame.image_size.astype(dtype)
    log_area = jnp.sum(jnp.log(size))
    # a keypoint outside the image is not found: the model's support is the image
    inside = jnp.all((frame.points >= -0.5) & (frame.points <= size - 0.5), -1)
    present = (frame.confidence > 0) & inside
    valid = jnp.arange(frame.points.shape[0]) < frame.num_people
    present = present & valid[:, None]
    confidence = jnp.where(present, frame.confidence, 1.0).astype(dtype)
    weight = (1 - params.outlier_rate) * confidence                      # w_k = (1 − ε) c_k
    log_weight, log_rest = jnp.log(weight), jnp.log1p(-weight)

    def person_terms(order):
        # Σ_k log[p(d_k | μ_order(k)) / U] of every person: the detections labelled k against
        # the pose's marker order(k) (the identity, or the left/right swap)
        mean, scale = pose[order], sigma[order]
        z = (frame.points - mean) / scale[:, None]
        log_gauss = (-0.5 * jnp.sum(z ** 2, -1) - 2 * jnp.log(scale) - jnp.log(2 * jnp.pi)
                     - jnp.sum(_log_normal_mass((-0.5 - mean) / scale[:, None],
                                                (size - 0.5 - mean) / scale[:, None]), -1))
        ratio = jnp.logaddexp(log_weight + log_gauss + log_area, log_rest)
        return jnp.sum(jnp.where(present, ratio, 0.0), -1)

    orders = jnp.asarray([tuple(range(pose.shape[0])), params.swap])
    straight, swapped = jax.vmap(person_terms)(orders)
    swap = params.swap_probability
    # ℓ_j = log[(1 − s) Π_k … + s Π_k …(swapped)] − log B(D_j)
    ell = jnp.logaddexp(jnp.log1p(-swap) + straight, jnp.log(swap) + swapped)
    count = frame.num_people
    log_ours = (jnp.log1p(-params.absent_probability)
                - jnp.log(jnp.maximum(count, 1)).astype(dtype) + ell)
    log_none = jnp.where(count > 0, jnp.log(params.absent_probability), 0.0)
    terms = jnp.concatenate([log_none[None], jnp.where(valid, log_ours, -jnp.inf)])
    return jax.nn.logsumexp(terms) - log_area * jnp.sum(present)
