"""Ong & Gong (2002) reproduced: the tracker against its baselines on the test subject with the
library's defaults, the error surfaces of Fig. 10 and 12, and view selection against its oracle.

    python -m papers.ong2002 --json papers/ong2002/results/ong2002.json
    python -m papers.ong2002 --json OUT.json --clusters 10 20 40 70 100 --samples 10 20 50 100 300
    python -m papers.ong2002 --json OUT.json --full          # the paper's 10 × 14 grid (~1 h)
    python -m papers.ong2002 --json OUT.json --validation    # also re-choose P, Q, ω

The model is trained on the training subjects' gestures through the four Pose2Sim cameras
(``jaxtrack.experiments.linear_combination.train``, 20 clusters). Entries of the JSON:

- ``test``: the tracker with the library's defaults (eq. 9's P, Q and the step ω chosen on
  validation, ``DEFAULT_FITNESS``, ``DEFAULT_STEP``; the weighted-mean skeleton,
  ``DEFAULT_SKELETON_ESTIMATE``), its two baselines (the filter on the global PCA, the nearest
  training vector per frame) and two constant skeletons, on the test subject's two waves in
  every view (:func:`papers.ong2002.evaluation.test_rows`), and every row that beats the
  tracker, without and after a similarity alignment;
- ``validation`` (``--validation``): P, Q and ω chosen again on the validation subject
  (:func:`papers.ong2002.evaluation.choose_on_validation`) and whether they are the shipped ones;
- ``surface``: the mean 3-D skeleton error over clusters × samples per iteration on a training
  clip (Fig. 10) and on the test subject (novel motion, Fig. 12)
  (:func:`papers.ong2002.surface.surface`), with what each shows
  (:func:`papers.ong2002.surface.trends`) and a heat map per surface beside the JSON;
- ``view_selection``: every view-selection rule against the best view per frame (the oracle)
  and the worst (:mod:`papers.ong2002.view_selection`, whose own JSON is written beside).

The JSON is written after every stage (``"complete": false`` until the end).
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import time
from pathlib import Path

from papers.ong2002 import evaluation, surface

FIGURES = {"test_m": ("ong2002_fig12_novel_motion.png",
                      "Fig. 12, novel motion:\nthe test subject's two waves, 4 views"),
           "training_m": ("ong2002_fig10_training_motion.png",
                          "Fig. 10, training motion:\na training clip, 4 views")}
"""Surface key → (file name beside the JSON, title). Both are the best particle's skeleton, the
paper's estimate; the JSON also holds the weighted mean's (``*_mean_m``)."""


def _parse(argv):
    parser = argparse.ArgumentParser(prog="python -m papers.ong2002",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", required=True, type=Path,
                        help="where to write the results (JSON); the figures go beside it")
    parser.add_argument("--frames", type=int, default=60, help="frames per clip (30 fps; 60)")
    parser.add_argument("--clusters", type=int, nargs="+", default=[10, 40, 100],
                        help="the surface's cluster counts (default 10 40 100)")
    parser.add_argument("--samples", type=int, nargs="+", default=[20, 100, 300],
                        help="the surface's samples per iteration (default 20 100 300)")
    parser.add_argument("--full", action="store_true", help="the paper's grid: clusters "
                        "10, 20, …, 100 × samples 10, 20, …, 100, 150, …, 300")
    parser.add_argument("--validation", action="store_true",
                        help="also choose P, Q and ω again on the validation subject")
    parser.add_argument("--no-surface", action="store_true", help="leave out the surfaces")
    parser.add_argument("--no-view-selection", action="store_true",
                        help="leave out view selection")
    parser.add_argument("--replot", action="store_true",
                        help="only draw the heat maps again from the surface rows --json holds")
    parser.add_argument("--view-frames", type=int, default=90,
                        help="frames per clip for view selection (90, as its validation run)")
    args = parser.parse_args(argv)
    if args.frames < 2 or args.view_frames < 11:
        parser.error(f"--frames must be at least 2 and --view-frames at least 11 (view "
                     f"selection's ±5 frames), got {args.frames} and {args.view_frames}")
    if min(args.clusters) < 2 or min(args.samples) < 1:
        parser.error("--clusters must be at least 2 and --samples at least 1")
    if args.json.suffix != ".json":
        parser.error(f"--json {args.json}: the file name must end in .json")
    if not args.json.parent.is_dir():
        parser.error(f"--json {args.json}: folder {args.json.parent} does not exist; create it "
                     "first")
    if args.full:
        args.clusters, args.samples = list(surface.PAPER_CLUSTERS), list(surface.PAPER_SAMPLES)
    return args


def beats(rows: list[dict], tracker: dict) -> dict:
    """Every row whose mean error is below the tracker's, per score (``error_m``: in the
    camera's axes; ``aligned_m``: after a similarity alignment per frame), with the margin in
    millimetres."""
    out = {}
    for key in ("error_m", "aligned_m"):
        out[key] = [{"method": row["method"], "estimate": row["estimate"],
                     "below_tracker_mm": round(1e3 * (tracker[key] - row[key]), 1)}
                    for row in rows if row is not tracker and row[key] < tracker[key]]
    return out


def test_table(trained, frames: int) -> dict:
    """The test table with the library's defaults (module docstring, entry ``test``)."""
    from jaxtrack.experiments import linear_combination as lc

    render = dict(views=(0, 1, 2, 3), max_frames=frames, keep_observations=True, seed=7)
    test = [s for clip in lc.TEST_CLIPS for s in lc.render_hybrid_sequences(clip, **render)]
    steps = {"linear-combination": lc.DEFAULT_STEP, "global-pca": lc.DEFAULT_STEP}
    rows = evaluation.test_rows(trained, test, fitness=lc.DEFAULT_FITNESS, steps=steps)
    tracker = next(row for row in rows if row["method"] == "linear-combination"
                   and row["estimate"] == lc.DEFAULT_SKELETON_ESTIMATE)
    return {"settings": {"P": float(lc.DEFAULT_FITNESS.contour_tolerance),
                         "Q": float(lc.DEFAULT_FITNESS.hands_tolerance),
                         "step": lc.DEFAULT_STEP, "estimate": lc.DEFAULT_SKELETON_ESTIMATE,
                         "particles": 300, "iterations": 5, "views": [0, 1, 2, 3],
                         "frames": frames, "test_clips": list(lc.TEST_CLIPS)},
            "rows": rows, "tracker": tracker, "beats_tracker": beats(rows, tracker)}


def validation_choice(trained, frames: int) -> dict:
    """P, Q and ω chosen again on the validation subject, against the shipped values."""
    from jaxtrack.experiments import linear_combination as lc

    render = dict(views=(0, 1, 2, 3), max_frames=frames, keep_observations=True, seed=7)
    sequences = [s for clip in lc.VALIDATION_CLIPS
                 for s in lc.render_hybrid_sequences(clip, **render)]
    sweep, best, steps = evaluation.choose_on_validation(trained, sequences)
    shipped = {"P": float(lc.DEFAULT_FITNESS.contour_tolerance),
               "Q": float(lc.DEFAULT_FITNESS.hands_tolerance), "step": lc.DEFAULT_STEP}
    return {"sweep": sweep, "chosen": {**best, "steps": steps}, "shipped": shipped,
            "chosen_is_shipped": bool(best["P"] == shipped["P"] and best["Q"] == shipped["Q"]
                                      and steps["linear-combination"] == shipped["step"])}


def surfaces(args, constant_mm: float | None, on_rows) -> dict:
    """The Fig. 10 and 12 surfaces, their trends and heat maps (entry ``surface``)."""
    from jaxtrack.experiments import linear_combination as lc

    rows = surface.surface(args.clusters, args.samples, views=(0, 1, 2, 3), frames=args.frames,
                           fitness=lc.DEFAULT_FITNESS, step=lc.DEFAULT_STEP,
                           on_row=on_rows)
    return {"clusters": args.clusters, "samples": args.samples, "rows": rows,
            "training": surface.trends(rows, "training_m"),
            "novel": surface.trends(rows, "test_m"),
            "training_weighted_mean": surface.trends(rows, "training_mean_m"),
            "novel_weighted_mean": surface.trends(rows, "test_mean_m"),
            "figures": draw(rows, args.json.parent, constant_mm)}


def draw(rows: list[dict], folder: Path, constant_mm: float | None) -> dict:
    """The heat map of each surface of :data:`FIGURES` in ``folder``; returns key → file name."""
    return {key: surface.heat_map(rows, key, folder / name, title=title,
                                  reference=("the training skeletons' mean", constant_mm)
                                  if key == "test_m" and constant_mm is not None else None).name
            for key, (name, title) in FIGURES.items()}


def _constant_mm(test: dict) -> float:
    """The test error (mm) of the training skeletons' mean held constant."""
    return 1e3 * next(row for row in test["rows"]
                      if row["method"] == evaluation.TRAINING_CONSTANT)["error_m"]


def view_selection_summary(out: Path, frames: int) -> dict:
    """Run :mod:`papers.ong2002.view_selection` (its JSON at ``out``) and keep each rule's
    selected, oracle and worst errors per estimate and split."""
    from papers.ong2002 import view_selection

    if view_selection.main(["--out", str(out), "--frames", str(frames)]):
        raise SystemExit("view selection failed")
    record = json.loads(out.read_text())
    return {"json": out.name, "chosen_on_validation": record["chosen_on_validation"],
            "summaries": record["summaries"], "linear_bound": {
                estimate: {split: bound[split] for split in ("validation", "test")}
                | {"weights": bound["weights"]}
                for estimate, bound in record["linear_bound"].items()}}


def main(argv=None) -> int:
    args = _parse(argv)
    if args.replot:
        try:
            record = json.loads(args.json.read_text())
            rows = record["surface"]["rows"]
        except (OSError, ValueError, KeyError) as error:
            raise SystemExit(f"--replot: {args.json} holds no finished surface ({error}); run "
                             "without --replot first") from None
        print(draw(rows, args.json.parent, _constant_mm(record["test"])))
        return 0
    from jaxtrack._files import write_json_atomically
    from jaxtrack.experiments import linear_combination as lc

    started = time.perf_counter()
    record = {"command": "python -m papers.ong2002 " + " ".join(
                  sys.argv[1:] if argv is None else argv),
              "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d"),
              "complete": False}

    def write(**entries):
        record.update(entries, seconds=round(time.perf_counter() - started))
        write_json_atomically(args.json, record)

    from benchmarks._common import device_description

    record["device"] = device_description()
    trained = lc.train(list(lc.TRAIN_CLIPS), views=(0, 1, 2, 3), num_clusters=20)
    write(test=test_table(trained, args.frames))
    print(json.dumps(record["test"]["beats_tracker"]), flush=True)
    if args.validation:
        write(validation=validation_choice(trained, args.frames))
    if not args.no_surface:
        write(surface=surfaces(args, _constant_mm(record["test"]),
                               lambda rows: write(surface={"partial_rows": rows})))
    if not args.no_view_selection:
        write(view_selection=view_selection_summary(
            args.json.with_name(args.json.stem + "_view_selection.json"), args.view_frames))
    write(complete=True)
    print(f"wrote {args.json} in {record['seconds']} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
