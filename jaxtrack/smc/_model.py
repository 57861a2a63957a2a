"""The state-space model contract that the SMC engine runs.

A model describes ONE particle; the engine vmaps its methods over the particle axis, so model
code never sees that axis. A particle is any pytree: an array, or a dict mixing a discrete
posture (integer leaf) with continuous positions (float leaves).
"""

from __future__ import annotations

import abc
from typing import Any

import equinox as eqx
from jaxtyping import Array, Float, Int, PRNGKeyArray, PyTree

Particle = PyTree[Any]
Observation = PyTree[Any]


class StateSpaceModel(eqx.Module):
    """Base class of every model the engine runs (Feynman–Kac form of a bootstrap filter).

    Subclasses implement the three per-particle methods. ``log_transition_density`` is
    optional: backward-simulation smoothers (``ffbsi``) need it, forward filtering does not.
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
