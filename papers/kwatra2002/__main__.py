"""Kwatra, Bobick & Johnson (2002) in the paper's own setting: one actor, one fixed side camera.

    python -m papers.kwatra2002 --json papers/kwatra2002/results/kwatra2002.json

renders HDM05 actor bd through one side camera framed on the whole of their motion
(:mod:`papers.kwatra2002.setting`), trains the posture model on bd's other takes (and their
mirror images), tracks the held-out lie-down, squat and crouch takes with the mixed-state
filter and smoother (:mod:`jaxtrack.trackers.mixed_state`), and scores the instantaneous
(extended Ghost) and the integrated (smoothed) estimates as the paper's Table 1 does: mean
squared error per part at 640 × 480, hands and feet under the best left/right assignment per
frame, and the posture error. Writes the JSON and, beside it, the Fig. 2 and Fig. 4 plots.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from papers.kwatra2002 import setting

ESTIMATES = ("instantaneous", "filtered", "smoothed")
TARGETS = "smoothed MSE (all parts) <= 1/2 instantaneous; posture error <= 1/2 instantaneous; " \
          "head within 20 px in >= 95 % of frames"
CURVE_EPSILONS = tuple(range(0, 101, 2))


def _parse(argv):
    parser = argparse.ArgumentParser(prog="python -m papers.kwatra2002", description=__doc__.split(
        "\n\n")[0])
    parser.add_argument("--json", required=True, help="where to write the results (JSON); the "
                        "plots go beside it")
    parser.add_argument("--particles", type=int, default=500, help="particles (default 500)")
    parser.add_argument("--seeds", type=int, default=3, help="tracker seeds per test take "
                        "(default 3); every score pools them")
    parser.add_argument("--actor", default=setting.ACTOR, help="the actor (default bd)")
    parser.add_argument("--validation", action="store_true", help="also try the model "
                        "settings of setting.VALIDATION_GRID on the validation takes (entry "
                        "'validation')")
    parser.add_argument("--held-out", action="store_true", help="also part 2: train on actors "
                        "bd, bk, dg and test on actor tr (entry 'held_out'; held_out.SPLIT)")
    parser.add_argument("--skip-paper-setting", action="store_true", help="compute only the "
                        "entries asked for by --validation and --held-out; every other entry "
                        "of an existing --json file is kept as it is (each entry is dated)")
    args = parser.parse_args(argv)
    if args.particles < 1 or args.seeds < 1:
        parser.error("--particles and --seeds must be at least 1")
    out = Path(args.json)
    if out.suffix != ".json":
        parser.error(f"--json {out}: the file name must end in .json")
    if not out.parent.exists():
        parser.error(f"--json {out}: folder {out.parent} does not exist; create it first")
    if args.skip_paper_setting and not (args.validation or args.held_out):
        parser.error("--skip-paper-setting leaves nothing to compute: add --validation or "
                     "--held-out")
    return args


def _progress(iterable, **kwargs):
    from tqdm import tqdm

    return tqdm(iterable, file=sys.stderr, **kwargs)


def prepare(actor: str, held_out) -> tuple:
    """Load every take of ``actor``, fit the side camera on all of them, and train the posture
    model on the takes not in ``held_out`` (and their mirror images). Returns the posture
    model, its JSON-able description, the camera and the staged motions by take."""
    from jaxtrack.experiments.mixed_state import fit
    from jaxtrack.vision.histograms import FRAME_OK, silhouette_features

    takes = setting.actor_takes(actor)
    unknown = sorted(set(held_out) - {take.name for take in takes})
    if unknown:
        raise ValueError(f"takes {unknown} are not takes of actor {actor}")
    motions = {take.name: setting.load_take(take) for take in
               _progress(takes, desc="loading takes")}
    camera = setting.side_camera(list(motions.values()))
    training = [name for name in motions if name not in held_out]
    features, labels, training_iou = [], [], []
    for index, name in enumerate(_progress(training, desc="rendering training takes")):
        rendered = setting.render_take(motions[name], camera, name, seed=index)
        training_iou.append(rendered.silhouette_iou)
        for view in (rendered, setting.mirrored(rendered)):
            values, status = silhouette_features(view.masks)
            features.append(values[status == FRAME_OK])
            labels.append(view.labels[status == FRAME_OK])
    postures, description = fit(features, labels, actor=actor, training_takes=training,
                                mirrored=True, background=setting.BACKGROUND,
                                silhouette_iou={name: round(value, 3) for name, value in
                                                zip(training, training_iou, strict=True)})
    return postures, description, camera, motions


def render_tests(motions: dict, camera, names) -> list:
    """The held-out takes through the camera (seeds 1000, 1001, … apart from training's)."""
    return [setting.render_take(motions[name], camera, name, seed=1000 + index)
            for index, name in enumerate(names)]


def hypothesis_floor(rendered: list, observations: list) -> dict:
    """What any choice among the hypotheses can reach: the mean squared error (all parts, px²)
    of the true posture's hypotheses in every frame, and of the best posture's per frame."""
    from jaxtrack.experiments.mixed_state import part_squared_errors

    true_posture, best_posture = [], []
    for take, frames in zip(rendered, observations, strict=True):
        hypotheses = np.asarray(frames.hypotheses)
        steps = np.arange(len(hypotheses))
        true_posture.append(part_squared_errors(hypotheses[steps, take.labels], take.parts))
        per_posture = np.stack([part_squared_errors(hypotheses[:, q], take.parts).mean(axis=1)
                                for q in range(hypotheses.shape[1])], axis=1)
        best_posture.append(per_posture.min(axis=1))
    true_posture = np.concatenate(true_posture)
    return {"true_posture": {name: float(true_posture[:, idx].mean()) for name, idx in (
                ("head", [0]), ("hands", [1, 2]), ("feet", [3, 4]), ("all", slice(None)))},
            "best_posture_per_frame_all": float(np.concatenate(best_posture).mean())}


def evaluate(model, rendered: list, num_particles: int, seeds: int) -> tuple[dict, dict]:
    """Track every rendered take with ``seeds`` tracker seeds and score the instantaneous,
    filtered and smoothed estimates, pooled over takes and seeds (Table 1), per take, and as
    fraction-within-ε curves. Returns the JSON-able results and the arrays the plots need."""
    import jax.random as jr

    from jaxtrack.experiments.mixed_state import part_squared_errors, score, track
    from jaxtrack.trackers.mixed_state import observations_from_silhouettes
    from jaxtrack.vision.histograms import FRAME_OK

    per_take, pooled, arrays = {}, {kind: [] for kind in ESTIMATES}, {}
    truth_parts, truth_labels, valid, observations = [], [], [], []
    for take in _progress(rendered, desc="tracking"):
        frames = observations_from_silhouettes(take.masks)
        observations.append(frames)
        runs = [track(jr.PRNGKey(seed), model, frames, num_particles) for seed in range(seeds)]
        ok = runs[0]["status"] == FRAME_OK
        per_take[take.name] = {kind: [score(run[kind]["parts"], run[kind]["posture"],
                                            take.parts, take.labels, ok) for run in runs]
                               for kind in ESTIMATES}
        per_take[take.name].update(frames=int(len(ok)), silhouette_iou=take.silhouette_iou,
                                   true_postures=np.bincount(take.labels, minlength=5).tolist())
        for run in runs:
            for kind in ESTIMATES:
                pooled[kind].append((run[kind]["parts"], run[kind]["posture"]))
            truth_parts.append(take.parts)
            truth_labels.append(take.labels)
            valid.append(ok)
        arrays[take.name] = {"truth": take.parts, "labels": take.labels,
                             **{kind: runs[0][kind]["parts"] for kind in ESTIMATES},
                             **{f"{kind}_posture": runs[0][kind]["posture"]
                                for kind in ESTIMATES}}
    truth_parts, truth_labels = np.concatenate(truth_parts), np.concatenate(truth_labels)
    valid = np.concatenate(valid)
    summary, squared = {}, {}
    for kind in ESTIMATES:
        parts = np.concatenate([p for p, _ in pooled[kind]])
        posture = np.concatenate([q for _, q in pooled[kind]])
        overall = score(parts, posture, truth_parts, truth_labels, valid)
        squared[kind] = part_squared_errors(parts, truth_parts)[valid]
        summary[kind] = {"mse_all": overall["mse"]["all"],
                         "posture_error": overall["posture_error"], "mse": overall["mse"],
                         "head_within_20px": overall["within"]["head"]["20"],
                         "within": overall["within"], "frames": overall["frames"]}
    instant, smoothed = summary["instantaneous"], summary["smoothed"]
    summary["targets"] = {
        "mse_halved": smoothed["mse_all"] <= 0.5 * instant["mse_all"],
        "posture_error_halved": smoothed["posture_error"] <= 0.5 * instant["posture_error"],
        "head_within_20px_95": smoothed["head_within_20px"] >= 0.95,
        "mse_ratio_smoothed_over_instantaneous": smoothed["mse_all"] / instant["mse_all"],
        "posture_error_ratio": (smoothed["posture_error"] / instant["posture_error"]
                                if instant["posture_error"] > 0 else None),
    }
    summary["hypothesis_floor"] = hypothesis_floor(rendered, observations)
    summary["per_take"] = per_take
    curves = {kind: {part: [float(np.mean(np.sqrt(squared[kind][:, idx]) <= eps))
                            for eps in CURVE_EPSILONS]
                     for part, idx in (("head", [0]), ("hands", [1, 2]), ("feet", [3, 4]))}
              for kind in ESTIMATES}
    return summary, {"takes": arrays, "curves": curves}


def paper_setting(actor: str = setting.ACTOR, num_particles: int = 500, seeds: int = 3,
                  model_options: dict | None = None) -> tuple[dict, dict]:
    """Train on every take of ``actor`` but :data:`setting.TEST_TAKES`, track and score those
    (module docstring). Returns the JSON-able results and the arrays the plots need."""
    from jaxtrack.trackers.mixed_state import MixedStateModel

    postures, description, camera, motions = prepare(actor, setting.TEST_TAKES)
    options = dict(setting.MODEL_OPTIONS if model_options is None else model_options)
    model = MixedStateModel(postures, **options)
    results, arrays = evaluate(model, render_tests(motions, camera, setting.TEST_TAKES),
                               num_particles, seeds)
    results.update(
        target_text=TARGETS, posture_model=description,
        camera={"focal_length": np.asarray(camera.focal_length).tolist(),
                "principal_point": np.asarray(camera.principal_point).tolist(),
                "image_size": list(camera.image_size)},
        settings={"actor": actor, "test_takes": list(setting.TEST_TAKES),
                  "particles": num_particles, "seeds": seeds, "fps": setting.FPS,
                  "model": model.options()})
    return results, arrays


def validation(actor: str = setting.ACTOR, num_particles: int = 500, seeds: int = 1) -> dict:
    """The model settings of :data:`setting.VALIDATION_GRID` on the validation takes
    (:data:`setting.VALIDATION_TAKES`), the posture model trained without them and without the
    test takes: smoothed and instantaneous MSE and posture error per setting."""
    from jaxtrack.trackers.mixed_state import MixedStateModel

    held_out = setting.TEST_TAKES + setting.VALIDATION_TAKES
    postures, _, camera, motions = prepare(actor, held_out)
    rendered = render_tests(motions, camera, setting.VALIDATION_TAKES)
    rows = []
    for options in setting.VALIDATION_GRID:
        results, _ = evaluate(MixedStateModel(postures, **options), rendered, num_particles,
                              seeds)
        rows.append({"options": options, **{kind: {
            "mse_all": results[kind]["mse_all"], "posture_error": results[kind]["posture_error"],
            "head_within_20px": results[kind]["head_within_20px"]}
            for kind in ("instantaneous", "smoothed")}})
    return {"takes": list(setting.VALIDATION_TAKES), "particles": num_particles,
            "seeds": seeds, "rows": rows}


def plot(arrays: dict, folder: Path, stem: str) -> list[Path]:
    """Fig. 2 (a part's x over time: instantaneous, integrated, truth) and Fig. 4 (fraction of
    frames within ε, per part) as PNGs in ``folder``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    takes = arrays["takes"]
    figure, axes = plt.subplots(len(takes), 2, figsize=(11, 3.2 * len(takes)), squeeze=False)
    for row, (name, data) in enumerate(takes.items()):
        frames = np.arange(len(data["truth"]))
        for column, (part, slot) in enumerate((("head", 0), ("hand", 1))):
            axis = axes[row, column]
            truth = data["truth"][:, slot, 0]
            axis.plot(frames, truth, "k-", lw=2, label="truth")
            for kind, style in (("instantaneous", "r."), ("smoothed", "b-")):
                estimate = data[kind][:, slot, 0]
                if slot == 1:  # the estimate's hand nearer this true hand, per frame
                    other = data[kind][:, 2, 0]
                    swap = np.abs(other - truth) < np.abs(estimate - truth)
                    estimate = np.where(swap, other, estimate)
                axis.plot(frames, estimate, style, ms=3, lw=1,
                          label="integrated" if kind == "smoothed" else kind)
            axis.set_title(f"{name}: {part} x (px)")
            axis.set_xlabel("frame (30 fps)")
            if row == 0 and column == 0:
                axis.legend(fontsize=8)
    figure.tight_layout()
    path = folder / f"{stem}_fig2_x_over_time.png"
    figure.savefig(path, dpi=70)
    plt.close(figure)
    written.append(path)
    figure, axes = plt.subplots(1, 3, figsize=(12, 3.4))
    for axis, part in zip(axes, ("head", "hands", "feet"), strict=True):
        for kind, style in (("instantaneous", "r--"), ("filtered", "g:"), ("smoothed", "b-")):
            axis.plot(CURVE_EPSILONS, arrays["curves"][kind][part], style,
                      label="integrated" if kind == "smoothed" else kind)
        axis.set_title(f"{part}: fraction of frames within ε")
        axis.set_xlabel("ε (px, 640 × 480)")
        axis.set_ylim(0, 1.02)
        axis.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    figure.tight_layout()
    path = folder / f"{stem}_fig4_within_epsilon.png"
    figure.savefig(path, dpi=70)
    plt.close(figure)
    written.append(path)
    return written


def _write_json(path: Path, contents: dict) -> None:
    """Write atomically: a half-written file never replaces a good one."""
    handle, temporary = tempfile.mkstemp(dir=path.parent, suffix=".json.tmp")
    try:
        with os.fdopen(handle, "w") as file:
            json.dump(contents, file, indent=1)
        os.chmod(temporary, 0o644)  # mkstemp's 0600 would hide the results from other users
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def _existing(path: Path) -> dict:
    """The entries of an earlier run's JSON at ``path`` (none if there is no such file)."""
    if not path.is_file():
        return {}
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as error:
        raise ValueError(f"--json {path} is not a JSON file ({error}); move it away or "
                         f"drop --skip-paper-setting") from None


def main(argv=None) -> int:
    import datetime

    args = _parse(argv)
    out = Path(args.json)
    stamp = {"date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d"),
             "command": "python -m papers.kwatra2002 " + " ".join(
                 sys.argv[1:] if argv is None else argv)}
    results = chosen = other_people = None
    try:
        contents = _existing(out) if args.skip_paper_setting else {}
        if not args.skip_paper_setting:
            results, arrays = paper_setting(args.actor, args.particles, args.seeds)
        chosen = validation(args.actor, args.particles) if args.validation else None
        if args.held_out:
            from papers.kwatra2002.held_out import held_out

            other_people = held_out(args.particles)
    except (FileNotFoundError, ValueError) as error:
        print(f"python -m papers.kwatra2002: {error}", file=sys.stderr)
        return 2
    for name, entry in (("paper_setting", results), ("validation", chosen),
                        ("held_out", other_people)):
        if entry is not None:
            contents[name] = {**entry, "run": stamp}
    if results is not None:
        plots = plot(arrays, out.parent, out.stem)
        contents["plots"] = [p.name for p in plots]
    _write_json(out, contents)
    if results is None:
        print(json.dumps({name: contents[name]["run"] for name in contents
                          if isinstance(contents[name], dict) and "run" in contents[name]},
                         indent=1))
        return 0
    summary = {kind: {"mse_all": round(results[kind]["mse_all"]),
                      "posture_error": round(results[kind]["posture_error"], 3),
                      "head_within_20px": round(results[kind]["head_within_20px"], 3)}
               for kind in ESTIMATES}
    print(json.dumps({"paper_setting": summary, "targets": results["targets"]}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
