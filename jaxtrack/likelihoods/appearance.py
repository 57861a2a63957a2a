"""Choosing a tracker's appearance likelihood by name: ``"limbs"``, ``"limbs+edges"`` or
``"markers"``.

Both are template models cut from the first frame at its known markers and scored as
``−λ Σ (1 − NCC)`` (Tian et al. 2005, eq. 7's form); both expose ``log_likelihood(markers,
image, sharpness, nearest)`` and ``residuals(markers, image, sharpness)``, which is all a tracker
calls, so every tracker (and every baseline) runs on either.

* ``"markers"``: square patches at the 12 markers, the paper's eq. 7
  (:mod:`jaxtrack.likelihoods.ncc`).
* ``"limbs"``: strips along the body's segments (:mod:`jaxtrack.likelihoods.limbs`), the
  default: on the held-out wave it is the one whose best-scoring pose lies near the truth.
* ``"limbs+edges"``: the strips plus the distance of their borders to the frame's edges
  (:mod:`jaxtrack.likelihoods.edges`), which do not drift as limbs turn. Its observations are
  ``(2, height, width)``, the grey frame and its edge distance map
  (``jaxtrack.vision.edge_observations``): :func:`needs_edges` says when to build them.
"""

from __future__ import annotations

from jaxtyping import ArrayLike, Float

from jaxtrack.likelihoods.edges import EdgeLimbTemplates, make_edge_limb_templates
from jaxtrack.likelihoods.limbs import DEFAULT_LIMB_SHARPNESS, LimbTemplates, make_limb_templates
from jaxtrack.likelihoods.ncc import DEFAULT_NCC_SHARPNESS, NCCTemplates, make_templates

__all__ = ["DEFAULT_LIKELIHOOD", "LIKELIHOODS", "AppearanceTemplates", "default_sharpness",
           "check_observations", "make_appearance_templates", "needs_edges"]

LIKELIHOODS = ("limbs", "limbs+edges", "markers")
DEFAULT_LIKELIHOOD = "limbs"
AppearanceTemplates = NCCTemplates | LimbTemplates | EdgeLimbTemplates


def _check(likelihood: str) -> None:
    if likelihood not in LIKELIHOODS:
        raise ValueError(f"likelihood must be one of {LIKELIHOODS}, got {likelihood!r}")


def default_sharpness(likelihood: str) -> float:
    """λ that suits ``likelihood``: :data:`DEFAULT_LIMB_SHARPNESS` or
    :data:`DEFAULT_NCC_SHARPNESS`."""
    _check(likelihood)
    return DEFAULT_NCC_SHARPNESS if likelihood == "markers" else DEFAULT_LIMB_SHARPNESS


def needs_edges(likelihood: str) -> bool:
    """Whether ``likelihood`` observes ``(2, height, width)`` frames with edge distance maps
    (``jaxtrack.vision.edge_observations``) rather than ``(height, width)`` grey frames."""
    _check(likelihood)
    return likelihood == "limbs+edges"


def make_appearance_templates(
    likelihood: str,
    image: Float[ArrayLike, "height width"] | Float[ArrayLike, "2 height width"],
    markers_2d: Float[ArrayLike, "markers 2"],
) -> AppearanceTemplates:
    """The templates of ``likelihood`` cut from a reference frame at its ``(12, 2)`` markers
    (for ``"limbs+edges"`` the frame is its ``(2, height, width)`` observation)."""
    _check(likelihood)
    if likelihood == "limbs+edges":
        return make_edge_limb_templates(image, markers_2d)
    if likelihood == "limbs":
        return make_limb_templates(image, markers_2d)
    return make_templates(image, markers_2d)


def check_observations(templates: AppearanceTemplates, shape: tuple[int, ...]) -> None:
    """Raise a ValueError unless a sequence of observations of ``shape`` suits ``templates``:
    ``(time, height, width)`` grey frames, or for the edge-limb templates ``(time, 2, height,
    width)`` grey frames with their edge distance maps."""
    shape = tuple(shape)
    if isinstance(templates, EdgeLimbTemplates):
        if len(shape) != 4 or shape[1] != 2:
            raise ValueError(f"frames must be (time, 2, height, width): grey frames with their "
                             f"edge distance maps (jaxtrack.vision.edge_observations) for the "
                             f"'limbs+edges' likelihood, got {shape}")
    elif len(shape) != 3:
        raise ValueError(f"frames must be (time, height, width) grey images, got {shape}")
