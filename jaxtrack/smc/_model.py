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
