"""The mixed-state tracker's settings chosen on the validation person (HDM05 actor mm) by a
reduced search fixed before any run, then the test clips scored once with them beside the
library's settings.

    python -m papers.kwatra2002.mm_selection validation   # the search (JSON row by row)
    python -m papers.kwatra2002.mm_selection test         # the test clips, once
    python -m papers.kwatra2002.mm_selection summary      # the README's tables from the JSON

Without ``--cache`` the library's posture model is trained first (the training clips
rendered from five azimuths) and cached in ``results/``, as the evaluation does.

The full grid of ``python -m papers.kwatra2002.mixed_state_evaluation`` (every posture model ×
δ × re-detection × switch rule on all validation clips from five azimuths) takes over an hour
on the project's 2-core machine. This is the reduced search; its rule was written down, here,
before its first run (2026-11-29):

- **Validation**: actor mm's three clips of ``experiments.mixed_state.VALIDATION_CLIPS``
  (lie-down 015, squat 037, crouch 019), rendered exactly as the evaluation renders them
  (:data:`SEED` 1, the clip's index in ``VALIDATION_CLIPS``), both side views (±90°, the
  paper's camera, as the evaluation's held-out run of 2026-11-29), 150 frames at most, clutter
  background, 640 × 480. The posture model is the library's (``mixed_state_evaluation``'s
  ``default_spec``: one Gaussian per posture, ridge 0.2, the training clips' level views).
- **Measure**: the smoothed estimate's mean squared error over all parts, all frames of the six
  sequences pooled (px²). The posture error is recorded, not used.
- **Monte Carlo error**: every setting is run with the same filter keys :data:`KEYS` and
  scored by the mean of their MSEs. Value ``a`` beats value ``b`` when the mean of the paired
  differences (key by key) is below ``-2 sd / √K``, ``sd`` their sample standard deviation
  over the K keys (:func:`beats`); otherwise they are tied.
- **Coordinate search**, one pass in the order of :data:`COORDINATES`, each coordinate's
  values tried with the others held at their current choice: the transition smoothing
  (pseudocount α of T), the part proposal, the part likelihood's cutoff δ, the scale of its
  standard deviations (R = diag(scale σ_i)²), the particles. At each coordinate, the values
  that the lowest-mean value does not beat are tied with it; if the current value is among
  them it stays, else the cheapest of them is taken (:data:`COST`; equal cost: the lowest
  mean). k is not searched: it multiplies every particle's likelihood by the same constant
  (eq. 4), so it changes no weight.
- **Time**: a coordinate not begun :data:`BUDGET_SECONDS` after the search began, or named
  by ``--skip``, is not searched (its value stays the library's); the JSON says which.
- **History of this rule**: the first version (committed before any run) ran every setting
  but the start with key 1 only, and called single runs tied within ``2 √2 s``, ``s`` the
  start's standard deviation over keys 1–3. Those three runs (13 922, 11 810 and
  15 057 px²) made ``2 √2 s`` about 4 700 px², a third of the MSE, so the search was stopped
  before any other setting ran, and the rule above (five keys, paired differences) replaced it.

The test stage then scores ``experiments.mixed_state.TEST_CLIPS`` (CMU 139_16 and 131_01,
HDM05 actor tr's lie-down, squat and crouch) from both side views, 150 frames, with the
library's settings and with the chosen ones on the same rendering, filter keys 1–3 pooled
(key 1 alone is the evaluation's run with ``--seed 1``), with 95 % bootstrap intervals over
clips (all views and keys of a clip drawn together: ``mixed_state_evaluation.clip_intervals``).
Nothing is chosen on them.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks._common import device_description, write_json

RESULTS = Path(__file__).parent / "results"
OUT = RESULTS / "mm_selection.json"
SEED = 1
FRAMES = 150
AZIMUTHS_DEGREES = (90.0, -90.0)
START = {"pseudocount": 0.5, "part_proposal": "dynamics", "part_cutoff": 25.0,
         "part_scale": 1.0, "particles": 500}
"""The library's settings (2026-11-29): the search starts here."""
COORDINATES = (("pseudocount", (0.5, 5.0, 25.0)),
               ("part_proposal", ("dynamics", "posterior")),
               ("part_cutoff", (9.0, 25.0, 100.0)),
               ("part_scale", (1.0, 2.0)),
               ("particles", (250, 500, 1000)))
"""The values tried per coordinate, in the order they are searched."""
COST = {"part_proposal": {"dynamics": 0, "posterior": 1},
        "particles": {250: 0, 500: 1, 1000: 2}}
"""Which value of a coordinate is cheaper to run (coordinates not named cost the same)."""
KEYS = (1, 2, 3, 4, 5)
"""The filter keys every setting is run with."""
BUDGET_SECONDS = 3000.0
"""The search's time (the project's 2-core machine is shared)."""


def beats(a, b) -> bool:
    """Whether per-key MSEs ``a`` are lower than ``b`` (the same keys) beyond Monte Carlo
    error: mean(a − b) < −2 sd(a − b) / √K."""
    difference = np.asarray(a, float) - np.asarray(b, float)
    spread = np.std(difference, ddof=1) / np.sqrt(difference.size)
    return bool(difference.mean() < -2.0 * spread)


def choose(values: dict, current, coordinate: str):
    """The value a coordinate takes (module docstring's rule): ``values`` maps each value
    tried to its per-key MSEs."""
    best = min(values, key=lambda value: np.mean(values[value]))
    tied = [value for value in values if not beats(values[best], values[value])]
    if current in tied:
        return current
    cost = COST.get(coordinate, {})
    return min(tied, key=lambda value: (cost.get(value, 0), np.mean(values[value])))


def key_of(settings: dict, filter_key: int) -> str:
    return json.dumps({**settings, "filter_key": filter_key}, sort_keys=True)


def posture_model(pseudocount: float):
    """The library's posture model (cached by ``mixed_state_evaluation.trained_models`` in
    ``--cache``) with its transition smoothing set to ``pseudocount`` (:func:`with_pseudocount`)."""
    from jaxtrack.priors.postures import load_posture_model
    from papers.kwatra2002.mixed_state_evaluation import (
        default_spec,
        model_path,
        trained_models,
    )

    spec = default_spec()
    model = trained_models(CACHE, [spec])[spec]
    return with_pseudocount(model, load_posture_model(model_path(CACHE, spec)).description,
                            pseudocount)


def with_pseudocount(model, description: dict, pseudocount: float):
    """``model`` with T and the first-frame prior re-estimated as ``fit_posture_model`` would
    with pseudocount α = ``pseudocount``: T = (n_ij + α) / Σ_j (n_ij + α), from the transition
    counts n_ij of its ``description`` (``experiments.mixed_state.fit``'s), and
    π = (m + α) / Σ (m + α), the first labels' counts m recovered from the fitted prior."""
    import equinox as eqx
    import jax.numpy as jnp

    fitted = float(description["pseudocount"])
    if pseudocount == fitted:
        return model
    if not (np.isfinite(pseudocount) and pseudocount >= 0):
        raise ValueError(f"pseudocount must be a non-negative number, got {pseudocount}")
    counts = np.asarray(description["transition_counts"], float) + pseudocount
    transition = counts / counts.sum(axis=1, keepdims=True)
    # the fitted prior is (m + a) / (N + 5 a) over N labelled sequences
    initial = np.exp(np.asarray(model.log_initial, float))
    first = np.round(np.clip(initial * (_sequences(description) + len(initial) * fitted)
                             - fitted, 0.0, None))
    initial = (first + pseudocount + 1e-12) / (first + pseudocount + 1e-12).sum()
    return eqx.tree_at(lambda m: (m.log_transition, m.log_initial), model,
                       (jnp.asarray(np.log(transition)), jnp.asarray(np.log(initial))))


def _sequences(description: dict) -> int:
    """How many labelled sequences the posture model was fitted on (clips × views ×
    backgrounds), or ``description["sequences"]`` where it says."""
    if "sequences" in description:
        return int(description["sequences"])
    return (len(description["clips"]) * (len(description["azimuths"])
                                         + len(description.get("pose2sim_cameras", [])))
            * len(description["backgrounds"]))


def tracker_options(settings: dict) -> dict:
    """``experiments.mixed_state.evaluate``'s model keywords for ``settings``."""
    return {"part_proposal": settings["part_proposal"], "part_cutoff": settings["part_cutoff"],
            "part_scale": settings["part_scale"]}


def run(settings: dict, sequences, clips, filter_key: int) -> dict:
    """Track ``sequences`` with ``settings`` and filter key ``filter_key``; scores and time."""
    from jaxtrack.experiments import mixed_state as ms

    begin = time.perf_counter()
    result = ms.evaluate(posture_model(settings["pseudocount"]), clips,
                         num_particles=settings["particles"], seed=filter_key,
                         sequences=sequences, **tracker_options(settings))
    seconds = time.perf_counter() - begin
    return {"result": result, "seconds": seconds}


def _row(settings: dict, filter_key: int, outcome: dict) -> dict:
    overall = outcome["result"]["overall"]
    return {"settings": settings, "filter_key": filter_key, "seconds": outcome["seconds"],
            **{kind: {"mse_all": overall[kind]["mse"]["all"],
                      "mse": overall[kind]["mse"],
                      "posture_error": overall[kind]["posture_error"],
                      "head_within_20px": overall[kind]["within"]["head"]["20"]}
               for kind in ("instantaneous", "filtered", "smoothed")}}


def render(clips_all, clips) -> list:
    """``clips`` (a subset of ``clips_all``) rendered exactly as ``render_sequences`` renders
    ``clips_all`` (the same per-clip seeds), both side views, clutter."""
    from jaxtrack.experiments import mixed_state as ms

    azimuths = [float(np.radians(value)) for value in AZIMUTHS_DEGREES]
    sequences = []
    for clip in clips:
        index = clips_all.index(clip)
        for view, azimuth in enumerate(azimuths):
            sequences.append(ms.render_posture_sequence(
                clip, azimuth, image_size=(640, 480), background="clutter",
                seed=SEED + 97 * index + view, max_frames=FRAMES))
    return sequences


def validation(out: Path, skip=()) -> dict:
    """The search (module docstring); writes ``out`` after every run and resumes from it.
    ``skip``: coordinates not searched (their values stay the library's), as for time."""
    from jaxtrack.experiments import mixed_state as ms

    clips = [clip for clip in ms.VALIDATION_CLIPS if "HDM_mm_" in clip]
    state = json.loads(out.read_text()) if out.is_file() else {}
    rows = {key_of(row["settings"], row["filter_key"]): row for row in state.get("rows", [])}
    rendered = []  # the clips are rendered once, when a setting is first run
    payload = {"command": "python -m papers.kwatra2002.mm_selection validation",
               "device": device_description(), "clips": clips,
               "azimuths_degrees": list(AZIMUTHS_DEGREES), "frames": FRAMES,
               "render_seed": SEED, "render_seconds": state.get("render_seconds"),
               "start": START,
               "coordinates": [[name, list(values)] for name, values in COORDINATES],
               "rule": __doc__.split("- **Validation**")[1].split("The test stage")[0].strip()}

    def measured(settings: dict, filter_key: int) -> dict:
        name = key_of(settings, filter_key)
        if name not in rows:
            if not rendered:
                begin = time.perf_counter()
                rendered.extend(render(list(ms.VALIDATION_CLIPS), clips))
                payload["render_seconds"] = time.perf_counter() - begin
            rows[name] = _row(settings, filter_key, run(settings, rendered, clips, filter_key))
            print(f"{settings} key {filter_key}: smoothed MSE all "
                  f"{rows[name]['smoothed']['mse_all']:.1f}, posture error "
                  f"{100 * rows[name]['smoothed']['posture_error']:.1f} %, "
                  f"{rows[name]['seconds']:.0f} s", flush=True)
            write_json(out, {**payload, "rows": list(rows.values())})
        return rows[name]

    began = time.perf_counter()
    current, steps, skipped = dict(START), [], []
    for name, values in COORDINATES:
        if name in skip or time.perf_counter() - began > BUDGET_SECONDS:
            skipped.append(name)
            continue
        tried = {value: [measured({**current, name: value}, key)["smoothed"]["mse_all"]
                         for key in KEYS] for value in values}
        picked = choose(tried, current[name], name)
        steps.append({"coordinate": name, "tried": [[value, mses] for value, mses in tried.items()],
                      "means": [[value, float(np.mean(mses))] for value, mses in tried.items()],
                      "was": current[name], "chosen": picked})
        current[name] = picked
        print(f"{name}: " + ", ".join(f"{value}: {np.mean(mses):.1f}" for value, mses in
                                      tried.items()) + f" -> {picked}", flush=True)
    payload.update(keys=list(KEYS), skipped_coordinates=skipped, steps=steps, chosen=current,
                   search_seconds=time.perf_counter() - began, rows=list(rows.values()))
    write_json(out, payload)
    return payload


TEST_KEYS = (1, 2, 3)
"""The filter keys of the test stage: key 1 alone is the evaluation's own run (its
``--seed 1``); the three pooled are the scores reported."""


def pooled_scores(sequences: dict) -> dict:
    """Frame-weighted means over ``sequences`` (``evaluate``'s per-sequence scores) of the MSE
    over all parts, the posture error and the head's fraction within 20 px, per estimate."""
    out = {}
    for kind in ("instantaneous", "filtered", "smoothed"):
        frames = np.array([scores[kind]["frames"] for scores in sequences.values()], float)
        weights = frames / frames.sum()
        out[kind] = {
            "mse_all": float(np.dot(weights, [s[kind]["mse"]["all"] for s in sequences.values()])),
            "posture_error": float(np.dot(weights, [s[kind]["posture_error"]
                                                    for s in sequences.values()])),
            "head_within_20px": float(np.dot(weights, [s[kind]["within"]["head"]["20"]
                                                       for s in sequences.values()])),
            "frames": int(frames.sum())}
    return out


def test(out: Path, validation_file: Path) -> dict:
    """The test clips with the library's and the chosen settings (module docstring), filter
    keys :data:`TEST_KEYS`."""
    from jaxtrack.experiments import mixed_state as ms
    from papers.kwatra2002.mixed_state_evaluation import clip_intervals

    chosen = json.loads(validation_file.read_text()).get("chosen")
    if chosen is None:
        raise ValueError(f"{validation_file} has no chosen settings; run the validation stage "
                         "to its end first")
    clips = list(ms.TEST_CLIPS)
    earlier = json.loads(out.read_text()) if out.is_file() else {}
    sequences = None
    entries = {}
    for label, settings in (("library", START), ("chosen", chosen)):
        if label == "chosen" and settings == START:
            entries[label] = entries["library"]
            continue
        if (earlier.get(label, {}).get("settings") == settings
                and earlier.get("filter_keys") == list(TEST_KEYS)):
            entries[label] = earlier[label]  # an earlier run of this stage scored it
            continue
        sequences = render(clips, clips) if sequences is None else sequences
        by_key, seconds = {}, 0.0
        for key in TEST_KEYS:
            outcome = run(settings, sequences, clips, key)
            seconds += outcome["seconds"]
            by_key[key] = outcome["result"]
        keyed = {f"{name}_key{key}": scores for key, result in by_key.items()
                 for name, scores in result["sequences"].items()}
        first = by_key[TEST_KEYS[0]]
        entries[label] = {"settings": settings, "seconds": seconds,
                          "pooled": pooled_scores(keyed),
                          "intervals": clip_intervals(keyed, clips),
                          "overall": first["overall"], "sequences": keyed,
                          "smoothed_confusion": first["smoothed_confusion"]}
        for kind in ("instantaneous", "smoothed"):
            scored = entries[label]["pooled"][kind]
            print(f"test, {label} settings, {kind}, keys {TEST_KEYS}: MSE all "
                  f"{scored['mse_all']:.1f}, posture error "
                  f"{100 * scored['posture_error']:.1f} % (key {TEST_KEYS[0]}: "
                  f"{first['overall'][kind]['mse']['all']:.1f})", flush=True)
    payload = {"command": "python -m papers.kwatra2002.mm_selection test",
               "device": device_description(), "clips": clips,
               "azimuths_degrees": list(AZIMUTHS_DEGREES), "frames": FRAMES,
               "filter_keys": list(TEST_KEYS),
               "note": "overall and smoothed_confusion: filter key 1 alone (the evaluation's "
                       "run with --seed 1); pooled and intervals: all keys",
               **entries}
    write_json(out, payload)
    return payload


def _clip_of(name: str, clips) -> str:
    stems = [clip.split("/")[-1] for clip in clips]
    return next(stem for stem in stems if name.startswith(stem + "_"))


def summary(validation_file: Path, test_file: Path) -> str:
    """Markdown tables of the search's steps and the test scores (what the README quotes)."""
    lines = []
    if validation_file.is_file():
        found = json.loads(validation_file.read_text())
        lines += ["| coordinate | value | smoothed MSE all, mean of keys " + "/".join(
                      str(key) for key in found.get("keys", KEYS)) + " | per key | chosen |",
                  "|---|---|---|---|---|"]
        for step in found.get("steps", []):
            for value, mses in step["tried"]:
                mark = "**yes**" if value == step["chosen"] else ""
                lines.append(f"| {step['coordinate']} | {value} | {np.mean(mses):,.0f} | "
                             + " / ".join(f"{mse:,.0f}" for mse in mses) + f" | {mark} |")
        instantaneous = {row["instantaneous"]["mse_all"] for row in found["rows"]}
        lines.append(f"\nchosen: {found.get('chosen')}; skipped for time: "
                     f"{found.get('skipped_coordinates')}; instantaneous MSE all "
                     + ", ".join(f"{value:,.0f}" for value in sorted(instantaneous)))
    if test_file.is_file():
        found = json.loads(test_file.read_text())
        lines += ["", "| settings | estimate | MSE all | 95 % | posture error | 95 % | "
                  "head ≤ 20 px |", "|---|---|---|---|---|---|---|"]
        for label in ("library", "chosen"):
            entry = found[label]
            for kind in ("instantaneous", "smoothed"):
                scored, interval = entry["pooled"][kind], entry["intervals"][kind]
                low, high = interval["mse_all_95"]
                error_low, error_high = interval["posture_error_95"]
                lines.append(f"| {label} | {kind} | {scored['mse_all']:,.0f} | {low:,.0f}–"
                             f"{high:,.0f} | {100 * scored['posture_error']:.1f} % | "
                             f"{100 * error_low:.1f}–{100 * error_high:.1f} % | "
                             f"{100 * scored['head_within_20px']:.1f} % |")
        lines += ["", "| settings | estimate | " + " | ".join(
            clip.split("/")[-1] for clip in found["clips"]) + " |",
            "|---|---|" + "---|" * len(found["clips"])]
        for label in ("library", "chosen"):
            for kind in ("instantaneous", "smoothed"):
                sums = {}
                for name, scores in found[label]["sequences"].items():
                    clip = _clip_of(name, found["clips"])
                    frames = scores[kind]["frames"]
                    total, count = sums.get(clip, (0.0, 0))
                    sums[clip] = (total + scores[kind]["mse"]["all"] * frames, count + frames)
                lines.append(f"| {label} | {kind} | " + " | ".join(
                    f"{sums[clip.split('/')[-1]][0] / max(sums[clip.split('/')[-1]][1], 1):,.0f}"
                    for clip in found["clips"]) + " |")
    return "\n".join(lines)


CACHE = RESULTS


def main(argv=None) -> int:
    global CACHE
    parser = argparse.ArgumentParser(prog="python -m papers.kwatra2002.mm_selection",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("stage", choices=("validation", "test", "summary"),
                        help="summary: print the tables of the two stages' JSON")
    parser.add_argument("--out", default=None, help="JSON to write (default results/"
                        "mm_selection.json for validation, results/mm_selection_test.json for "
                        "test)")
    parser.add_argument("--validation-file", default=str(OUT),
                        help="the validation stage's JSON (test stage: its chosen settings)")
    parser.add_argument("--skip", nargs="*", default=[], metavar="COORDINATE",
                        choices=[name for name, _ in COORDINATES],
                        help="validation: coordinates not searched (kept at the library's)")
    parser.add_argument("--cache", default=str(RESULTS),
                        help="folder of the cached posture model (mixed_state_evaluation's)")
    args = parser.parse_args(argv)
    CACHE = Path(args.cache)
    out = Path(args.out or (OUT if args.stage == "validation"
                            else RESULTS / "mm_selection_test.json"))
    if out.suffix != ".json" or not out.parent.is_dir():
        parser.error(f"--out {out}: must end in .json in an existing folder")
    if args.stage == "summary":
        print(summary(Path(args.validation_file), Path(args.out or RESULTS
                                                        / "mm_selection_test.json")))
        return 0
    try:
        if args.stage == "validation":
            validation(out, args.skip)
        else:
            test(out, Path(args.validation_file))
    except (FileNotFoundError, ValueError) as error:
        print(f"python -m papers.kwatra2002.mm_selection: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
