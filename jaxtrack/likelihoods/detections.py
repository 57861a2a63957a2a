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
from jaxtrack.likelihoods._base import PartTemplates
from jaxtrack.smc import cond_any
from jaxtrack.vision.observations import detections_of

__all__ = ["DEFAULT_JOINT_SCALES", "DetectionModel", "DetectionTemplates", "DetectionsFrame",
           "check_detections_frames", "detection_model", "detections_frames", "em_residuals",
           "log_density", "swap_order"]

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
    ``log_ndtr`` keeps its digits: exact at any distance from the image (two ``log_ndtr``,
    each an ``erf``, an ``erfc``, two logs and an asymptotic series, then a ``log1mexp``)."""
    flip = lower > 0
    low, high = jnp.where(flip, -upper, lower), jnp.where(flip, -lower, upper)
    log_high = log_ndtr(high)
    return log_high + _log1mexp(log_ndtr(low) - log_high)


_FAR_TAIL = 12.0
"""How many σ outside the image a marker may lie for :func:`_log_normal_mass_near`; beyond,
``erfc`` of the reflected bound would leave float32's normal range (it does at ≈ 13σ)."""


def _log_normal_mass_near(lower, upper):
    """:func:`_log_normal_mass` from two ``erfc`` tails, for intervals whose reflected upper
    bound lies above −:data:`_FAR_TAIL`, within float rounding of it there (a few 1e−6
    relative in float32; closer to 0 than it near log 1) at about half its cost.

    Reflected so that ``low < 0`` (``Φ(low)`` then has no cancellation): inside the image
    (``high > 0``) the mass is ``1 − Φ(low) − Φ(−high)``, outside it (``high ≤ 0``)
    ``Φ(high) (1 − Φ(low) / Φ(high))``; each a log and a ``log1p``. Bounds past the far tail
    are clamped, so that values and gradients stay finite where the caller takes the exact
    function instead."""
    flip = lower > 0
    low, high = jnp.where(flip, -upper, lower), jnp.where(flip, -lower, upper)
    high = jnp.maximum(high, -_FAR_TAIL)
    low = jnp.minimum(low, high)
    root_half = np.sqrt(0.5).astype(low.dtype)
    tail_low = 0.5 * jax.lax.erfc(-low * root_half)                 # Φ(low)
    tail_high = 0.5 * jax.lax.erfc(jnp.abs(high) * root_half)       # Φ(−|high|)
    inside = high > 0
    whole = jnp.where(inside, 1.0, tail_high)
    rest = jnp.where(inside, tail_high + tail_low, tail_low)
    return jnp.log(whole) + jnp.log1p(-rest / whole)


def _marker_log_mass(lower, upper):
    """log of the Gaussian's mass inside the image per coordinate, the standardised bounds
    of the markers' x and then y: :func:`_log_normal_mass_near` unless some marker lies past
    :data:`_FAR_TAIL` σ outside the image, :func:`_log_normal_mass` then. Under ``vmap`` over
    particles the exact branch runs only on frames where some particle needs it
    (``cond_any``), and is chosen per particle."""
    far = jnp.any(jnp.where(lower > 0, -lower, upper) < -_FAR_TAIL)
    # the near form outside the branch, so that it is compiled once, not in both
    near = _log_normal_mass_near(lower, upper)
    return cond_any(far, lambda operands: _log_normal_mass(*operands[:2]),
                    lambda operands: operands[2], (lower, upper, near))


def _components(pose, frame: DetectionsFrame, params: DetectionModel):
    """The pieces of :func:`log_density` of one pose and one frame.

    Returns ``(ratio, inlier, log_components, log_none, present, sigma, log_area)``:
    ``ratio`` ``(2, people, markers)`` log[p(d_jk | μ_o(k), c_jk) / U] of each order o (the
    identity, the left/right swap), 0 where not found; ``inlier`` the same with the Gaussian's
    share alone, log[w N_I / U]; ``log_components`` ``(2, people)`` the log of each (person,
    order) mixture component over the background (−inf past ``num_people``); ``log_none`` the
    log of the none-is-ours component; ``present`` ``(people, markers)``; ``sigma``
    ``(markers,)``; ``log_area`` log(W H).
    """
    dtype = jnp.result_type(pose, frame.points, params.joint_scales)
    # every per-pose array is flat, x and y apart, and indexed by no array: under the
    # particles' vmap XLA's CPU loops over (particles, 24) run up to eight times faster than
    # over (particles, 12, 2) or (particles, 2, 12), and a gather keeps them scalar
    x, y = pose[:, 0].astype(dtype), pose[:, 1].astype(dtype)
    num_people, num_markers = frame.points.shape[:2]
    neck, pelvis = params.spine
    torso = jnp.sqrt((x[neck] - x[pelvis]) ** 2 + (y[neck] - y[pelvis]) ** 2
                     + jnp.finfo(dtype).tiny)
    sigma = jnp.sqrt((params.joint_scales * torso) ** 2 + params.pixel_noise ** 2)
    size = frame.image_size.astype(dtype)
    log_area = jnp.sum(jnp.log(size))
    # a keypoint outside the image is not found: the model's support is the image
    inside = jnp.all((frame.points >= -0.5) & (frame.points <= size - 0.5), -1)
    present = (frame.confidence > 0) & inside
    valid = jnp.arange(num_people) < frame.num_people
    present = present & valid[:, None]
    confidence = jnp.where(present, frame.confidence, 1.0).astype(dtype)
    weight = (1 - params.outlier_rate) * confidence                      # w_k = (1 − ε) c_k
    log_weight, log_rest = jnp.log(weight), jnp.log1p(-weight)

    # log σ and the Gaussian's log mass inside the image (the costly part), once per marker
    # and not once per (order, person, keypoint)
    log_scale = jnp.log(sigma)
    coordinates, scales = jnp.concatenate([x, y]), jnp.concatenate([sigma, sigma])
    limits = jnp.repeat(size - 0.5, num_markers)
    mass = _marker_log_mass((-0.5 - coordinates) / scales, (limits - coordinates) / scales)
    log_mass = mass[:num_markers] + mass[num_markers:]

    # log[p(d_k | μ_order(k)) / U] of every keypoint of every person and order (the
    # identity, or the left/right swap), flat over (order, person, keypoint). The swapped
    # order's sum over k is taken over the detections permuted instead (the detection
    # labelled swap(k) against marker k: the same sum, swap being its own inverse), so that
    # each pose's arrays are its own, tiled, and only the frame's are permuted, once
    mirror = np.asarray(params.swap)

    def keyed(value):  # (people, markers) of the frame → flat over (order, person, keypoint)
        return jnp.concatenate([value.ravel(), value[:, mirror].ravel()])

    def tiled(value):  # (markers,) of the pose → flat over (order, person, keypoint)
        return jnp.tile(value, 2 * num_people)

    scale = tiled(sigma)
    z_x = (keyed(frame.points[..., 0]) - tiled(x)) / scale
    z_y = (keyed(frame.points[..., 1]) - tiled(y)) / scale
    log_gauss = (-0.5 * (z_x ** 2 + z_y ** 2) - 2 * tiled(log_scale) - jnp.log(2 * jnp.pi)
                 - tiled(log_mass))
    inlier = keyed(log_weight) + log_gauss + log_area
    ratio = jnp.logaddexp(inlier, keyed(log_rest))
    shape = (2, num_people, num_markers)
    ratio = jnp.where(keyed(present), ratio, 0.0).reshape(shape)
    inlier = jnp.where(keyed(present), inlier, 0.0).reshape(shape)
    straight, swapped = jnp.sum(ratio, -1)
    # indexed by the detections' labels in both orders, as em_residuals reads them
    ratio = jnp.stack([ratio[0], ratio[1][:, mirror]])
    inlier = jnp.stack([inlier[0], inlier[1][:, mirror]])
    swap = params.swap_probability
    count = frame.num_people
    log_ours = (jnp.log1p(-params.absent_probability)
                - jnp.log(jnp.maximum(count, 1)).astype(dtype))
    # ℓ_j = log[(1 − s) Π_k … + s Π_k …(swapped)] − log B(D_j), kept as its two components
    log_components = jnp.stack([jnp.log1p(-swap) + straight, jnp.log(swap) + swapped])
    log_components = jnp.where(valid, log_ours + log_components, -jnp.inf)
    log_none = jnp.where(count > 0, jnp.log(params.absent_probability), 0.0)
    return ratio, inlier, log_components, log_none, present, sigma, log_area


def _check_shapes(pose, frame: DetectionsFrame, params: DetectionModel) -> None:
    if pose.shape != frame.points.shape[1:] or pose.shape[0] != params.joint_scales.shape[0]:
        raise ValueError(f"pose_markers {pose.shape}, the detections' markers "
                         f"{frame.points.shape[1:]} and the model's joint_scales "
                         f"{params.joint_scales.shape} must agree on the markers")


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
    _check_shapes(pose, detections_frame, params)
    _, _, log_components, log_none, present, _, log_area = _components(
        pose, detections_frame, params)
    # a person's two orders summed first, then the people, as log p is written
    terms = jnp.concatenate([log_none[None], jax.nn.logsumexp(log_components, 0)])
    return jax.nn.logsumexp(terms) - log_area * jnp.sum(present)


def em_residuals(pose_markers: Float[ArrayLike, "markers 2"], detections_frame: DetectionsFrame,
                 params: DetectionModel) -> Float[Array, " residuals"]:
    """Residuals for Gauss–Newton on the detection density: its EM surrogate's quadratic part.

    With the responsibilities γ_ojk = P(person j is ours, in order o, keypoint k from the
    Gaussian | D, μ) held fixed at the pose given (Dempster, Laird & Rubin 1977, the E step) and
    the spreads σ_k too, −log p is, up to a constant, ½ Σ_ojk γ_ojk |d_jk − μ_o(k)|² / σ_k², the
    half squared norm of the residuals √γ_ojk (d_jk − μ_o(k)) / σ_o(k); at the pose given its
    gradient in the markers is that of −log p (σ fixed), so a Gauss–Newton step on it is an
    EM step towards the density's mode, not on a different cost.

    Returns:
        ``(2 × people × markers × 2,)``, 0 where a keypoint was not found.
    """
    pose = jnp.asarray(pose_markers)
    frame = detections_frame
    _check_shapes(pose, frame, params)
    ratio, inlier, log_components, log_none, present, sigma, _ = jax.lax.stop_gradient(
        _components(pose, frame, params))
    total = jax.nn.logsumexp(jnp.concatenate([log_none[None], log_components.ravel()]))
    share = jnp.exp(log_components - total)[..., None] * jnp.exp(inlier - ratio)
    gamma = jnp.where(present, share, 0.0)
    orders = jnp.asarray([tuple(range(pose.shape[0])), params.swap])
    mean, scale = pose[orders], sigma[orders]                              # (2, markers, …)
    residual = (frame.points[None] - mean[:, None]) / scale[:, None, :, None]
    return (jnp.sqrt(gamma)[..., None] * residual).ravel()


def check_detections_frames(frames: DetectionsFrame, num_markers: int, *,
                            name: str = "detections") -> None:
    """Raise a one-line ValueError unless ``frames`` is a sequence's :class:`DetectionsFrame`
    (a leading ``time`` axis on every field) with ``num_markers`` markers and sound values:
    finite points where a keypoint was found, confidences in ``[0, 1]``, people counts within
    the people axis, a positive finite frame size."""
    if not isinstance(frames, DetectionsFrame):
        raise ValueError(f"{name} must be a DetectionsFrame (jaxtrack.likelihoods."
                         f"detections_frames of a jaxtrack.vision.Detections), got "
                         f"{type(frames).__name__}")
    points, confidence = np.asarray(frames.points), np.asarray(frames.confidence)
    people, size = np.asarray(frames.num_people), np.asarray(frames.image_size)
    if points.ndim != 4 or points.shape[2:] != (num_markers, 2):
        raise ValueError(f"{name}: points must be (time, people, {num_markers}, 2), got shape "
                         f"{points.shape}")
    time = points.shape[0]
    for label, value, shape in (("confidence", confidence, points.shape[:3]),
                                ("num_people", people, (time,)), ("image_size", size, (time, 2))):
        if value.shape != shape:
            raise ValueError(f"{name}: {label} must be {shape}, got shape {value.shape}")
    if time < 1:
        raise ValueError(f"{name} hold no frame")
    if not np.all(np.isfinite(confidence)) or confidence.min() < 0 or confidence.max() > 1:
        raise ValueError(f"{name}: confidence must be finite and lie in [0, 1]")
    found = confidence > 0
    bad = found & ~np.all(np.isfinite(points), -1)
    if bad.any():
        frame = int(np.argwhere(bad)[0][0])
        raise ValueError(f"{name}: frame {frame} has a non-finite keypoint with confidence "
                         f"> 0; give confidence 0 where a keypoint was not found")
    if people.min() < 0 or people.max() > points.shape[1]:
        raise ValueError(f"{name}: num_people must lie in [0, {points.shape[1]}]")
    if not (np.all(np.isfinite(size)) and np.all(size > 0)):
        raise ValueError(f"{name}: image_size must be a positive (width, height)")


class DetectionTemplates(PartTemplates):
    """An image likelihood's templates times the detection density, or the density alone.

    ``log p(z, D | μ) = log p_image(z | μ) + log p(D | μ)`` (:func:`log_density`): the image
    and the detector are taken as independent given the pose. The image's parts stay its
    parts; the density is a term of the whole pose (:meth:`whole_pose_log_likelihood`), whose
    Gauss–Newton residuals are its EM surrogate's (:func:`em_residuals`). The frame's
    detections ride in the observation (``jaxtrack.vision.ImageObservation.detections``).

    Attributes:
        image: the image likelihood's templates, or None (the detections alone).
        params: the :class:`DetectionModel`.
    """

    image: PartTemplates | None
    params: DetectionModel

    @property
    def part_markers(self) -> tuple[tuple[int, ...], ...]:
        return () if self.image is None else self.image.part_markers

    @property
    def direct_part_markers(self) -> tuple[tuple[int, ...], ...]:
        return () if self.image is None else self.image.direct_part_markers

    @property
    def spine_markers(self) -> tuple[int, int] | None:
        return None if self.image is None else self.image.spine_markers

    @property
    def has_whole_pose_terms(self) -> bool:
        return True

    def _frame(self, observation) -> DetectionsFrame:
        frame = detections_of(observation)
        if frame is None:
            raise ValueError("the detection likelihood reads each frame's detections: give "
                             "observations with detections (jaxtrack.trackers."
                             "detection_observations)")
        return frame

    def _image_dtype(self, markers_2d):
        return jnp.result_type(jnp.asarray(markers_2d), self.params.joint_scales)

    def detection_log_density(self, markers_2d, observation) -> Float[Array, ""]:
        """log p(D | μ) of one pose (:func:`log_density`)."""
        return log_density(markers_2d, self._frame(observation), self.params)

    def whole_pose_log_likelihood(self, markers_2d, observation) -> Float[Array, ""]:
        value = self.detection_log_density(markers_2d, observation)
        if self.image is not None and self.image.has_whole_pose_terms:
            value = value + self.image.whole_pose_log_likelihood(markers_2d, observation)
        return value

    def whole_pose_residuals(self, markers_2d, observation, spine=None
                             ) -> Float[Array, " residuals"]:
        residuals = em_residuals(markers_2d, self._frame(observation), self.params)
        if self.image is not None and self.image.has_whole_pose_terms:
            image = self.image.whole_pose_residuals(markers_2d, observation, spine)
            residuals = jnp.concatenate([image, residuals.astype(image.dtype)])
        return residuals

    def log_likelihood(self, markers_2d, observation, sharpness, nearest: bool = True
                       ) -> Float[Array, ""]:
        value = self.detection_log_density(markers_2d, observation)
        if self.image is None:
            return value
        image = self.image.log_likelihood(markers_2d, observation, sharpness, nearest)
        return image + value.astype(image.dtype)

    def residuals(self, markers_2d, observation, sharpness, spine=None
                  ) -> Float[Array, " residuals"]:
        residuals = em_residuals(markers_2d, self._frame(observation), self.params)
        if self.image is None:
            return residuals
        image = self.image.residuals(markers_2d, observation, sharpness, spine)
        return jnp.concatenate([image, residuals.astype(image.dtype)])

    def part_log_likelihoods(self, markers_2d, observation, sharpness, nearest: bool = True,
                             parts: tuple[int, ...] | None = None) -> Float[Array, " parts"]:
        if self.image is None:
            return jnp.zeros((0,), self._image_dtype(markers_2d))
        return self.image.part_log_likelihoods(markers_2d, observation, sharpness, nearest,
                                               parts)

    def part_residuals(self, markers_2d, observation, sharpness, spine=None
                       ) -> Float[Array, "parts per_part"]:
        if self.image is None:
            return jnp.zeros((0, 0), self._image_dtype(markers_2d))
        return self.image.part_residuals(markers_2d, observation, sharpness, spine)
