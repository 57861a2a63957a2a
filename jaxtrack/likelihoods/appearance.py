"""Choosing a tracker's appearance likelihood by name: ``"limbs+edges"``, ``"limbs"`` or
``"markers"``.

All three are template models cut from the first frame at its known markers and scored as
``−λ Σ (1 − NCC)`` (Tian et al. 2005, eq. 7's form), the first with an edge term added. All
three subclass :class:`~jaxtrack.likelihoods.PartTemplates` (``_base.py``), the contract the
trackers call: ``log_likelihood`` and ``residuals``, and, part by part, ``part_markers``,
``part_log_likelihoods``, ``part_residuals``, ``spine_markers`` and ``direct_part_markers``
(the latent tracker's arm search and the refinement's block-sparse Jacobian), so every tracker
(and every baseline) runs on any of them. ``docs/likelihoods.md`` says which file holds what.

* ``"limbs+edges"`` (the default): the limb strips plus the distance of their borders to the
  frame's edges (:mod:`jaxtrack.likelihoods.edges`), which do not drift as limbs turn in depth.
  Its observations are ``(3, height, width)``, the grey frame, its edge distance map and the
  nearest edge's orientation;
  the image trackers build them from grey frames (``Tracker.observe``).
* ``"limbs"``: strips along the body's segments (:mod:`jaxtrack.likelihoods.limbs`); grey
  frames.
* ``"markers"``: square patches at the body's markers, the paper's eq. 7
  (:mod:`jaxtrack.likelihoods.ncc`); grey frames.
"""

from __future__ import annotations

from jaxtyping import ArrayLike, Float

from jaxtrack.likelihoods.edges import EdgeLimbTemplates, make_edge_limb_templates
from jaxtrack.likelihoods.limbs import DEFAULT_LIMB_SHARPNESS, LimbTemplates, make_limb_templates
from jaxtrack.likelihoods.ncc import DEFAULT_NCC_SHARPNESS, NCCTemplates, make_templates
from jaxtrack.vision.observations import images_of

__all__ = ["DEFAULT_LIKELIHOOD", "LIKELIHOODS", "AppearanceTemplates", "default_sharpness",
           "make_appearance_templates", "needs_edges"]

LIKELIHOODS = ("limbs", "limbs+edges", "markers")
DEFAULT_LIKELIHOOD = "limbs+edges"
AppearanceTemplates = NCCTemplates | LimbTemplates | EdgeLimbTemplates
"""The templates :func:`make_appearance_templates` makes, one kind per name of
:data:`LIKELIHOODS`; each is a :class:`~jaxtrack.likelihoods.PartTemplates`."""


def _check(likelihood: str) -> None:
    if likelihood not in LIKELIHOODS:
        raise ValueError(f"likelihood must be one of {LIKELIHOODS}, got {likelihood!r}")


def default_sharpness(likelihood: str) -> float:
    """λ that suits ``likelihood``: :data:`DEFAULT_LIMB_SHARPNESS` or
    :data:`DEFAULT_NCC_SHARPNESS`."""
    _check(likelihood)
    return DEFAULT_NCC_SHARPNESS if likelihood == "markers" else DEFAULT_LIMB_SHARPNESS


def needs_edges(likelihood: str) -> bool:
    """Whether ``likelihood`` observes ``(3, height, width)`` frames with edge maps
    (``jaxtrack.vision.edge_observations``) rather than ``(height, width)`` grey frames."""
    _check(likelihood)
    return likelihood == "limbs+edges"


def make_appearance_templates(
    likelihood: str,
    image: Float[ArrayLike, "height width"] | Float[ArrayLike, "3 height width"],
    markers_2d: Float[ArrayLike, "markers 2"],
    background: Float[ArrayLike, "height width"] | None = None,
    **edge_options: float,
) -> AppearanceTemplates:
    """The templates of ``likelihood`` cut from a reference frame (for ``"limbs+edges"`` the
    grey frame or its ``(3, height, width)`` observation) at its ``(markers, 2)`` pixel markers
    in ``SPM_MARKERS`` order, with the static camera's grey ``background`` for
    ``"limbs+edges"``'s foreground term (None: none; the other likelihoods take none), cast to
    the templates' dtype. ``edge_options`` (``edge_weight``, ``edge_tolerance``,
    ``foreground_weight``, ``coverage_weight``, ``keypoint_weight``, ``keypoint_scale``) go to
    ``make_edge_limb_templates``; other likelihoods take none."""
    _check(likelihood)
    image = images_of(image)
    if likelihood == "limbs+edges":
        return make_edge_limb_templates(image, markers_2d, background=background,
                                        **edge_options)
    if edge_options:
        raise ValueError(f"{sorted(edge_options)} are settings of the 'limbs+edges' likelihood "
                         f"only, not of {likelihood!r}")
    if background is not None:
        raise ValueError(f"a background is used by the 'limbs+edges' likelihood only, not by "
                         f"{likelihood!r}")
    if likelihood == "limbs":
        return make_limb_templates(image, markers_2d)
    return make_templates(image, markers_2d)
