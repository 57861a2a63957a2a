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
filters' own estimates are scored (no refinement), the latent tracker with 200 particles and
CONDENSATION with 1 000 and its AR(2) learned from the same training poses.

The one setting chosen is the per-part prior's sampler (one step on the whole latent point, or
partitioned sampling): on mm's takes, by the latent tracker's own mean error. Then tr's takes
are tracked and only reported.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

KINDS = ("grabHighR", "rotateArmsBothBackward1Reps", "elbowToKnee1RepsLelbowStart")
PARTICLES = {"latent": 200, "condensation": 1000}
LIKELIHOOD = "limbs+edges"
CONFIGURATIONS = {
    "latent, whole body": ("whole", "latent", {}),
    "latent, per part": ("parts", "latent", {}),
    "latent, per part, partitioned": ("parts", "latent", {"partitioned": 1.0}),
    "condensation": ("whole", "condensation", {}),
}
"""name -> (prior, method, ``tracking.run_one`` settings). CONDENSATION learns from the same
training poses whichever prior it is given; it is run with the whole-body one."""
PER_PART = ("latent, per part", "latent, per part, partitioned")


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


def track_split(priors: dict, split: str, names, seeds: int, takes_per_kind: int | None = None,
                progress: bool = True) -> list[dict]:
    """Every configuration of ``names`` on the arm takes of ``split``'s actors (frontal view;
    :func:`arm_clips`), ``seeds`` tracker seeds each: ``tracking.run_one``'s records plus
    ``configuration``."""
    from tqdm import tqdm

    from jaxtrack.experiments import render_test_sequences
    from papers.tian2005.tracking import run_one

    runs = []
    for index, clip in enumerate(tqdm(arm_clips(split, takes_per_kind), desc=f"{split} takes",
                                      disable=not progress)):
        (sequence,) = render_test_sequences(clip, views=1, seed=index)
        for name in names:
            prior, method, settings = CONFIGURATIONS[name]
            for seed in range(seeds):
                record = run_one(priors[prior], sequence, {"method": method, "estimate": "own",
                                                           "likelihood": LIKELIHOOD},
                                 seed, PARTICLES[method], "training", settings=dict(settings))
                runs.append({"configuration": name, "clip": clip, **record})
    return runs


def summarise(runs: list[dict]) -> dict:
    """Per configuration: mean error (torso lengths) with its 95 % t-interval over runs,
    frames within 15 %, runs lost; and each latent configuration's ratio to CONDENSATION
    with its bootstrap interval over seeds (:func:`papers.tian2005.protocols.ratio_interval`)."""
    import statistics

    from papers.tian2005.protocols import ratio_interval
    from papers.tian2005.tracking import t_interval

    rows, by_sequence = {}, {}
    for name in CONFIGURATIONS:
        group = [run for run in runs if run["configuration"] == name]
        if not group:
            continue
        torso = [run["mean_error_torso"] for run in group]
        rows[name] = {"runs": len(group), "error_torso": statistics.mean(torso),
                      "error_torso_ci": t_interval(torso),
                      "within_15": statistics.mean(run["fraction_within_15"] for run in group),
                      "lost": sum(run["failed"] for run in group)}
        by_sequence[name] = {}
        for run in group:
            by_sequence[name].setdefault(run["sequence"], []).append(run["mean_error_torso"])
    if "condensation" in by_sequence:
        for name in by_sequence:
            if name != "condensation":
                ratio, low, high = ratio_interval(by_sequence[name], by_sequence["condensation"])
                rows[name]["ratio_to_condensation"] = {"ratio": ratio, "low": low, "high": high}
    return rows


def markdown_table(rows: dict) -> str:
    lines = ["| configuration | runs | error / torso | ± 95 % | within 15 % | lost | "
             "/ CONDENSATION (95 %) |", "|---|---|---|---|---|---|---|"]
    for name, row in rows.items():
        ratio = row.get("ratio_to_condensation")
        lines.append(f"| {name} | {row['runs']} | {row['error_torso']:.1%} | "
                     f"{row['error_torso_ci']:.1%} | {row['within_15']:.0%} | "
                     f"{row['lost']}/{row['runs']} | " + (
                         f"{ratio['ratio']:.2f} ({ratio['low']:.2f}–{ratio['high']:.2f})"
                         if ratio else "–") + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    from benchmarks._common import run_header
    from jaxtrack._files import write_json_atomically

    parser = argparse.ArgumentParser(prog="python -m papers.tian2005.hdm05",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", required=True, help="where to write the results (JSON)")
    parser.add_argument("--seeds", type=int, default=2, help="tracker seeds per tr take (2)")
    parser.add_argument("--validation-seeds", type=int, default=1,
                        help="tracker seeds per mm take (1)")
    parser.add_argument("--takes-per-kind", type=int, default=1,
                        help="tracked takes of each movement (the first ones; 1), or 0 for all")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if args.seeds < 2 or args.validation_seeds < 1 or args.takes_per_kind < 0:
        parser.error("--seeds must be at least 2 (an interval over seeds) and "
                     "--validation-seeds at least 1, --takes-per-kind at least 0")
    out = Path(args.json)
    if out.suffix != ".json" or not out.parent.is_dir():
        parser.error(f"--json {out}: give a .json file in an existing folder")
    started = time.perf_counter()
    try:
        priors = train_priors()
        takes = args.takes_per_kind or None
        # the one choice made on mm: the per-part prior's sampler
        validation_runs = track_split(priors, "validation", PER_PART, args.validation_seeds,
                                      takes)
        validation = summarise(validation_runs)
        chosen = min(PER_PART, key=lambda name: validation[name]["error_torso"])
        names = ["latent, whole body", chosen, "condensation"]
        test_runs = track_split(priors, "test", names, args.seeds, takes)
    except (FileNotFoundError, ValueError) as error:
        print(f"python -m papers.tian2005.hdm05: {error}", file=sys.stderr)
        return 2
    test = summarise(test_runs)
    tables = {"validation": markdown_table(validation), "test": markdown_table(test)}
    write_json_atomically(out, {
        **run_header("papers.tian2005.hdm05", argv if argv is not None else sys.argv[1:],
                     started),
        "kinds": list(KINDS), "training_clips": list(arm_clips("training")),
        "validation_clips": list(arm_clips("validation", takes)),
        "test_clips": list(arm_clips("test", takes)), "takes_per_kind": takes,
        "priors": {name: prior.description for name, prior in priors.items()},
        "particles": PARTICLES, "likelihood": LIKELIHOOD, "estimate": "own",
        "baseline_dynamics": "training", "seeds": args.seeds,
        "validation_seeds": args.validation_seeds, "chosen_per_part": chosen,
        "validation": validation, "test": test, "tables": tables,
        "runs": validation_runs + test_runs})
    print("validation (mm):\n" + tables["validation"] + f"\n\nchosen: {chosen}\n\ntest (tr):\n"
          + tables["test"])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
