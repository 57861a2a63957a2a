"""Tian et al.'s protocol beside the held-out protocol, on the same test sequences.

Both protocols track the test subject's two waves (cmu_1006, :data:`TEST_CLIPS`), rendered as
the scripted comparison renders them (:mod:`papers.tian2005.tracking`: a frontal and a random
view over a real photo, 30 fps), with the paper's trackers and settings:

- the latent tracker, 200 particles, its own estimate (no refinement), decoding with the GP mean
  alone (``subject_lengths=False``: the paper's decoder);
- CONDENSATION, 1 000 particles, with the AR(2) learned from the first 30 frames of the test
  clip's ground truth (the paper's baseline, ``baseline_dynamics="test_start"``);
- MHT, 10 modes, its step learned the same way;
- every method scored by the paper's likelihood (eq. 7: NCC of template patches at the
  markers) and started from frame 0's ground truth.

The two protocols differ only in the prior's training poses:

- **paper**: the same person's other take (Tian et al. trained and tested on one subject): the
  prior that tracks ``cmu_1006_wave_hello_2`` learns from ``cmu_1006_wave_hello_1`` and the
  other way round (:func:`same_person_training`);
- **held_out**: the training subjects' waves (:data:`jaxtrack.data.clip_sets.TRAINING_CLIPS`),
  people the test subject is not (:func:`jaxtrack.data.splits.check_disjoint`).

The claim tested: the latent tracker's own error is at most :data:`TARGET_RATIO` times
CONDENSATION's (Tian et al. report about half).
"""

from __future__ import annotations

import statistics
from collections.abc import Sequence

import numpy as np

from jaxtrack.data.clip_sets import GESTURE_CLIPS, TRAINING_CLIPS
from jaxtrack.data.splits import check_disjoint, subject_of

PROTOCOLS = ("paper", "held_out")
TEST_CLIPS = GESTURE_CLIPS["test"]
PARTICLES = {"latent": 200, "condensation": 1000, "mht": 10}
"""The paper's counts: 200 latent particles against 1 000 in the full state; MHT's modes."""
LIKELIHOOD = "markers"
SETTINGS = {"subject_lengths": 0.0}
"""The latent tracker decodes with the GP mean alone, as the paper does."""
BASELINE_DYNAMICS = "test_start"
TARGET_RATIO = 0.6
"""The target: the latent tracker's own mean error at most 0.6 × CONDENSATION's."""


def same_person_training(test_clip: str, clips: Sequence[str] = TEST_CLIPS) -> tuple[str, ...]:
    """The paper's protocol's training clips for ``test_clip``: the same person's other takes
    among ``clips``.

    Raises:
        ValueError: ``test_clip`` is not among ``clips``, or its person has no other take.
    """
    if test_clip not in clips:
        raise ValueError(f"{test_clip} is not one of the test clips {', '.join(clips)}")
    person = subject_of(test_clip)
    others = tuple(clip for clip in clips if clip != test_clip and subject_of(clip) == person)
    if not others:
        raise ValueError(f"{test_clip}: {person} has no other take among {', '.join(clips)}")
    return others


def training_clips(protocol: str, test_clip: str) -> tuple[str, ...]:
    """The prior's training clips for ``test_clip`` under ``protocol`` (:data:`PROTOCOLS`);
    the held-out protocol's are checked to share no person with the test clip."""
    if protocol == "paper":
        return same_person_training(test_clip)
    if protocol == "held_out":
        check_disjoint(TRAINING_CLIPS, [test_clip])
        return TRAINING_CLIPS
    raise ValueError(f"protocol must be one of {', '.join(PROTOCOLS)}, got {protocol!r}")


def ratio_interval(numerator: dict, denominator: dict, resamples: int = 10_000,
                   seed: int = 0) -> tuple[float, float, float]:
    """The ratio of two methods' mean errors and its 95 % bootstrap interval over seeds.

    Args:
        numerator: sequence name -> the latent tracker's errors of that sequence, one per seed.
        denominator: sequence name -> CONDENSATION's errors, one per seed (the same sequences).
        resamples: bootstrap resamples.
        seed: the bootstrap's random seed.

    Returns:
        ``(ratio, low, high)``: mean over all runs of ``numerator`` over that of
        ``denominator``, and the 2.5 and 97.5 percentiles of the same ratio when each
        sequence's seeds are resampled with replacement, each method on its own (the sequences
        stay fixed: the interval is over tracker seeds).
    """
    if set(numerator) != set(denominator) or not numerator:
        raise ValueError("both methods need runs of the same sequences")
    rng = np.random.default_rng(seed)

    def resampled(runs: dict) -> np.ndarray:
        means = []
        for name in sorted(runs):
            values = np.asarray(runs[name], float)
            picks = rng.integers(len(values), size=(resamples, len(values)))
            means.append(values[picks].mean(axis=1))
        return np.mean(means, axis=0)  # every sequence has the same number of seeds

    def mean(runs: dict) -> float:
        return float(np.mean([np.mean(runs[name]) for name in sorted(runs)]))

    ratios = resampled(numerator) / resampled(denominator)
    low, high = np.percentile(ratios, [2.5, 97.5])
    return mean(numerator) / mean(denominator), float(low), float(high)


def summarise(runs: list[dict]) -> dict:
    """One protocol's runs (``tracking.run_one``'s records plus ``protocol``): per method the
    mean error (torso lengths) with its 95 % t-interval over runs, the pixels, the fraction of
    frames within 15 % of the torso and the lost runs; and the latent tracker's ratio to
    CONDENSATION with its bootstrap interval over seeds (:func:`ratio_interval`)."""
    from papers.tian2005.tracking import t_interval

    rows, by_sequence = {}, {}
    for method in PARTICLES:
        group = [run for run in runs if run["method"] == method]
        if not group:
            continue
        torso = [run["mean_error_torso"] for run in group]
        rows[method] = {
            "particles": group[0]["particles"], "runs": len(group),
            "error_torso": statistics.mean(torso), "error_torso_ci": t_interval(torso),
            "error_px": statistics.mean(run["mean_error_px"] for run in group),
            "within_15": statistics.mean(run["fraction_within_15"] for run in group),
            "lost": sum(run["failed"] for run in group)}
        by_sequence[method] = {}
        for run in group:
            by_sequence[method].setdefault(run["sequence"], []).append(run["mean_error_torso"])
    result = {"rows": rows}
    if "latent" in by_sequence and "condensation" in by_sequence:
        ratio, low, high = ratio_interval(by_sequence["latent"], by_sequence["condensation"])
        result["ratio_latent_over_condensation"] = {"ratio": ratio, "low": low, "high": high,
                                                    "target": TARGET_RATIO,
                                                    "met": ratio <= TARGET_RATIO}
    return result


def run(seeds: int = 3, views: int = 2, max_frames: int | None = None,
        protocols: Sequence[str] = PROTOCOLS, progress: bool = True) -> dict:
    """Track :data:`TEST_CLIPS` under each protocol with every method of :data:`PARTICLES`
    and ``seeds`` tracker seeds (module docstring). Returns the JSON-able results: the runs,
    each protocol's :func:`summarise` and its training clips per test clip."""
    from tqdm import tqdm

    from jaxtrack.experiments import render_test_sequences
    from jaxtrack.priors.train import train_prior
    from papers.tian2005 import RUNS, candidate_prior
    from papers.tian2005.tracking import run_one

    # the same renders as the scripted comparison's (seed = the clip's index)
    sequences = {clip: render_test_sequences(clip, views=views, seed=index,
                                             max_frames=max_frames)
                 for index, clip in enumerate(TEST_CLIPS)}
    results, runs = {}, []
    for protocol in protocols:
        trained_on, protocol_runs = {}, []
        for clip in TEST_CLIPS:
            clips = training_clips(protocol, clip)
            trained_on[clip] = list(clips)
            if protocol == "held_out":
                prior = candidate_prior("waves")
            else:
                name = "_".join(other.rsplit("/", 1)[-1] for other in clips)
                prior = train_prior(clips, progress=False,
                                    cache=RUNS / "tracking" / f"prior_same_person_{name}.npz")
            jobs = [(method, sequence, seed) for method in PARTICLES
                    for sequence in sequences[clip] for seed in range(seeds)]
            for method, sequence, seed in tqdm(jobs, desc=f"{protocol}: {clip.rsplit('/')[-1]}",
                                               unit="run", disable=not progress):
                record = run_one(prior, sequence, {"method": method, "estimate": "own",
                                                   "likelihood": LIKELIHOOD},
                                 seed, PARTICLES[method], BASELINE_DYNAMICS,
                                 settings=dict(SETTINGS) if method == "latent" else None)
                protocol_runs.append({"protocol": protocol, **record})
        results[protocol] = {"training_clips": trained_on, **summarise(protocol_runs)}
        runs.extend(protocol_runs)
    return {"protocols": results, "runs": runs,
            "settings": {"test_clips": list(TEST_CLIPS), "views": views, "seeds": seeds,
                         "max_frames": max_frames, "particles": PARTICLES,
                         "likelihood": LIKELIHOOD, "estimate": "own",
                         "baseline_dynamics": BASELINE_DYNAMICS,
                         "latent_settings": SETTINGS, "initialisation": "frame 0's truth"}}


def markdown_table(results: dict) -> str:
    """The protocols side by side: one row per protocol and method, then the ratios."""
    lines = ["| protocol | method | N | runs | error / torso | ± 95 % | error px | within 15 % "
             "| lost |", "|---|---|---|---|---|---|---|---|---|"]
    for protocol, found in results["protocols"].items():
        for method, row in found["rows"].items():
            lines.append(f"| {protocol} | {method} | {row['particles']} | {row['runs']} | "
                         f"{row['error_torso']:.1%} | {row['error_torso_ci']:.1%} | "
                         f"{row['error_px']:.1f} | {row['within_15']:.0%} | "
                         f"{row['lost']}/{row['runs']} |")
    lines += ["", "| protocol | latent / CONDENSATION | 95 % (seeds) | target ≤ "
              f"{TARGET_RATIO:g} |", "|---|---|---|---|"]
    for protocol, found in results["protocols"].items():
        ratio = found.get("ratio_latent_over_condensation")
        if ratio:
            lines.append(f"| {protocol} | {ratio['ratio']:.2f} | {ratio['low']:.2f}–"
                         f"{ratio['high']:.2f} | {'met' if ratio['met'] else 'not met'} |")
    return "\n".join(lines)


def plot(results: dict, path) -> None:
    """Bars: each protocol's mean error per method with its 95 % interval."""
    from jaxtrack._plotting import new_figure, save_figure

    figure, axis = new_figure(7.0, 3.6)
    protocols = list(results["protocols"])
    width = 0.8 / len(PARTICLES)
    for index, method in enumerate(PARTICLES):
        rows = [results["protocols"][p]["rows"].get(method) for p in protocols]
        positions = np.arange(len(protocols)) + (index - 1) * width
        axis.bar(positions, [100 * row["error_torso"] if row else 0 for row in rows], width,
                 yerr=[100 * row["error_torso_ci"] if row else 0 for row in rows], capsize=3,
                 label=f"{method} ({PARTICLES[method]})")
    axis.set_xticks(np.arange(len(protocols)),
                    ["paper's (same person's other take)" if p == "paper" else
                     "held out (other people)" for p in protocols])
    axis.set_ylabel("mean marker error, % of torso")
    axis.set_title("own estimates, eq. 7 likelihood, baselines' AR(2) from the test clip's "
                   "first 30 frames", fontsize=8)
    axis.legend(fontsize=8)
    save_figure(figure, path, dpi=100)
