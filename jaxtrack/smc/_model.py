"""The state-space model contract that the SMC engine runs.

A model describes ONE particle; the engine vmaps its methods over the particle axis, so model
code never sees that axis. A particle is any pytree: an array, or a dict mixing a discrete
posture (integer leaf) with continuous positions (float leaves).
"""

from __future__ import annotations

import abc
from typing import Any

import equinox as eqx
import jax
import numpy as np
from jaxtyping import Array, Float, Int, PRNGKeyArray, PyTree

Particle = PyTree[Any]
Observation = PyTree[Any]


class StateSpaceModel(eqx.Module):
    """Base class of every model the engine runs (Feynman–Kac form of a bootstrap filter).

    Subclasses implement the three per-particle methods. ``log_transition_density`` is
    optional: backward-simulation smoothers (``ffbsi``) need it, forward filtering does not.

    A model may also declare ``observation_shape``: the shape of ONE frame's observation (a
    tuple of ints, or a pytree of such tuples matching a pytree observation), as a class
    attribute, a property or a static field. ``run``, ``step`` and ``initialize`` then refuse
    observations of another shape at trace time, naming both shapes; without it (the default,
    ``None``) the engine cannot tell a wrong shape from a right one, and a wrong one may
    broadcast silently. ``LinearGaussian`` declares it.
    Numeric model parameters must be array fields so ``jax.grad`` of the log evidence reaches
    them; shapes and counts are ``eqx.field(static=True)``.

    Proposals (optional). A model may draw its particles from something other than its
    dynamics, and say by how much that tilts them, by defining either or both of:

    - ``propose(key, particle, time, observation) -> (particle, log_weight_correction)``: draw
      the particle of frame ``time`` from a proposal q(x_t | x_{t-1}, y_t) that may look at
      that frame's observation. ``step`` calls it instead of ``propagate`` and weighs each child
      by ``log_weight_correction + log_likelihood(child, observation)``; the two together must
      be the log importance weight log [p(y_t | x_t) p(x_t | x_{t-1}) / q(x_t | x_{t-1}, y_t)],
      up to a constant shared by all particles. Usually the correction is log p(x_t | x_{t-1})
      − log q(x_t | x_{t-1}, y_t) and ``log_likelihood`` stays log p(y_t | x_t); a proposal
      that already accounts for part of the likelihood may instead put the whole weight of
      that part in the correction and leave the rest in ``log_likelihood`` (the "optimal"
      proposal p(x_t | x_{t-1}, y_t): correction log p(y_t | x_{t-1}), log-likelihood zero,
      ``tests/smc/test_proposals.py``; the mixed-state tracker: the posture drawn from eq. 8–9,
      correction its row normaliser, ``log_likelihood`` the parts' term).
    - ``init_propose(key, observation) -> (particle, log_weight_correction)``: the same for
      frame 0 (a proposal for p(x_0) that may look at the first observation), used by
      ``initialize`` instead of ``init``, and by the re-seeding of a degenerate frame (with that
      frame's observation).

    Corrections are scalars per particle (the engine vmaps these methods like the others); a
    NaN correction counts as an invalid particle (weight zero). A model that defines neither
    runs as the bootstrap filter, bit for bit as before the hooks existed.
    """

    @abc.abstractmethod
    def init(self, key: PRNGKeyArray) -> Particle:
        """Draw one particle from the initial distribution p(x_0)."""

    @abc.abstractmethod
    def propagate(self, key: PRNGKeyArray, particle: Particle, time: Int[Array, ""]) -> Particle:
        """Draw one particle at frame ``time`` from p(x_time | x_{time-1} = particle)."""

    @abc.abstractmethod
    def log_likelihood(self, particle: Particle, observation: Observation) -> Float[Array, ""]:
        """Return log p(observation | particle) up to a constant that is the same for all particles.

        The constant matters only for the absolute value of the log evidence.
        """

    def log_transition_density(
        self, previous: Particle, particle: Particle, time: Int[Array, ""]
    ) -> Float[Array, ""]:
        """Return log p(x_time = particle | x_{time-1} = previous); needed by ``ffbsi`` only."""
        raise NotImplementedError(
            f"{type(self).__name__} does not define log_transition_density, which backward "
            "simulation (ffbsi) needs; use the ancestry-tracing smoother instead."
        )


def defines(model: Any, hook: str) -> bool:
    """Whether ``model`` defines the optional method ``hook`` (``propose``, ``init_propose``)."""
    return callable(getattr(model, hook, None))


def _is_shape(value: Any) -> bool:
    return isinstance(value, tuple) and all(isinstance(size, int | np.integer) for size in value)


def check_observation_shape(model: StateSpaceModel, observation: Observation, *,
                            time_axis: bool) -> None:
    """Raise ``ValueError`` if ``observation`` does not match the model's ``observation_shape``.

    Args:
        observation: one frame's observation, or with ``time_axis`` a whole sequence (each
            leaf with a leading ``time`` axis).

    Does nothing for a model that declares no ``observation_shape``. Shapes are static, so the
    check runs at trace time and costs nothing in the compiled filter.
    """
    expected = getattr(model, "observation_shape", None)
    if expected is None:
        return
    name = type(model).__name__
    what = "observations" if time_axis else "observation"
    expected_leaves, expected_tree = jax.tree.flatten(expected, is_leaf=_is_shape)
    given_leaves, given_tree = jax.tree.flatten(observation)
    if expected_tree != given_tree:
        raise ValueError(f"{name} expects each frame's observation structured as {expected}, "
                         f"got {what} structured as {given_tree}")
    for want, leaf in zip(expected_leaves, given_leaves, strict=True):
        given = tuple(np.shape(leaf))
        frame = given[1:] if time_axis else given
        if (time_axis and not given) or frame != tuple(int(size) for size in want):
            want = tuple(int(size) for size in want)
            wanted = "(" + ", ".join(["time", *map(str, want)]) + ")" if time_axis else str(want)
            raise ValueError(f"{name} expects {what} of shape {wanted} (one observation of "
                             f"shape {want} per frame), got {what} of shape {given}")
