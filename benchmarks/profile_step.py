"""Where one frame of the latent tracker's compiled scan spends its time, stage by stage and op
by op (JAX's profiler on CPU XLA).

The tracker is built as ``benchmarks.tracker_step`` builds it (the demo's held-out wave over a
photo, ``limbs+edges`` with the median background, 200 particles). The chunk scan of
``jaxtrack.trackers.track`` is compiled ahead, timed without the profiler (median of
``--repeats`` runs), then run once under ``jax.profiler.trace``. Every op XLA executed is
matched to its HLO instruction, whose ``op_name`` carries the tracker's named scopes:

    filter        the particle filter's step and estimate (propagate, μ, strips, resample)
    candidates    μ of the particles' estimate: the second refinement candidate
    arm_search    the arm search of both candidates
    gauss_newton  the damped Gauss–Newton of both candidates
    choice        scoring the refined candidates and keeping the better one
    other         the scan's own bookkeeping

Control-flow thunks (while, conditional, call) are left out, their bodies being counted op by
op. The profiler slows every op down, so the table gives each stage's share of the traced
time and that share of the untraced ms per frame.

Second, the cost of dispatching an op, to tell a floor set by the number of ops from one set
by their work: a scan whose body is a chain of ``k`` rounds of three dependent tiny ops (a
gather, a sum, an 8 × 8 matrix–vector product), for a few ``k``; the slope is the cost per op.

    python -m benchmarks.profile_step            # table, top ops; writes results/profile_step.json
"""

from __future__ import annotations

import argparse
import collections
import gzip
import json
import re
import statistics
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks._common import device_description, print_table, write_json
from benchmarks.tracker_step import CHUNK, _chunk_arguments, _load_average, _tracked_state, build

RESULTS = Path(__file__).parent / "results"
STAGES = ("filter", "candidates", "arm_search", "gauss_newton", "choice")
_CONTROL_FLOW = {"while", "conditional", "call"}


def _instructions(hlo: str) -> dict[str, tuple[str, str]]:
    """``{instruction name: (opcode, op_name)}`` of an optimised HLO module's text."""
    found = {}
    pattern = re.compile(r"^\s*(?:ROOT )?%([\w.\-]+) = .*?\s([a-z][\w\-]*)\((.*)$", re.M)
    for match in pattern.finditer(hlo):
        name, opcode, rest = match.groups()
        scope = re.search(r'op_name="([^"]*)"', rest)
        found.setdefault(name, (opcode, scope.group(1) if scope else ""))
    return found


def _stage(op_name: str) -> str:
    for stage in STAGES:
        if re.search(rf"(^|[/(]){stage}[/)]", op_name):
            return stage
    return "other"


def _trace_events(directory: Path) -> list[dict]:
    paths = sorted(directory.glob("plugins/profile/*/*.trace.json.gz"))
    if not paths:
        raise RuntimeError(f"jax.profiler wrote no trace.json.gz under {directory}")
    with gzip.open(paths[-1]) as handle:
        return [event for event in json.load(handle)["traceEvents"] if event.get("ph") == "X"]


def profile_chunk(tracker, frames, initial_pose, repeats: int) -> dict:
    """Untraced ms per frame of the chunk scan, and the traced ops grouped by stage."""
    from jaxtrack.trackers._runner import _chunk

    arguments = _chunk_arguments(tracker, _tracked_state(tracker, frames, initial_pose), frames)
    compiled = _chunk.lower(*arguments).compile()
    instructions = _instructions(compiled.compiled.as_text())
    jax.block_until_ready(compiled(*arguments))
    times = []
    for _ in range(repeats):
        tick = time.perf_counter()
        jax.block_until_ready(compiled(*arguments))
        times.append((time.perf_counter() - tick) / CHUNK)
    with tempfile.TemporaryDirectory() as directory:
        with jax.profiler.trace(directory):
            jax.block_until_ready(compiled(*arguments))
        events = _trace_events(Path(directory))
    stages = collections.defaultdict(lambda: {"ops": 0, "us": 0.0})
    ops = collections.defaultdict(lambda: {"count": 0, "us": 0.0, "stage": "", "op_name": ""})
    for event in events:
        opcode, op_name = instructions.get(event["name"], (None, ""))
        if opcode is None or opcode in _CONTROL_FLOW:
            continue
        stage = _stage(op_name)
        stages[stage]["ops"] += 1
        stages[stage]["us"] += event["dur"]
        op = ops[event["name"]]
        op["count"] += 1
        op["us"] += event["dur"]
        op["stage"], op["op_name"] = stage, op_name
    traced_us = sum(stage["us"] for stage in stages.values())
    ms = 1e3 * statistics.median(times)
    if traced_us == 0:
        raise RuntimeError("the trace holds no op of the compiled scan")
    table = {name: {"ops_per_frame": value["ops"] / CHUNK,
                    "share": value["us"] / traced_us,
                    "ms_per_frame": ms * value["us"] / traced_us}
             for name, value in sorted(stages.items(), key=lambda item: -item[1]["us"])}
    top = [{"op": name, "stage": value["stage"], "per_frame": value["count"] / CHUNK,
            "share": value["us"] / traced_us, "op_name": value["op_name"]}
           for name, value in sorted(ops.items(), key=lambda item: -item[1]["us"])[:15]]
    return {"ms_per_frame": ms, "ops_per_frame": sum(v["ops"] for v in stages.values()) / CHUNK,
            "stages": table, "top_ops": top}


def dispatch_cost(rounds=(0, 16, 64, 256), repeats: int = 30) -> dict:
    """µs per scan step of a chain of ``k`` rounds of three dependent tiny ops, and the
    fitted µs per op."""
    rng = np.random.default_rng(0)
    matrix = jnp.asarray(rng.normal(size=(8, 8)) / 3, jnp.float32)
    table = jnp.linspace(0, 1, 4096, dtype=jnp.float32)
    step_us = {}
    for count in rounds:
        def body(x, _, count=count):
            for _ in range(count):
                index = (jnp.abs(x[:4]) * 4000).astype(jnp.int32)
                x = x + jnp.take(table, index, mode="clip").sum()
                x = jnp.tanh(matrix @ x)
            return x, x[0]

        run = jax.jit(lambda x, body=body: jax.lax.scan(body, x, None, length=CHUNK))
        start = jnp.ones(8, jnp.float32)
        compiled = run.lower(start).compile()
        jax.block_until_ready(compiled(start))
        times = []
        for _ in range(repeats):
            tick = time.perf_counter()
            jax.block_until_ready(compiled(start))
            times.append(time.perf_counter() - tick)
        step_us[count] = 1e6 * statistics.median(times) / CHUNK
    slope = np.polyfit(list(step_us), list(step_us.values()), 1)[0]
    return {"step_us": step_us, "us_per_op": float(slope) / 3}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--particles", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--output", default=str(RESULTS / "profile_step.json"))
    args = parser.parse_args()
    tracker, frames, _, initial_pose = build(args.particles, likelihood="limbs+edges")
    load = _load_average()
    profile = profile_chunk(tracker, frames, initial_pose, args.repeats)
    dispatch = dispatch_cost()
    print(f"{device_description()}, load {load:.2f}")
    print(f"\nlatent tracker, {args.particles} particles: {profile['ms_per_frame']:.2f} ms and "
          f"{profile['ops_per_frame']:.0f} ops per frame in the scan\n")
    print_table([{"stage": name, **row, "share": 100 * row["share"]}
                 for name, row in profile["stages"].items()],
                [("stage", "stage", "s"), ("ops_per_frame", "ops/frame", ".0f"),
                 ("share", "share %", ".1f"), ("ms_per_frame", "ms/frame", ".3f")])
    print("\ncostliest ops:\n")
    print_table([{**op, "share": 100 * op["share"],
                  "from": op["op_name"].split("closed_call/")[-1][-60:]}
                 for op in profile["top_ops"]],
                [("op", "op", "s"), ("stage", "stage", "s"), ("per_frame", "runs/frame", ".0f"),
                 ("share", "share %", ".1f"), ("from", "from", "s")])
    print(f"\ndispatch: {dispatch['us_per_op']:.3f} µs per op (scan steps of k rounds: "
          + ", ".join(f"k={k} {us:.1f} µs" for k, us in dispatch["step_us"].items()) + ")")
    print(f"the tracker's {profile['ops_per_frame']:.0f} ops per frame at that cost: "
          f"{profile['ops_per_frame'] * dispatch['us_per_op'] / 1e3:.3f} ms")
    write_json(args.output, {"device": device_description(), "load_average": load,
                             "particles": args.particles, "profile": profile,
                             "dispatch": dispatch})


if __name__ == "__main__":
    main()
