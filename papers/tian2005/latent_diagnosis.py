"""Why the latent tracker's own estimate misses a new person: variants on one validation wave.

    python -m papers.tian2005.latent_diagnosis            # Bandai's right-hand wave, frontal view

The latent tracker (its own estimate, no refinement, the default likelihood) with a candidate
prior of ``papers.tian2005.tracking`` (``--prior``, ``--mirror``, ``--parts``; default the per-part
prior of the ten training-subject gestures) and variants of its settings: 1 000 particles, a
flatter likelihood (λ / 2, λ / 4), a larger latent step (2 ν, 3 ν: the random walk's ν scales
with the square root of the frame rate it is rescaled from), and no jumps with the subject's own
link lengths. Per variant: the estimate's and the best particle's mean error in % of the torso,
frames within 15 %, median ESS and the two wrists' error. A validation subject: this chooses
nothing by itself, it says where the error comes from (papers/tian2005/history.md, "A prior that
generalises across people").
"""

from __future__ import annotations

import argparse

import jax.random as jr
import numpy as np

from benchmarks._common import print_table
from jaxtrack.body import UPPER_BODY_12
from jaxtrack.data.clip_sets import PRIOR_CLIPS
from jaxtrack.evaluation import torso_lengths
from jaxtrack.experiments import render_test_sequences
from jaxtrack.likelihoods import default_sharpness
from jaxtrack.trackers import Engine, Likelihood, latent_tracker, track
from papers.tian2005 import candidate_prior

CLIP = "bandai/dataset-2_wave-right-hand_normal_001"
WRISTS = (UPPER_BODY_12.index("right_wrist"), UPPER_BODY_12.index("left_wrist"))


def variants() -> list[tuple[str, dict, float, float]]:
    """(name, latent_tracker options, λ factor, ν factor)."""
    return [("default", {}, 1.0, 1.0), ("1 000 particles", {"engine": Engine(1000)}, 1.0, 1.0),
            ("λ / 2", {}, 0.5, 1.0), ("λ / 4", {}, 0.25, 1.0),
            ("2 ν", {}, 1.0, 2.0), ("3 ν", {}, 1.0, 3.0),
            ("no jumps, subject's link lengths",
             {"jump_probability": 0.0, "subject_lengths": True}, 1.0, 1.0)]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m papers.tian2005.latent_diagnosis",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--prior", choices=tuple(PRIOR_CLIPS), default="gestures")
    parser.add_argument("--mirror", action="store_true")
    parser.add_argument("--parts", action=argparse.BooleanOptionalAction, default=True)
    parser.add_argument("--only-default", action="store_true", help="the default variant alone")
    args = parser.parse_args(argv)
    prior = candidate_prior(args.prior, args.mirror, args.parts)
    sequence = render_test_sequences(CLIP, views=1, seed=0)[0]
    torso = torso_lengths(sequence.truth, UPPER_BODY_12)
    rows = []
    for name, options, sharpness, step in variants()[:1 if args.only_default else None]:
        likelihood = Likelihood("limbs+edges", sharpness=sharpness * default_sharpness(
            "limbs+edges"))
        tracker = latent_tracker(prior.model, prior.template, likelihood=likelihood,
                                 refinement=None, fps=sequence.fps / step**2, **options)
        result = track(tracker, jr.PRNGKey(0), sequence.frames, sequence.truth[0],
                       progress=False)
        errors = np.linalg.norm(result.markers - sequence.truth, axis=-1) / torso[:, None]
        best = np.linalg.norm(result.best_markers - sequence.truth, axis=-1) / torso[:, None]
        per_frame = errors.mean(axis=1)
        rows.append({"variant": name, "error": per_frame.mean(), "best": best.mean(),
                     "within_15": (per_frame < 0.15).mean(), "ess": float(np.median(result.ess)),
                     "right_wrist": errors[:, WRISTS[0]].mean(),
                     "left_wrist": errors[:, WRISTS[1]].mean()})
    print(f"{CLIP}, frontal view, {len(sequence.frames)} frames; prior "
          f"{args.prior}{' + mirrored' if args.mirror else ''}{', per part' if args.parts else ''}")
    print_table(rows, [("variant", "variant", "s"), ("error", "estimate/torso", ".1%"),
                       ("best", "best particle", ".1%"), ("within_15", "within 15 %", ".0%"),
                       ("ess", "median ESS", ".1f"), ("right_wrist", "right wrist", ".2f"),
                       ("left_wrist", "left wrist", ".2f")])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
