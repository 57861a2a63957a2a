"""Choose again, on the validation subject, the defaults first tuned on a test subject's clip.

    python -m papers.tian2005.defaults_sweep                  # the whole sweep (resumes)
    python -m papers.tian2005.defaults_sweep --methods mht    # MHT's three only
    python -m papers.tian2005.defaults_sweep --dry-run        # print the commands only

The latent tracker's jump probability ε, the refinement's steps, the default likelihood's κ and
angular tolerance and MHT's velocity weight, prior scale and pruning threshold were first tuned on
``cmu_1006_wave_hello_2`` (a clip of a test subject, papers/tian2005/history.md). Each is chosen
here on the validation subject alone, one after the other in :data:`GRID`'s order, every later
sweep running with the values already chosen (``--methods mht`` alone runs MHT's with κ and the
tolerance as shipped). Grid and rule were fixed before any run:

* **Runs.** Every value is one run of :mod:`papers.tian2005.tracking` (``--split validation
  --clips wide --views 1 --seeds 1 --max-frames 100``): the frontal view of all nine of the
  validation subject's gesture clips, 100 frames each, seed 0, so every value meets the same nine
  sequences and the same random numbers. The latent settings are scored on the shipped
  configuration (latent tracker, 200 particles, the default likelihood, refined); MHT's on MHT's
  own estimate (10 modes, the default likelihood), as the earlier records scored them.
* **Rule.** Take the value of lowest mean error (% of the torso over the nine runs). Another
  value ties with it when its mean is above by less than the 95 % t half-width of the paired
  differences (the same sequence and seed). Among the tied values the one at the parameter's
  simpler or cheaper end wins (:data:`GRID`'s ``prefer``: ``"low"`` or ``"high"``); where neither
  end is simpler or cheaper (``None``) the lowest mean wins. The value shipped today has no part
  in the rule.

Writes ``benchmarks/results/tracking/defaults/<method>/<settings>/`` (the tracking runs; a value
whose settings were already run is read back, not run again) and
``benchmarks/results/tracking/defaults/sweep-<method>.json`` (every value's mean ± 95 %
half-width, the tied values, the choice and its command). The runs share one process, so a
compiled tracker is reused by every value of a setting it takes as an input.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from jaxtrack._files import write_json_atomically
from papers.tian2005 import tracking
from papers.tian2005.tracking import t_interval

RESULTS = Path("benchmarks/results/tracking/defaults")

GRID = (
    # name, values, simpler/cheaper end, method, the shipped value before this sweep (reported)
    ("jump_probability", (0.05, 0.2, 0.5), "low", "latent", 0.2),  # fewer jumps: Tian's walk
    ("refine_steps", (3, 10, 30), "low", "latent", 10),  # fewer Gauss-Newton steps: cheaper
    ("edge_weight", (0.25, 1.0, 4.0), None, "latent", 1.0),
    ("edge_tolerance", (20.0, 45.0, 90.0), None, "latent", 45.0),
    ("velocity_weight", (0.0, 0.5, 1.0), "low", "mht", 0.5),  # 0: constant position
    ("prior_scale", (1.0, 4.0, 16.0), None, "mht", 4.0),
    ("prune_below", (0.25, 1.0, 4.0), None, "mht", 1.0),
)
"""The sweep's order, each parameter's values and which end is simpler or cheaper; fixed before
any run (2026-11-29)."""

COMMON = ("--split", "validation", "--clips", "wide", "--views", "1", "--seeds", "1",
          "--max-frames", "100", "--likelihoods", "limbs+edges")
METHOD_ARGS = {"latent": ("--methods", "latent", "--estimates", "refined"),
               "mht": ("--methods", "mht", "--estimates", "own")}
SWEPT = {"latent": ("jump_probability", "refine_steps", "edge_weight", "edge_tolerance"),
         "mht": ("edge_weight", "edge_tolerance", "velocity_weight", "prior_scale",
                 "prune_below")}
"""The settings each method's runs pass explicitly (κ and the tolerance as chosen for both)."""


def command(method: str, settings: dict) -> tuple[list[str], Path]:
    """The tracking command of one configuration and its output folder."""
    tag = ",".join(f"{name}={settings[name]:g}" for name in SWEPT[method])
    out = RESULTS / method / tag
    argv = [*COMMON, *METHOD_ARGS[method]]
    for name in SWEPT[method]:
        argv += ["--set", f"{name}={settings[name]:g}"]
    return argv + ["--out", str(out)], out


def errors(out: Path) -> dict[str, float]:
    """Mean error (fraction of the torso) of every run of a finished configuration, by run."""
    runs = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    return {f"{run['sequence']}/{run['seed']}": run["mean_error_torso"] for run in runs}


def choose(values: tuple, results: dict, prefer: str | None) -> tuple[float, list]:
    """The rule: the lowest mean, ties by the paired 95 % half-width to the simpler end."""
    keys = sorted(results[values[0]])
    means = {value: float(np.mean([results[value][key] for key in keys])) for value in values}
    best = min(values, key=lambda value: means[value])
    tied = []
    for value in values:
        differences = [results[value][key] - results[best][key] for key in keys]
        if value == best or np.mean(differences) < t_interval(differences):
            tied.append(value)
    if prefer is None:
        return best, tied
    return (min(tied) if prefer == "low" else max(tied)), tied


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m papers.tian2005.defaults_sweep",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--dry-run", action="store_true", help="print the commands only")
    parser.add_argument("--methods", nargs="+", choices=tuple(METHOD_ARGS),
                        default=list(METHOD_ARGS), help="whose settings to sweep")
    args = parser.parse_args(argv)
    chosen = {name: shipped for name, _, _, _, shipped in GRID}
    record = {method: [] for method in args.methods}
    for name, values, prefer, method, shipped in GRID:
        if method not in args.methods:
            continue
        results, rows = {}, []
        for value in values:
            settings = {**chosen, name: value}
            argv_, out = command(method, settings)
            line = " ".join(["python -m papers.tian2005.tracking", *argv_])
            if args.dry_run:
                print(line)
                continue
            if not (out / "summary.json").exists():
                print(line, flush=True)
                if tracking.main(argv_) != 0:
                    print(f"{line} failed")
                    return 1
            results[value] = errors(out)
            torso = list(results[value].values())
            summary = json.loads((out / "summary.json").read_text())
            rows.append({"value": value, "runs": len(torso), "mean": float(np.mean(torso)),
                         "half_width": t_interval(torso),
                         "lost": sum(row["num_lost"] for row in summary["rows"]),
                         "ms_per_frame": summary["rows"][0]["ms_per_frame"],
                         "command": line})
        if args.dry_run:
            continue
        value, tied = choose(values, results, prefer)
        chosen[name] = value
        record[method].append({"name": name, "method": method, "values": list(values),
                       "prefer": prefer, "shipped": shipped, "chosen": value, "tied": tied,
                       "rows": rows})
        print(f"{name}: " + ", ".join(f"{row['value']:g}: {100 * row['mean']:.2f} ± "
                                      f"{100 * row['half_width']:.2f} % ({row['lost']} lost)"
                                      for row in rows)
              + f"; tied {tied}; chosen {value:g} (shipped {shipped:g})", flush=True)
        write_json_atomically(RESULTS / f"sweep-{method}.json", {
            "grid": [{"name": n, "values": list(v), "prefer": p, "method": m}
                     for n, v, p, m, _ in GRID if m == method],
            "rule": __doc__.split("* **Rule.** ")[1].split("\n\nWrites")[0].replace("\n  ", " "),
            "record": record[method], "chosen": chosen})
    return 0 if all(math.isfinite(value) for value in chosen.values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
