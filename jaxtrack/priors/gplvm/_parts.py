"""A pose prior factorised by body part: one GPLVM per part, their latent spaces side by side.

Tian et al. learn one GPLVM of the whole upper body, so a pose is only reachable if some training
pose combined its arms' configurations the same way. Another person waves with the other arm
raised a little differently, and no training pose holds that combination: on the validation
subjects the nearest of 14 540 whole-body training poses was 17.5 % of the torso off on a wave,
the nearest *per part* (torso, each arm) 3.8 % (papers/tian2005/history.md, "A prior that
generalises").
:class:`PartsGPLVM` learns one GPLVM per part from the same training poses; its latent point is
the parts' latent points concatenated (2 + 2 + 2 = 6-D for the default parts), μ(x) scatters
each part's μ into its links' features, and μ⁻¹ inverts each part on its own links. It has the
interface the trackers use of :class:`GPLVM` (``mean``, ``inverse``, ``reconstruct``,
``latents``, ``dynamics_std``, ``astype``), so the latent tracker, its jumps (a whole training
row of latents) and the automatic initialisation take either.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, ArrayLike, Float

from jaxtrack.priors.gplvm._model import GPLVM, InverseResult

__all__ = ["UPPER_BODY_PARTS", "PartsGPLVM", "feature_columns", "part_features"]

UPPER_BODY_PARTS: dict[str, tuple[int, ...]] = {
    "torso": (0, 1, 2, 6, 10),  # neck–head, neck–thorax, thorax–pelvis, the two hips
    "right_arm": (3, 4, 5),  # neck–shoulder, upper arm, forearm
    "left_arm": (7, 8, 9),
}
"""The default parts: indices into :data:`jaxtrack.body.SPM_LINKS` (each link is two features)."""


def feature_columns(links: tuple[int, ...]) -> np.ndarray:
    """The columns of link-vector features (two per link, x then y) that hold ``links``."""
    return np.asarray([index for link in links for index in (2 * link, 2 * link + 1)])


class PartsGPLVM(eqx.Module):
    """One :class:`GPLVM` per body part over the same training poses (module docstring).

    Attributes:
        parts: the parts' GPLVMs, each over its links' features.
        links: per part, its links (indices into ``SPM_LINKS``); together every link once.
        names: per part, its name.
    """

    parts: tuple[GPLVM, ...]
    links: tuple[tuple[int, ...], ...] = eqx.field(static=True)
    names: tuple[str, ...] = eqx.field(static=True)

    def __check_init__(self):
        if len(self.parts) != len(self.links) or len(self.parts) != len(self.names):
            raise ValueError(f"{len(self.parts)} parts, {len(self.links)} link groups and "
                             f"{len(self.names)} names differ in number")
        flat = sorted(link for group in self.links for link in group)
        if flat != list(range(len(flat))):
            raise ValueError(f"the parts' links must cover links 0..{len(flat) - 1} once each, "
                             f"got {self.links}")
        for part, group, name in zip(self.parts, self.links, self.names, strict=True):
            if part.pose_dim != 2 * len(group):
                raise ValueError(f"part {name!r} has {len(group)} links but its GPLVM models "
                                 f"{part.pose_dim} features")
        rows = {int(part.latents.shape[0]) for part in self.parts}
        if len(rows) != 1:
            raise ValueError(f"the parts were trained on different numbers of poses: {rows}")

    # --- shapes -------------------------------------------------------------------------
    @property
    def latent_dim(self) -> int:
        return sum(part.latent_dim for part in self.parts)

    @property
    def pose_dim(self) -> int:
        return sum(part.pose_dim for part in self.parts)

    @property
    def active_size(self) -> int:
        """The largest active set of a part."""
        return max(part.active_size for part in self.parts)

    def _latent_slices(self) -> list[slice]:
        offsets = np.cumsum([0] + [part.latent_dim for part in self.parts])
        return [slice(int(a), int(b)) for a, b in zip(offsets[:-1], offsets[1:], strict=True)]

    def _feature_indices(self) -> list[np.ndarray]:
        return [feature_columns(group) for group in self.links]

    # --- what the trackers read ---------------------------------------------------------
    @property
    def latents(self) -> Float[Array, "n latent"]:
        """Every training pose's latent point: the parts' latents side by side."""
        return jnp.concatenate([part.latents for part in self.parts], axis=1)

    @property
    def dynamics_std(self) -> Float[Array, " latent"]:
        """ν of every part, side by side."""
        return jnp.concatenate([part.dynamics_std for part in self.parts])

    @property
    def dynamics_fps(self) -> Float[Array, ""]:
        return self.parts[0].dynamics_fps

    def astype(self, dtype) -> PartsGPLVM:
        return PartsGPLVM(tuple(part.astype(dtype) for part in self.parts), self.links,
                          self.names)

    def mean(self, latent: Float[ArrayLike, " latent"]) -> Float[Array, " dims"]:
        """μ(x): each part's μ of its slice of ``latent``, in its links' places."""
        latent = jnp.asarray(latent)
        pieces = [part.mean(latent[where])
                  for part, where in zip(self.parts, self._latent_slices(), strict=True)]
        order = np.argsort(np.concatenate(self._feature_indices()))
        return jnp.concatenate(pieces)[order]

    def variance(self, latent: Float[ArrayLike, " latent"]) -> Float[Array, ""]:
        """The parts' σ²(x), averaged over features (each part's σ² weighted by its
        features)."""
        latent = jnp.asarray(latent)
        values = [part.variance(latent[where]) * part.pose_dim
                  for part, where in zip(self.parts, self._latent_slices(), strict=True)]
        return sum(values) / self.pose_dim

    def inverse(self, poses: Float[ArrayLike, "poses dims"], **options) -> InverseResult:
        """μ⁻¹ of each part on its links' features (``options`` as for
        :meth:`GPLVM.inverse`; ``initial_latents``, if given, side by side as ``latents``)."""
        poses = jnp.asarray(poses)
        if poses.ndim != 2 or poses.shape[1] != self.pose_dim:
            raise ValueError(
                f"poses must have shape (num_poses, {self.pose_dim}), got {poses.shape}")
        starts = options.pop("initial_latents", None)
        solved = []
        for part, features, where in zip(self.parts, self._feature_indices(),
                                         self._latent_slices(), strict=True):
            start = None if starts is None else jnp.asarray(starts)[:, where]
            solved.append(part.inverse(poses[:, features], initial_latents=start, **options))
        result = solved[0].result  # per pose: the first part's that did not converge, if any
        success = optx.RESULTS.successful._value
        for other in solved[1:]:
            result = jax.tree.map(lambda mine, theirs: jnp.where(mine == success, theirs, mine),
                                  result, other.result)
        return InverseResult(latents=jnp.concatenate([s.latents for s in solved], axis=1),
                             objective=sum(s.objective for s in solved), result=result)

    def reconstruct(self, poses: Float[ArrayLike, "poses dims"], **options) -> Array:
        """μ(μ⁻¹(y)) for a batch of poses (``options`` as for :meth:`inverse`)."""
        return jax.vmap(self.mean)(self.inverse(poses, **options).latents)


def part_features(features: Float[ArrayLike, "n dims"], links: tuple[int, ...]) -> np.ndarray:
    """The columns of link-vector features (``(n, 2 × links)``) that belong to ``links``."""
    return np.asarray(features)[:, feature_columns(links)]
