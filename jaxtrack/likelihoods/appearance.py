"""Choosing a tracker's appearance likelihood by name: ``"limbs"`` or ``"markers"``.

Both are template models cut from the first frame at its known markers and scored as
``−λ Σ (1 − NCC)`` (Tian et al. 2005, eq. 7's form); both expose ``log_likelihood(markers,
image, sharpness, nearest)`` and ``residuals(markers, image, sharpness)``, which is all a tracker
calls, so every tracker (and every baseline) runs on either.

* ``"markers"``: square patches at the 12 markers, the paper's eq. 7
  (:mod:`jaxtrack.likelihoods.ncc`).
* ``"limbs"``: strips along the body's segments (:mod:`jaxtrack.likelihoods.limbs`), the
  default: on the held-out wave it is the one whose best-scoring pose lies near the truth.
"""

from __future__ import annotations

from jaxtyping import ArrayLike, Float

from jaxtrack.likelihoods.limbs import DEFAULT_LIMB_SHARPNESS, LimbTemplates, make_limb_templates
from jaxtrack.likelihoods.ncc import DEFAULT_NCC_SHARPNESS, NCCTemplates, make_templates

__all__ = ["DEFAULT_LIKELIHOOD", "LIKELIHOODS", "AppearanceTemplates", "default_sharpness",
           "make_appearance_templates"]

LIKELIHOODS = ("limbs", "markers")
DEFAULT_LIKELIHOOD = "limbs"
AppearanceTemplates = NCCTemplates | LimbTemplates


def _check(likelihood: str) -> None:
    if likelihood not in LIKELIHOODS:
        raise ValueError(f"likelihood must be one of {LIKELIHOODS}, got {likelihood!r}")


def default_sharpness(likelihood: str) -> float:
    """λ that suits ``likelihood``: :data:`DEFAULT_LIMB_SHARPNESS` or
    :data:`DEFAULT_NCC_SHARPNESS`."""
    _check(likelihood)
    return DEFAULT_LIMB_SHARPNESS if likelihood == "limbs" else DEFAULT_NCC_SHARPNESS


def make_appearance_templates(
    likelihood: str,
    image: Float[ArrayLike, "height width"],
    markers_2d: Float[ArrayLike, "markers 2"],
) -> AppearanceTemplates:
    """The templates of ``likelihood`` cut from a reference frame at its ``(12, 2)`` markers."""
    _check(likelihood)
    if likelihood == "limbs":
        return make_limb_templates(image, markers_2d)
    return make_templates(image, markers_2d)
