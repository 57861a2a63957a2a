"""HDM05's arm movements as held-out people: the latent tracker against CONDENSATION on actor tr.

    python -m papers.tian2005.hdm05 --json papers/tian2005/results/hdm05.json

The priors learn from actors bd, bk and dg's takes of three arm movements of HDM05
(``../shared/data/hdm05_cut``, CC BY-SA 3.0, read in place): reach up with the right hand
(``grabHighR``), circle both arms backwards (``rotateArmsBothBackward1Reps``) and elbow to knee
(``elbowToKnee1RepsLelbowStart``); :mod:`jaxtrack.data.splits` puts those actors in training,
mm in validation and tr in test. Two priors are trained on the same poses (5 views, 30 fps):
Tian et al.'s one GPLVM of the whole upper body, and one GPLVM per body part
(``PartsGPLVM``). Each take is rendered from the front over the real photo and tracked from
frame 0's truth with the default likelihood (limb strips, edges, the arms' foreground); the
filters' own estimates are scored (no refinement), the latent tracker with 200 particles,
CONDENSATION with 1 000 and MHT with 10 modes, both baselines with their dynamics learned from
the same training poses.

The one setting chosen is the per-part prior's sampler (one step on the whole latent point, or
partitioned sampling), on all of mm's takes by :data:`CHOICE_RULE`. Then tr's takes are
tracked and only reported; the ratio to CONDENSATION has a bootstrap interval over takes.
Each run's record is cached in ``RUNS/hdm05/tracks`` (keyed by everything it depends on), so an
interrupted run resumes where it stopped.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

KINDS = ("grabHighR", "rotateArmsBothBackward1Reps", "elbowToKnee1RepsLelbowStart")
PARTICLES = {"latent": 200, "condensation": 1000, "mht": 10}
LIKELIHOOD = "limbs+edges"
TAKES = ("all", "first")
"""``--takes``: every take of each movement and actor, or only the first (by take number)."""
CONFIGURATIONS = {
    "latent, whole body": ("whole", "latent", {}),
    "latent, per part": ("parts", "latent", {}),
    "latent, per part, partitioned": ("parts", "latent", {"partitioned": 1.0}),
    "condensation": ("whole", "condensation", {}),
    "mht": ("whole", "mht", {}),
}
"""name -> (prior, method, ``tracking.run_one`` settings). The baselines learn from the same
training poses whichever prior they are given; they are run with the whole-body one."""
PER_PART = ("latent, per part", "latent, per part, partitioned")
"""The per-part prior's two samplers: one step (Tian et al.'s) and partitioned sampling."""
CHOICE_RULE = (
    "on every validation take, the per-part latent tracker's own mean error (torso lengths, "
    "averaged over seeds) with each sampler; partitioned sampling is chosen only when its mean "
    "paired difference to one step (partitioned - one step, over takes) is below 0 and its 95 % "
    "t-interval excludes 0; otherwise the paper's one-step sampler, the simpler, is kept")
"""Written before the all-takes runs (2026-11-29): the argmin of the latent tracker's own
mean error, with the one-step sampler kept whenever the difference is within the noise."""


def arm_clips(split: str, takes_per_kind: int | None = None) -> tuple[str, ...]:
    """The HDM05 arm-movement takes (:data:`KINDS`) of one split's actors: all of them, or the
    first ``takes_per_kind`` of each movement and actor (by take number)."""
    from jaxtrack.data.splits import clips_in, subject_of

    clips = [clip for clip in clips_in(split, "hdm05_cut") if clip.split("/")[1] in KINDS]
    if takes_per_kind is None:
        return tuple(clips)
    kept, count = [], {}
    for clip in clips:  # clips_in sorts them, so by take number within a movement and actor
        key = (clip.split("/")[1], subject_of(clip))
        count[key] = count.get(key, 0) + 1
        if count[key] <= takes_per_kind:
            kept.append(clip)
    return tuple(kept)


def takes_of(split: str, takes: str) -> tuple[str, ...]:
    """:func:`arm_clips` of ``split`` for ``--takes`` (:data:`TAKES`)."""
    if takes not in TAKES:
        raise ValueError(f"takes must be one of {', '.join(TAKES)}, got {takes!r}")
    return arm_clips(split, None if takes == "all" else 1)


def train_priors(progress: bool = False) -> dict:
    """The whole-body and the per-part prior of the training actors' arm takes, cached in
    ``RUNS/hdm05``."""
    from jaxtrack.data.splits import check_disjoint
    from jaxtrack.priors.gplvm import UPPER_BODY_PARTS
    from jaxtrack.priors.train import train_prior
    from papers.tian2005 import RUNS

    clips = arm_clips("training")
    check_disjoint(clips, arm_clips("validation") + arm_clips("test"))
    return {"whole": train_prior(clips, progress=progress,
                                 cache=RUNS / "hdm05" / "prior_whole.npz"),
            "parts": train_prior(clips, progress=progress, parts=UPPER_BODY_PARTS,
                                 cache=RUNS / "hdm05" / "prior_parts.npz")}


def _cache_path(priors: dict, name: str, clip: str, render_seed: int, seed: int) -> Path:
    """Where one run's record is cached: a hash of everything the run depends on (the prior's
    description, the configuration, the take and its rendering seed, the tracker seed)."""
    from papers.tian2005 import RUNS

    prior, method, settings = CONFIGURATIONS[name]
    key = {"prior": priors[prior].description, "method": method, "settings": settings,
           "particles": PARTICLES[method], "likelihood": LIKELIHOOD, "estimate": "own",
           "baseline_dynamics": "training", "clip": clip, "render_seed": render_seed,
           "seed": seed}
    digest = hashlib.sha256(json.dumps(key, sort_keys=True, default=str).encode()).hexdigest()
    return RUNS / "hdm05" / "tracks" / f"{digest[:20]}.json"


def track_split(priors: dict, split: str, names, seeds: int, takes: str = "all",
                progress: bool = True, reverse: bool = False) -> list[dict]:
    """Every configuration of ``names`` on the arm takes of ``split``'s actors (frontal view;
    :func:`takes_of`), ``seeds`` tracker seeds each: ``tracking.run_one``'s records plus
    ``configuration`` and ``clip``. A take is rendered with its index among all of its split's
    takes as seed, so that it looks the same whichever ``takes`` are run; ``reverse`` tracks
    the takes last to first (a second process can then fill the cache from the other end)."""
    from tqdm import tqdm

    from jaxtrack._files import write_json_atomically
    from jaxtrack.experiments import render_test_sequences
    from papers.tian2005.tracking import run_one

    every = arm_clips(split)
    clips = takes_of(split, takes)[::-1 if reverse else 1]
    runs = []
    bar = tqdm(total=len(clips) * len(names) * seeds, desc=f"{split} runs",
               disable=not progress)
    for clip in clips:
        render_seed = every.index(clip)
        sequence = None
        for name in names:
            prior, method, settings = CONFIGURATIONS[name]
            for seed in range(seeds):
                cached = _cache_path(priors, name, clip, render_seed, seed)
                if cached.is_file():
                    record = json.loads(cached.read_text())
                else:
                    if sequence is None:  # rendered only when some run of it is not cached
                        (sequence,) = render_test_sequences(clip, views=1, seed=render_seed)
                    record = {"configuration": name, "clip": clip, **run_one(
                        priors[prior], sequence, {"method": method, "estimate": "own",
                                                  "likelihood": LIKELIHOOD},
                        seed, PARTICLES[method], "training", settings=dict(settings))}
                    cached.parent.mkdir(parents=True, exist_ok=True)
                    write_json_atomically(cached, record)
                runs.append(record)
                bar.set_postfix_str(f"{clip.split('/')[-1]} {name} seed {seed}: "
                                    f"{record['mean_error_torso']:.1%}")
                bar.update()
    bar.close()
    return runs


def per_take(runs: list[dict], name: str) -> dict:
    """clip -> the mean over seeds of configuration ``name``'s own error (torso lengths)."""
    errors = {}
    for run in runs:
        if run["configuration"] == name:
            errors.setdefault(run["clip"], []).append(run["mean_error_torso"])
    return {clip: float(np.mean(values)) for clip, values in errors.items()}


def ratio_over_takes(numerator: dict, denominator: dict, resamples: int = 10_000,
                     seed: int = 0) -> tuple[float, float, float]:
    """The ratio of two configurations' mean errors and its 95 % bootstrap interval over takes.

    Args:
        numerator: clip -> one configuration's error on that take (mean over seeds).
        denominator: clip -> the other's (the same takes).
        resamples: bootstrap resamples.
        seed: the bootstrap's random seed.

    Returns:
        ``(ratio, low, high)``: the mean over takes of ``numerator`` over that of
        ``denominator``, and the 2.5 and 97.5 percentiles of the same ratio when the takes are
        resampled with replacement, the same takes for both (paired).
    """
    if set(numerator) != set(denominator) or not numerator:
        raise ValueError("both configurations need runs of the same takes")
    clips = sorted(numerator)
    top = np.array([numerator[clip] for clip in clips])
    bottom = np.array([denominator[clip] for clip in clips])
    picks = np.random.default_rng(seed).integers(len(clips), size=(resamples, len(clips)))
    low, high = np.percentile(top[picks].mean(axis=1) / bottom[picks].mean(axis=1), [2.5, 97.5])
    return float(top.mean() / bottom.mean()), float(low), float(high)


def choose_sampler(runs: list[dict]) -> tuple[str, dict]:
    """The per-part sampler by :data:`CHOICE_RULE` from validation runs of both
    :data:`PER_PART` configurations; returns it and the evidence (paired difference over
    takes, its 95 % t-interval half-width, the takes)."""
    from papers.tian2005.tracking import t_interval

    one_step, partitioned = (per_take(runs, name) for name in PER_PART)
    if set(one_step) != set(partitioned) or not one_step:
        raise ValueError("both per-part samplers need runs of the same validation takes")
    differences = [partitioned[clip] - one_step[clip] for clip in sorted(one_step)]
    mean, half = float(np.mean(differences)), t_interval(differences)
    chosen = PER_PART[1] if mean + half < 0 else PER_PART[0]
    return chosen, {"rule": CHOICE_RULE, "takes": len(differences),
                    "difference_partitioned_minus_one_step": mean,
                    "difference_ci": half}


def summarise(runs: list[dict]) -> dict:
    """Per configuration: mean error (torso lengths) with its 95 % t-interval over runs,
    frames within 15 %, runs lost, the mean of each movement; and each other configuration's
    ratio to CONDENSATION with its bootstrap interval over takes (:func:`ratio_over_takes`)."""
    import statistics

    from papers.tian2005.tracking import t_interval

    rows = {}
    for name in CONFIGURATIONS:
        group = [run for run in runs if run["configuration"] == name]
        if not group:
            continue
        torso = [run["mean_error_torso"] for run in group]
        rows[name] = {"runs": len(group), "takes": len({run["clip"] for run in group}),
                      "error_torso": statistics.mean(torso),
                      "error_torso_ci": t_interval(torso),
                      "within_15": statistics.mean(run["fraction_within_15"] for run in group),
                      "lost": sum(run["failed"] for run in group),
                      "by_kind": {kind: statistics.mean(
                          run["mean_error_torso"] for run in group
                          if run["clip"].split("/")[1] == kind)
                          for kind in KINDS if any(run["clip"].split("/")[1] == kind
                                                   for run in group)}}
    if "condensation" in rows:
        baseline = per_take(runs, "condensation")
        for name in rows:
            if name != "condensation":
                ratio, low, high = ratio_over_takes(per_take(runs, name), baseline)
                rows[name]["ratio_to_condensation"] = {"ratio": ratio, "low": low, "high": high}
    return rows


def markdown_table(rows: dict) -> str:
    lines = ["| configuration | takes | runs | error / torso | ± 95 % | within 15 % | lost | "
             "/ CONDENSATION (95 %, over takes) |", "|---|---|---|---|---|---|---|---|"]
    for name, row in rows.items():
        ratio = row.get("ratio_to_condensation")
        lines.append(f"| {name} | {row['takes']} | {row['runs']} | {row['error_torso']:.1%} | "
                     f"{row['error_torso_ci']:.1%} | {row['within_15']:.0%} | "
                     f"{row['lost']}/{row['runs']} | " + (
                         f"{ratio['ratio']:.2f} ({ratio['low']:.2f}–{ratio['high']:.2f})"
                         if ratio else "–") + " |")
    return "\n".join(lines)


def movement_table(rows: dict) -> str:
    """Each configuration's mean error per movement (torso lengths)."""
    lines = ["| configuration | " + " | ".join(KINDS) + " |", "|---|" + "---|" * len(KINDS)]
    for name, row in rows.items():
        lines.append(f"| {name} | " + " | ".join(
            f"{row['by_kind'][kind]:.1%}" if kind in row["by_kind"] else "–"
            for kind in KINDS) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    from benchmarks._common import run_header
    from jaxtrack._files import write_json_atomically

    parser = argparse.ArgumentParser(prog="python -m papers.tian2005.hdm05",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", required=True, help="where to write the results (JSON)")
    parser.add_argument("--seeds", type=int, default=1, help="tracker seeds per tr take (1)")
    parser.add_argument("--validation-seeds", type=int, default=3,
                        help="tracker seeds per mm take (3)")
    parser.add_argument("--takes", choices=TAKES, default="all",
                        help="every take of each movement and actor (all), or the first one")
    parser.add_argument("--no-mht", action="store_true", help="leave MHT out of the test runs")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if args.seeds < 1 or args.validation_seeds < 1:
        parser.error("--seeds and --validation-seeds must be at least 1")
    out = Path(args.json)
    if out.suffix != ".json" or not out.parent.is_dir():
        parser.error(f"--json {out}: give a .json file in an existing folder")
    started = time.perf_counter()
    try:
        priors = train_priors()
        # the one choice made on mm: the per-part prior's sampler (CHOICE_RULE)
        validation_runs = track_split(priors, "validation", PER_PART, args.validation_seeds,
                                      args.takes)
        validation = summarise(validation_runs)
        chosen, choice = choose_sampler(validation_runs)
        names = ["latent, whole body", chosen, "condensation"] + ([] if args.no_mht
                                                                   else ["mht"])
        test_runs = track_split(priors, "test", names, args.seeds, args.takes)
    except (FileNotFoundError, ValueError) as error:
        print(f"python -m papers.tian2005.hdm05: {error}", file=sys.stderr)
        return 2
    test = summarise(test_runs)
    tables = {"validation": markdown_table(validation), "test": markdown_table(test),
              "validation_by_movement": movement_table(validation),
              "test_by_movement": movement_table(test)}
    write_json_atomically(out, {
        **run_header("papers.tian2005.hdm05", argv if argv is not None else sys.argv[1:],
                     started),
        "kinds": list(KINDS), "training_clips": list(arm_clips("training")),
        "validation_clips": list(takes_of("validation", args.takes)),
        "test_clips": list(takes_of("test", args.takes)), "takes": args.takes,
        "priors": {name: prior.description for name, prior in priors.items()},
        "particles": PARTICLES, "likelihood": LIKELIHOOD, "estimate": "own",
        "baseline_dynamics": "training", "seeds": args.seeds,
        "validation_seeds": args.validation_seeds, "chosen_per_part": chosen,
        "choice": choice, "ratio_interval": "bootstrap over takes (paired), 10 000 resamples",
        "validation": validation, "test": test, "tables": tables,
        "runs": validation_runs + test_runs})
    print(f"validation (mm):\n{tables['validation']}\n\n{tables['validation_by_movement']}\n\n"
          f"chosen: {chosen} (partitioned - one step: "
          f"{choice['difference_partitioned_minus_one_step']:+.1%} ± "
          f"{choice['difference_ci']:.1%})\n\ntest (tr):\n{tables['test']}\n\n"
          f"{tables['test_by_movement']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
