"""The part contract every appearance likelihood keeps, and the marker set it scores.

Every appearance likelihood here is a template model cut from a reference frame at its known
markers and scored as a sum of parts (Tian et al. 2005, eq. 7's form):

    log p(z | y) = Σ_p ℓ_p(y),    ℓ_p = −λ (1 − NCC_p)  (+ the edge and foreground terms),

one part per marker patch (:mod:`jaxtrack.likelihoods.ncc`) or per limb strip
(:mod:`jaxtrack.likelihoods.limbs`, :mod:`jaxtrack.likelihoods.edges`). The trackers call only
what :class:`PartTemplates` declares, so each of them runs on any likelihood: the filters call
``log_likelihood``, the Gauss–Newton refinement ``residuals`` (a sum of squares whose half
squared norm is ``−log p``), and the arm search and the block-sparse Gauss–Newton
(``jaxtrack.trackers._parts_gauss_newton``) read the terms part by part, through
``part_markers`` (the markers part p depends on), ``part_log_likelihoods`` and
``part_residuals``. Strips read the neck–pelvis length, which sets their width; a likelihood
that does names the two markers in ``spine_markers`` and accepts that length apart
(``spine=s``), part p then depending only on ``direct_part_markers[p]`` and on ``s``.

The markers are the Scaled Prismatic Model's, in ``jaxtrack.body.SPM_MARKERS`` order:
:data:`NUM_MARKERS` of them, and :func:`check_markers` is the one place their shape is checked.
See ``docs/likelihoods.md`` for which file holds what.
"""

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from equinox import AbstractVar
from jaxtyping import Array, ArrayLike, Float

from jaxtrack.body import SPM_MARKERS

__all__ = ["NUM_MARKERS", "SPINE_MARKERS", "PartTemplates", "check_markers"]

NUM_MARKERS = len(SPM_MARKERS)
"""How many markers a pose has: those of ``jaxtrack.body.SPM_MARKERS``."""

SPINE_MARKERS: tuple[int, int] = (SPM_MARKERS.index("neck"), SPM_MARKERS.index("pelvis"))
"""The neck and pelvis (``SPM_MARKERS`` indices): their distance, the spine length, sizes the
patches and the strips."""


def check_markers(markers: ArrayLike, *, name: str = "markers", batched: bool = False,
                  finite: bool = False) -> None:
    """Raise a ValueError unless ``markers`` are :data:`NUM_MARKERS` ``(x, y)`` pixel markers.

    Args:
        markers: an array (traced or concrete) of shape ``(NUM_MARKERS, 2)``, or
            ``(..., NUM_MARKERS, 2)`` when ``batched``.
        name: what the caller calls them, for the message.
        batched: accept leading batch axes.
        finite: also require every value to be finite (``markers`` must then be concrete).
    """
    shape = tuple(np.shape(markers))
    expected = f"(..., {NUM_MARKERS}, 2)" if batched else f"({NUM_MARKERS}, 2)"
    if (shape[-2:] != (NUM_MARKERS, 2)) if batched else (shape != (NUM_MARKERS, 2)):
        raise ValueError(f"{name} must be {NUM_MARKERS}{' finite' if finite else ''} (x, y) "
                         f"pixel markers of shape {expected} in SPM_MARKERS order, got shape "
                         f"{shape}")
    if finite:
        if isinstance(markers, jax.core.Tracer):
            raise ValueError(f"{name} must be concrete (not traced) to be checked for finite "
                             f"values")
        if not np.all(np.isfinite(np.asarray(markers))):
            raise ValueError(f"{name} must be {NUM_MARKERS} finite (x, y) pixel markers, got "
                             f"non-finite values")


class PartTemplates(eqx.Module):
    """Templates of an appearance likelihood that is a sum of parts, each reading a few markers.

    A subclass declares the three attributes (a field or a property each) and implements the
    four methods; it cannot be instantiated otherwise. Every method scores ONE pose: markers
    ``(NUM_MARKERS, 2)`` in pixels and one frame's observation (the engine vmaps over
    particles); ``sharpness`` is λ of eq. 7, an array so that it can change without
    recompiling.

    Attributes:
        part_markers: for each part, the markers (``SPM_MARKERS`` indices) its terms depend on.
        direct_part_markers: for each part, the markers it reads other than through the spine
            length: with ``spine`` given apart, part p depends only on these and on ``spine``
            (:attr:`part_markers` itself when no part reads the spine length).
        spine_markers: the two markers whose distance the parts read apart (neck and pelvis,
            :data:`SPINE_MARKERS`), or None when no part reads it.
    """

    # (evaluated annotations, no `from __future__ import annotations` in this module: equinox
    # does not read AbstractVar from a string)
    part_markers: AbstractVar[tuple[tuple[int, ...], ...]]
    direct_part_markers: AbstractVar[tuple[tuple[int, ...], ...]]
    spine_markers: AbstractVar[tuple[int, int] | None]

    def __check_init__(self):
        # the block-sparse Gauss–Newton relies on these: a part's markers are the markers it
        # reads directly plus, when it reads the spine length, the spine's two
        parts, direct, spine = self.part_markers, self.direct_part_markers, self.spine_markers
        if len(direct) != len(parts):
            raise ValueError(f"direct_part_markers names {len(direct)} parts but part_markers "
                             f"{len(parts)}")
        if spine is not None and len(spine) != 2:
            raise ValueError(f"spine_markers must be two markers or None, got {spine}")
        through_spine = set() if spine is None else set(spine)
        for index, (markers, reads) in enumerate(zip(parts, direct, strict=True)):
            if not set(reads) <= set(markers) <= set(reads) | through_spine:
                raise ValueError(f"part {index} depends on markers {markers} but reads {reads} "
                                 f"directly and the spine length through {spine}")

    @property
    def num_parts(self) -> int:
        """How many parts (patches or strips) the likelihood sums."""
        return len(self.part_markers)

    @property
    def has_whole_pose_terms(self) -> bool:
        """Whether :meth:`log_likelihood` also holds terms of the whole pose that no part
        holds (:meth:`whole_pose_log_likelihood`); False unless a subclass says so."""
        return False

    def whole_pose_log_likelihood(self, markers_2d: Float[ArrayLike, "markers 2"],
                                  observation: Array) -> Float[Array, ""]:
        """The terms of :meth:`log_likelihood` that are no part's (0 unless a subclass has
        some): ``log_likelihood`` is the sum of :meth:`part_log_likelihoods` plus this."""
        return jnp.zeros((), jnp.result_type(jnp.asarray(markers_2d), float))

    def whole_pose_residuals(self, markers_2d: Float[ArrayLike, "markers 2"],
                             observation: Array) -> Float[Array, " residuals"]:
        """The residuals of :meth:`whole_pose_log_likelihood` (half their squared norm is its
        negative), which :meth:`residuals` holds after the parts'; empty unless a subclass has
        such terms."""
        return jnp.zeros((0,), jnp.result_type(jnp.asarray(markers_2d), float))

    @abc.abstractmethod
    def log_likelihood(self, markers_2d: Float[ArrayLike, "markers 2"], observation: Array,
                       sharpness: Float[ArrayLike, ""], nearest: bool = True
                       ) -> Float[Array, ""]:
        """``log p(z | y)`` of one pose, the sum of its parts' terms; ``nearest``: read the
        pixel nearest each sample point (fast, for filters) rather than interpolating
        bilinearly (smooth in the markers, for gradients)."""

    @abc.abstractmethod
    def residuals(self, markers_2d: Float[ArrayLike, "markers 2"], observation: Array,
                  sharpness: Float[ArrayLike, ""], spine: Float[ArrayLike, ""] | None = None
                  ) -> Float[Array, " residuals"]:
        """A flat vector whose half squared norm is ``−log p(z | y)`` up to a constant (bilinear
        reads), for Gauss–Newton; ``spine``: the spine length, given apart (None: the
        markers' own; must be None when :attr:`spine_markers` is)."""

    @abc.abstractmethod
    def part_log_likelihoods(self, markers_2d: Float[ArrayLike, "markers 2"],
                             observation: Array, sharpness: Float[ArrayLike, ""],
                             nearest: bool = True, parts: tuple[int, ...] | None = None
                             ) -> Float[Array, " parts"]:
        """The terms :meth:`log_likelihood` sums, of the parts ``parts`` picks (static
        indices; None: all), computed for those parts alone."""

    @abc.abstractmethod
    def part_residuals(self, markers_2d: Float[ArrayLike, "markers 2"], observation: Array,
                       sharpness: Float[ArrayLike, ""],
                       spine: Float[ArrayLike, ""] | None = None
                       ) -> Float[Array, "parts per_part"]:
        """:meth:`residuals` grouped by part, one row per part: row p depends only on the
        markers :attr:`part_markers` names for it (with ``spine`` given: on those
        :attr:`direct_part_markers` names, and on ``spine``)."""
