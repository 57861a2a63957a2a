"""Why temporal integration cannot halve the error in the paper's setting: how the hypotheses'
errors are spread over time.

Integration (Kwatra et al. 2002, §3.2–3.3) can lower the part error in two ways only: by
choosing the right posture's hypotheses where the instantaneous estimate chose a wrong one, and
by averaging the chosen hypotheses' error over the frames the dynamics tie together. The
second works only where that error changes from frame to frame. An error that stays put for
many frames (a hand the heuristics do not see, so they put it on the silhouette's edge for
as long as it stays hidden) is the same in every frame that would be averaged, and survives.

    python -m papers.kwatra2002.diagnosis --json papers/kwatra2002/results/kwatra2002_diagnosis.json

renders the paper setting's three test takes exactly as ``python -m papers.kwatra2002`` does
(the same camera and seeds) and measures, per part, for the true posture's hypotheses and for
the best posture's per frame (an oracle that knows the truth):

- :func:`error_autocorrelation`: the correlation of the error vector with itself k frames
  later (uncentred: a constant offset counts as correlated, since averaging cannot remove it);
- :func:`averaged_mse`: the mean squared error left after averaging the error over a centred
  window of w frames, the most that averaging w frames can do with a perfect motion model (the
  error is averaged, not the hypotheses, so the body's own motion costs nothing). White noise
  would fall as 1/w.

    python -m papers.kwatra2002.diagnosis --synthetic \
        --json papers/kwatra2002/results/kwatra2002_synthetic.json

runs :func:`averaging_experiment` instead: how much of white or persistent hypothesis noise the
filter and smoother remove where the answer is known, for each way of drawing the parts
(``MixedStateModel.part_proposal``), particle count and seed.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from papers.kwatra2002 import setting

LAGS = (1, 2, 5, 10, 15, 30)
"""Lags (frames at 30 fps) at which the autocorrelation is reported."""
WIDTHS = (1, 3, 5, 9, 15, 31)
"""Averaging windows (frames, centred) of :func:`averaged_mse`."""
GROUPS = {"head": [0], "hands": [1, 2], "feet": [3, 4], "all": [0, 1, 2, 3, 4]}


def part_errors(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """``(time, 5, 2)`` error vectors estimate − truth (px) of head, hand, hand, foot, foot,
    hands and feet under the best left/right assignment per frame (as Table 1 scores them:
    :func:`jaxtrack.experiments.mixed_state.part_squared_errors` is their squared norm)."""
    estimate, truth = np.asarray(estimate, np.float64), np.asarray(truth, np.float64)
    if estimate.shape != truth.shape or estimate.shape[1:] != (5, 2):
        raise ValueError(f"estimate and truth must both be (time, 5, 2), got {estimate.shape} "
                         f"and {truth.shape}")
    errors = estimate - truth
    for first in (1, 3):
        pair = [first, first + 1]
        crossed = estimate[:, pair[::-1]] - truth[:, pair]
        swap = np.sum(crossed ** 2, axis=(1, 2)) < np.sum(errors[:, pair] ** 2, axis=(1, 2))
        errors[:, pair] = np.where(swap[:, None, None], crossed, errors[:, pair])
    return errors


def error_autocorrelation(sequences, lags=LAGS) -> np.ndarray:
    """``(len(lags), parts)`` uncentred autocorrelation of the error vectors,

        ρ(k) = Σ_t e_t · e_t+k / √(Σ_t |e_t|² Σ_t |e_t+k|²),

    the sums over every pair of frames k apart within one sequence, all sequences pooled.

    Args:
        sequences: ``(time, parts, 2)`` error arrays, one per sequence (times may differ).
        lags: positive lags in frames.

    Returns:
        ρ per lag and part; 1 for an error that never changes, about 0 for white noise."""
    sequences = [np.asarray(s, np.float64) for s in sequences]
    if not sequences or any(s.ndim != 3 or s.shape[2] != 2 for s in sequences):
        raise ValueError("sequences must be a non-empty list of (time, parts, 2) error arrays")
    out = np.full((len(lags), sequences[0].shape[1]), np.nan)
    for row, lag in enumerate(lags):
        if lag < 1:
            raise ValueError(f"lags must be positive frames, got {lag}")
        cross = early = late = 0.0
        for errors in sequences:
            if len(errors) <= lag:
                continue
            cross = cross + np.sum(errors[:-lag] * errors[lag:], axis=-1).sum(axis=0)
            early = early + np.sum(errors[:-lag] ** 2, axis=-1).sum(axis=0)
            late = late + np.sum(errors[lag:] ** 2, axis=-1).sum(axis=0)
        if np.ndim(cross):
            out[row] = cross / np.sqrt(np.maximum(early * late, 1e-300))
    return out


def averaged_mse(sequences, width: int) -> np.ndarray:
    """``(parts,)`` mean squared error (px²) left after replacing each frame's error vector
    by its mean over the centred window of ``width`` frames (shortened at a sequence's ends),
    all frames of all sequences pooled. ``width`` 1 gives the raw MSE."""
    if width < 1 or width % 2 == 0:
        raise ValueError(f"width must be a positive odd number of frames, got {width}")
    half, total, count = width // 2, 0.0, 0
    for errors in sequences:
        errors = np.asarray(errors, np.float64)
        cumulative = np.concatenate([np.zeros((1, *errors.shape[1:])),
                                     np.cumsum(errors, axis=0)])
        steps = np.arange(len(errors))
        low, high = np.maximum(steps - half, 0), np.minimum(steps + half + 1, len(errors))
        means = (cumulative[high] - cumulative[low]) / (high - low)[:, None, None]
        total = total + np.sum(means ** 2, axis=(0, 2))
        count += len(errors)
    return total / count


def summarise(sequences) -> dict:
    """Per part group: the MSE, ρ at every lag of :data:`LAGS` and the MSE left after
    averaging over every window of :data:`WIDTHS` (and that as a fraction of the MSE)."""
    rho = error_autocorrelation(sequences)
    averaged = {width: averaged_mse(sequences, width) for width in WIDTHS}
    squared = np.concatenate([np.sum(np.asarray(s) ** 2, axis=-1) for s in sequences])
    energy = squared.mean(axis=0)  # per part: ρ of a group weighs its parts by their energy
    out = {}
    for name, idx in GROUPS.items():
        mse = float(squared[:, idx].mean())
        out[name] = {
            "mse": mse,
            "autocorrelation": {str(lag): float(np.sum(rho[row, idx] * energy[idx])
                                                / np.sum(energy[idx]))
                                for row, lag in enumerate(LAGS)},
            "mse_after_averaging": {str(w): float(averaged[w][idx].mean()) for w in WIDTHS},
            "fraction_left_after_averaging": {str(w): float(averaged[w][idx].mean() / mse)
                                              for w in WIDTHS},
        }
    return out


SYNTHETIC_FRAMES, SYNTHETIC_SIZE, SYNTHETIC_NOISE = 24, (120, 100), 8.0


def averaging_experiment(part_proposal: str, num_particles: int, seed: int,
                         noise: str = "white") -> dict:
    """The filter and the ancestry-tracing smoother on hypotheses of known noise: five parts
    at fixed points of a 120 × 100 image moving right 1 px every third frame for 24 frames,
    every posture's hypotheses the parts plus ``noise``: ``"white"`` (N(0, 8²) per
    coordinate, a new draw every frame) or ``"persistent"`` (one such draw kept for the whole
    sequence). The silhouette fills the image (projection moves nothing) and one posture
    explains the features far better than the others, so only integration over time acts.

    Returns:
        the hypotheses' MSE, the filtered and smoothed MSE (all parts, px²) and the mean
        effective sample size."""
    import jax.numpy as jnp
    import jax.random as jr

    from jaxtrack.priors.postures import NUM_POSTURES, PostureModel
    from jaxtrack.trackers.mixed_state import (
        MixedStateFrame,
        MixedStateModel,
        filter_sequence,
        smooth,
    )

    if noise not in ("white", "persistent"):
        raise ValueError(f"noise must be 'white' or 'persistent', got {noise!r}")
    frames, (width, height) = SYNTHETIC_FRAMES, SYNTHETIC_SIZE
    start = np.array([[50.0, 14.0], [25.0, 45.0], [75.0, 45.0], [40.0, 90.0], [60.0, 90.0]])
    truth = start[None] + np.stack([np.arange(frames) // 3, np.zeros(frames)], -1)[:, None]
    rng = np.random.default_rng(0)
    shape = (frames, 5, 2) if noise == "white" else (1, 5, 2)
    offsets = np.broadcast_to(SYNTHETIC_NOISE * rng.normal(size=shape), truth.shape)
    hypotheses = np.broadcast_to((truth + offsets)[:, None], (frames, NUM_POSTURES, 5, 2))
    # one feature, the first posture's mean; unit variances; a sticky T
    transition = np.full((NUM_POSTURES,) * 2, 0.025) + 0.875 * np.eye(NUM_POSTURES)
    postures = PostureModel(jnp.arange(NUM_POSTURES, dtype=float)[:, None] * 5.0,
                            jnp.ones((NUM_POSTURES, 1, 1)), jnp.zeros(NUM_POSTURES),
                            jnp.asarray(np.log(transition)),
                            jnp.full(NUM_POSTURES, -np.log(NUM_POSTURES)), jnp.asarray(1e9))
    grid = np.stack(np.meshgrid(np.arange(width), np.arange(height)), -1).astype(np.int16)
    observations = MixedStateFrame(jnp.zeros((frames, 1)), jnp.asarray(hypotheses),
                                   jnp.asarray(np.broadcast_to(grid, (frames, height, width,
                                                                      2))),
                                   jnp.zeros(frames, jnp.int32))
    model = MixedStateModel(postures, part_proposal=part_proposal)
    result = filter_sequence(jr.PRNGKey(seed), model, observations, num_particles)
    smoothed = smooth(result)

    def mse(parts):
        return float(np.mean(np.sum((np.asarray(parts) - truth) ** 2, -1)))

    return {"hypotheses": float(np.mean(np.sum(offsets ** 2, -1))),
            "filtered": mse(result.filtered_parts), "smoothed": mse(smoothed.parts),
            "mean_ess": float(np.mean(np.asarray(result.ess)))}


def synthetic(particles=(300, 1000), seeds=(0, 1, 2, 3)) -> dict:
    """:func:`averaging_experiment` for both part proposals, every particle count and seed,
    white and persistent noise."""
    from jaxtrack.trackers.mixed_state import PART_PROPOSALS

    rows = []
    for proposal in PART_PROPOSALS:
        for count in particles:
            for noise in ("white", "persistent"):
                for seed in seeds:
                    rows.append({"part_proposal": proposal, "particles": count,
                                 "noise": noise, "seed": seed,
                                 **averaging_experiment(proposal, count, seed, noise)})
                    print(rows[-1], flush=True)
    return {"frames": SYNTHETIC_FRAMES, "noise_std": SYNTHETIC_NOISE, "rows": rows}


def diagnose(actor: str = setting.ACTOR) -> dict:
    """Render the paper setting's test takes (``python -m papers.kwatra2002``'s camera and
    seeds) and :func:`summarise` the errors of the true posture's hypotheses and of the best
    posture's per frame."""
    from jaxtrack.trackers.mixed_state import observations_from_silhouettes
    from jaxtrack.vision.histograms import FRAME_OK
    from papers.kwatra2002.__main__ import _progress, render_tests

    takes = setting.actor_takes(actor)
    motions = {take.name: setting.load_take(take) for take in
               _progress(takes, desc="loading takes")}
    camera = setting.side_camera(list(motions.values()))
    rendered = render_tests(motions, camera, setting.TEST_TAKES)
    true_posture, best_posture, per_take = [], [], {}
    for take in _progress(rendered, desc="hypotheses"):
        frames = observations_from_silhouettes(take.masks)
        ok = np.asarray(frames.status) == FRAME_OK
        hypotheses = np.asarray(frames.hypotheses)
        steps = np.arange(len(hypotheses))
        every = np.stack([part_errors(hypotheses[:, q], take.parts)
                          for q in range(hypotheses.shape[1])], axis=1)  # (time, q, 5, 2)
        own = every[steps, take.labels]
        best = every[steps, np.argmin(np.sum(every ** 2, axis=(2, 3)), axis=1)]
        # frames with no silhouette split a take: each run of scored frames is a sequence
        for start, stop in _runs(ok):
            true_posture.append(own[start:stop])
            best_posture.append(best[start:stop])
        per_take[take.name] = {"frames": int(len(ok)), "scored_frames": int(ok.sum()),
                               "true_posture": summarise([own[ok]])}
    return {"actor": actor, "test_takes": list(setting.TEST_TAKES), "fps": setting.FPS,
            "lags": list(LAGS), "widths": list(WIDTHS),
            "true_posture": summarise(true_posture),
            "best_posture_per_frame": summarise(best_posture), "per_take": per_take}


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``(start, stop)`` of every run of True in ``mask``."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return list(zip(edges[::2], edges[1::2], strict=True))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m papers.kwatra2002.diagnosis",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", required=True, help="where to write the measurements (JSON)")
    parser.add_argument("--actor", default=setting.ACTOR, help="the actor (default bd)")
    parser.add_argument("--synthetic", action="store_true", help="run averaging_experiment "
                        "(known noise) instead of the paper setting's hypotheses")
    args = parser.parse_args(argv)
    out = Path(args.json)
    if out.suffix != ".json" or not out.parent.is_dir():
        parser.error(f"--json {out}: must end in .json, in a folder that exists")
    if args.synthetic:
        import jax

        jax.config.update("jax_enable_x64", True)  # as the tests run it
        from papers.kwatra2002.__main__ import _write_json

        _write_json(out, synthetic())
        return 0
    try:
        results = diagnose(args.actor)
    except (FileNotFoundError, ValueError) as error:
        print(f"python -m papers.kwatra2002.diagnosis: {error}", file=sys.stderr)
        return 2
    from papers.kwatra2002.__main__ import _write_json

    _write_json(out, results)
    for kind in ("true_posture", "best_posture_per_frame"):
        for name in ("head", "hands", "feet", "all"):
            row = results[kind][name]
            print(f"{kind:24s} {name:5s} MSE {row['mse']:7.0f}  rho(1,5,15) "
                  + " ".join(f"{row['autocorrelation'][k]:.2f}" for k in ("1", "5", "15"))
                  + "  left after 5/15/31 frames "
                  + " ".join(f"{row['fraction_left_after_averaging'][k]:.2f}"
                             for k in ("5", "15", "31")))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
