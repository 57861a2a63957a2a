"""``cond_any``: a ``lax.cond`` that stays a branch under ``vmap`` (rare branches cost nothing).

``jax.vmap`` turns ``lax.cond`` with a batched predicate into ``select``: both branches run on
every element, every time. For the engine's degenerate-frame recovery (re-draw N particles from
``init`` and weight them) that doubled the cost of a frame for a branch that is almost never
taken. ``cond_any`` has its own batching rule: under ``vmap`` the true branch runs (for the
whole batch, selecting per element) only when the predicate holds for *some* element, and not
at all otherwise, as a sequence filtered on its own would.

Differentiation goes through the plain ``lax.cond`` (a ``custom_jvp`` whose rule is the JVP
of ``lax.cond``), because ``custom_vmap`` has no reverse mode; ``grad`` of a vmapped call then
falls back to both branches, which is correct, only not faster.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import lax
from jax.custom_batching import custom_vmap
from jaxtyping import Array, Bool

Operands = TypeVar("Operands")


def cond_any(predicate: Bool[Array, ""], true_fn: Callable[[Operands], Any],
             false_fn: Callable[[Operands], Any], operands: Operands) -> Any:
    """``lax.cond(predicate, true_fn, false_fn, operands)``, branching on any(predicate) under vmap.

    Both branches must return the same structure of arrays. Non-array leaves of ``operands``
    (static model fields) are passed through unchanged.
    """
    dynamic, static = eqx.partition(operands, eqx.is_array)

    def branch(function):
        return lambda dynamic: function(eqx.combine(dynamic, static))

    def plain(predicate, dynamic):
        return lax.cond(predicate, branch(true_fn), branch(false_fn), dynamic)

    @custom_vmap
    def batched(predicate, dynamic):
        return plain(predicate, dynamic)

    @batched.def_vmap
    def rule(axis_size, in_batched, predicate, dynamic):
        predicate_batched, dynamic_batched = in_batched
        dynamic_axes = jax.tree.map(lambda is_batched: 0 if is_batched else None, dynamic_batched)
        predicate_axis = 0 if predicate_batched else None

        def both(predicate, dynamic):  # under vmap: select between the two branches
            return jax.vmap(plain, in_axes=(predicate_axis, dynamic_axes),
                            axis_size=axis_size)(predicate, dynamic)

        def untaken(predicate, dynamic):
            return jax.vmap(branch(false_fn), in_axes=(dynamic_axes,),
                            axis_size=axis_size)(dynamic)

        if predicate_batched:
            result = lax.cond(jnp.any(predicate), both, untaken, predicate, dynamic)
        else:  # an unbatched predicate keeps vmap's own cond
            result = both(predicate, dynamic)
        return result, jax.tree.map(lambda _: True, result)

    @jax.custom_jvp
    def differentiable(predicate, dynamic):
        return batched(predicate, dynamic)

    @differentiable.defjvp
    def differentiable_jvp(primals, tangents):
        return jax.jvp(plain, primals, tangents)

    return differentiable(predicate, dynamic)
