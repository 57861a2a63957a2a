"""Shared helpers for the benchmark scripts: timing, memory, device name, table and JSON output."""

from __future__ import annotations

import json
import os
import platform
import resource
import statistics
import subprocess
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import jax


def device_description() -> str:
    device = jax.devices()[0]
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as handle:
            names = [line.split(":", 1)[1].strip() for line in handle if "model name" in line]
        cpu = names[0] if names else cpu
    except OSError:
        pass
    cores = os.cpu_count()
    return f"{device.platform}:{device.device_kind} ({cores} cores, {cpu}), jax {jax.__version__}"


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far (MB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_header(module: str, argv: Sequence[str] | None, started: float) -> dict:
    """The fields every benchmark's JSON opens with: the command line that ran ``module``
    (``benchmarks.X``) with ``argv``, the device, today's date, the seconds since ``started``
    (a ``time.perf_counter()`` reading) and the peak resident memory (MB)."""
    return {"command": f"python -m {module} " + " ".join(argv or []),
            "device": device_description(), "date": time.strftime("%Y-%m-%d"),
            "seconds": time.perf_counter() - started, "peak_rss_mb": peak_rss_mb()}


def time_call(function, *args, repeats: int = 3):
    """(compile+first-run seconds, median seconds of ``repeats`` further runs, last output)."""
    start = time.perf_counter()
    output = jax.block_until_ready(function(*args))
    first = time.perf_counter() - start
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        output = jax.block_until_ready(function(*args))
        times.append(time.perf_counter() - start)
    median = statistics.median(times) if times else first
    return max(first - median, 0.0), median, output


def time_compiled(function, *args, repeats: int = 3):
    """(lower+compile seconds, median seconds, median CPU seconds of ``repeats`` runs, last output).

    ``jax.jit(function)`` is lowered and compiled explicitly, so compile time is measured on its
    own rather than as first call minus median (which a loaded machine can swamp). CPU seconds
    are this process's (all threads), less sensitive than wall time to other jobs on the
    machine. Every argument must be a pytree of arrays.
    """
    start = time.perf_counter()
    compiled = jax.jit(function).lower(*args).compile()
    compile_seconds = time.perf_counter() - start
    times, cpu_times, output = [], [], None
    for _ in range(max(repeats, 1)):
        start, cpu = time.perf_counter(), time.process_time()
        output = jax.block_until_ready(compiled(*args))
        times.append(time.perf_counter() - start)
        cpu_times.append(time.process_time() - cpu)
    return compile_seconds, statistics.median(times), statistics.median(cpu_times), output


def print_table(rows: list[dict], columns: list[tuple[str, str, str]]) -> None:
    """columns: (key, header, format)."""
    headers = [header for _, header, _ in columns]
    cells = [[format(row[key], fmt) if row.get(key) is not None else "-" for key, _, fmt in columns]
             for row in rows]
    widths = [max(len(h), *(len(c[i]) for c in cells)) for i, h in enumerate(headers)]
    print("  ".join(h.rjust(w) for h, w in zip(headers, widths, strict=True)))
    for line in cells:
        print("  ".join(c.rjust(w) for c, w in zip(line, widths, strict=True)))


def write_json(path: str | Path, payload: dict) -> None:
    """Write JSON atomically (temp file + rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False, suffix=".tmp") as handle:
        json.dump(payload, handle, indent=2)
        temp = handle.name
    os.replace(temp, path)


def run_in_venv(python: Path, script: Path, inputs: dict, *, output: str, read, label: str,
                timeout: float | None, arguments: tuple[str, ...] = ()) -> dict:
    """Run ``python script [arguments] IN.npz OUT`` on ``inputs`` in a temporary folder (a
    reference library in its own venv) and return ``read(OUT)`` plus ``summary`` (the script's
    stdout),
    or ``{"skipped": reason}`` when the run fails, times out or cannot start. ``output`` names
    OUT's file (its suffix is the script's format); ``label`` names the run in the reasons."""
    import numpy as np

    with tempfile.TemporaryDirectory(prefix="jaxtrack-reference-") as folder:
        in_path, out_path = Path(folder) / "in.npz", Path(folder) / output
        np.savez(in_path, **inputs)
        command = [str(python), str(script), *arguments, str(in_path), str(out_path)]
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            return {"skipped": f"{label} run timed out after {timeout:g} s"}
        except OSError as error:
            return {"skipped": f"cannot run {python}: {error}"}
        if done.returncode != 0 or not out_path.exists():
            tail = (done.stderr or done.stdout).strip().splitlines()[-3:]
            return {"skipped": f"{label} run failed ({done.returncode}): " + " | ".join(tail)}
        result = read(out_path)
    result["summary"] = done.stdout.strip()
    return result
