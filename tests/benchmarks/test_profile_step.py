"""``benchmarks.tracker_step --profile``'s helpers: HLO instructions matched to the tracker's
named scopes."""

import jax
import jax.numpy as jnp
import pytest

from benchmarks.tracker_step import _instructions, _stage, dispatch_cost


@pytest.mark.parametrize("op_name, stage", [
    ("jit(_chunk)/while/body/closed_call/filter/vmap()/dot_general", "filter"),
    ("jit(_chunk)/while/body/closed_call/vmap(arm_search)/vmap()/add", "arm_search"),
    ("vmap(gauss_newton)/while/body/closed_call/reduce_sum", "gauss_newton"),
    ("jit(_chunk)/while/body/closed_call/candidates/mul", "candidates"),
    ("jit(_chunk)/while/body/closed_call/filtered_thing/add", "other"),  # a name, not a scope
    ("jit(_chunk)/while/body/add", "other"),
    ("", "other"),
])
def test_stage_of_an_op_name(op_name, stage):
    assert _stage(op_name) == stage


def test_instructions_carry_the_named_scopes_of_compiled_code():
    def function(x, table):
        with jax.named_scope("filter"):
            y = jnp.take(table, jnp.clip((x * 10).astype(jnp.int32), 0, 9))
        with jax.named_scope("gauss_newton"):
            return jnp.linalg.cholesky(jnp.outer(y, y) + jnp.eye(3)) @ y

    x, table = jnp.arange(3.0), jnp.linspace(0.0, 1.0, 10)
    text = jax.jit(function).lower(x, table).compile().as_text()
    instructions = _instructions(text)
    stages = {_stage(op_name) for _, op_name in instructions.values()}
    assert {"filter", "gauss_newton"} <= stages
    opcodes = {opcode for opcode, _ in instructions.values()}
    assert "parameter" in opcodes
    assert all(name and opcode for name, (opcode, _) in instructions.items())


def test_dispatch_cost_is_a_positive_slope():
    result = dispatch_cost(rounds=(0, 4, 16), repeats=3)
    assert set(result["step_us"]) == {0, 4, 16}
    assert result["step_us"][16] > result["step_us"][0]
    assert 0 < result["us_per_op"] < 100
