"""How well each candidate prior reconstructs the poses of people it was never trained on.

    python -m papers.tian2005.prior_generalisation                     # validation subjects
    python -m papers.tian2005.prior_generalisation --split test        # report only, never choose
    python -m papers.tian2005.prior_generalisation --priors waves gestures --mirror both

The latent tracker's own estimate is μ of a latent point, so no tracker can report a pose
closer than μ(μ⁻¹(y)), the prior's reconstruction of the true pose y: a floor under the
latent tracker's error that CONDENSATION, tracking in the full state, does not have. For every
candidate prior of ``papers.tian2005.tracking`` (``--prior`` × ``--mirror``, trained with the same
settings and cache), the held-out subjects' gesture clips of ``--split``
(:data:`jaxtrack.data.splits.SUBJECTS`; every clip of the split's AnimatedDrawings and Bandai
subjects) are seen from ``--views`` viewpoints and fitted with the prior's SPM template, and
each pose's features are reconstructed by

* the GPLVM through eq. 5's μ⁻¹ (the tracker's) and through argmin ½|y − μ(x)|²,
* PCA with the same latent dimension on the same training features,
* the nearest training pose (a lookup: the best any model of these poses could do without
  generalising), and the mean training pose,

and scored as markers (the held-out pose's own placement) in % of its torso. A second table
says how smooth each prior's training trajectories are in its latent space
(:func:`latent_smoothness`: free latents sit in islands joined by jumps; a back-constrained
GPLVM's move smoothly); with ``--steps`` a third says how far each held-out clip's own μ⁻¹
trajectory steps, in units of the latent walk's ν (:func:`walk_steps`), and how fast its
markers move (:func:`marker_speed`). ``papers/tian2005/results/runs/prior_latent_trajectories.png``
draws the training trajectories (each prior's first two latent dimensions, one line per
training sequence). Writes the tables and
``papers/tian2005/results/runs/prior_generalisation_<split>.json``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from tqdm import tqdm

from benchmarks._common import device_description, print_table, run_header, write_json
from benchmarks.gplvm import marker_errors, pca_reconstruction
from jaxtrack._plotting import new_figure, save_figure
from jaxtrack.body import UPPER_BODY_12
from jaxtrack.data.clip_sets import PRIOR_CLIPS
from jaxtrack.data.splits import check_disjoint, clips_in
from jaxtrack.evaluation import torso_lengths
from jaxtrack.experiments.priors import prior_tag
from jaxtrack.priors.dynamics import fit_latent_velocity
from jaxtrack.priors.gplvm import UPPER_BODY_PARTS, feature_columns, part_features
from jaxtrack.priors.poses import clip_motions, pose_features, pose_set
from papers.tian2005 import RUNS, candidate_prior

HELD_OUT_COLLECTIONS = ("animateddrawings", "bandai")
"""Upper-body gesture sources whose held-out subjects are reconstructed."""


def held_out_clips(split: str) -> tuple[str, ...]:
    """The split's gesture clips (its AnimatedDrawings and Bandai subjects' clips)."""
    return clips_in(split, *HELD_OUT_COLLECTIONS)


def nearest_reconstruction(train: np.ndarray, test: np.ndarray) -> np.ndarray:
    """Each test row's nearest training row (Euclidean, feature space)."""
    distances = (np.sum(test**2, axis=1)[:, None] - 2.0 * test @ train.T
                 + np.sum(train**2, axis=1)[None, :])
    return train[np.argmin(distances, axis=1)]


def nearest_per_part(train: np.ndarray, test: np.ndarray) -> np.ndarray:
    """Each part (:data:`UPPER_BODY_PARTS`) of each test row from its nearest training part."""
    out = np.array(test, copy=True)
    for links in UPPER_BODY_PARTS.values():
        out[:, feature_columns(links)] = nearest_reconstruction(part_features(train, links),
                                                                part_features(test, links))
    return out


def latent_smoothness(latents: np.ndarray, sequence_ids: np.ndarray) -> dict:
    """How a prior's training trajectories move in its latent space: the median and 99th
    percentile of the frame-to-frame step length within a sequence over the latents' spread
    (the root of their total variance), and the carried share a of the last step
    (:func:`~jaxtrack.priors.dynamics.fit_latent_velocity`) per latent dimension."""
    latents = np.asarray(latents, np.float64)
    ids = np.asarray(sequence_ids)
    steps = np.linalg.norm(np.diff(latents, axis=0)[ids[1:] == ids[:-1]], axis=1)
    spread = float(np.sqrt(latents.var(axis=0).sum()))
    carried = np.asarray(fit_latent_velocity(latents, ids).coefficient)
    return {"median_step": float(np.median(steps)) / spread,
            "p99_step": float(np.percentile(steps, 99)) / spread,
            "carried": carried.round(2).tolist(),
            "carried_range": f"{carried.min():.2f}–{carried.max():.2f}"}


def walk_steps(latents: np.ndarray, sequence_ids: np.ndarray, step_std: np.ndarray) -> dict:
    """How far a held-out motion moves in a prior's latent space: the frame-to-frame steps of
    its μ⁻¹ latents within a sequence, each in units of the random walk's ν (the RMS over the
    latent dimensions of step / ν), as the median, 90th and 99th percentile and the share of
    steps over 3 ν (a random walk of ν rarely goes that far in one frame)."""
    latents = np.asarray(latents, np.float64)
    ids = np.asarray(sequence_ids)
    steps = (np.diff(latents, axis=0) / np.asarray(step_std, np.float64))[ids[1:] == ids[:-1]]
    size = np.sqrt(np.mean(steps**2, axis=1))
    return {"median_nu": float(np.median(size)), "p90_nu": float(np.percentile(size, 90)),
            "p99_nu": float(np.percentile(size, 99)), "over_3nu": float(np.mean(size > 3.0))}


def marker_speed(markers: np.ndarray, sequence_ids: np.ndarray) -> float:
    """The median over frames of the fastest marker's frame-to-frame move, in torso lengths
    (neck to pelvis): how fast the motion is in the image."""
    markers = np.asarray(markers, np.float64)
    ids = np.asarray(sequence_ids)
    torso = torso_lengths(markers, UPPER_BODY_12)
    moves = np.linalg.norm(np.diff(markers, axis=0), axis=-1).max(axis=1) / torso[1:]
    return float(np.median(moves[ids[1:] == ids[:-1]]))


def held_out_steps(name: str, mirror: bool, parts: bool, clips, back_constraint=None
                   ) -> list[dict]:
    """One row per held-out clip (frontal view, every frame at 30 fps): :func:`walk_steps` of
    its μ⁻¹ trajectory under the candidate prior, ν at 30 fps as the tracker rescales it, and
    :func:`marker_speed` of the clip."""
    prior = candidate_prior(name, mirror, parts, back_constraint)
    model = prior.model
    nu = np.asarray(model.dynamics_std, np.float64) * np.sqrt(float(model.dynamics_fps) / 30.0)
    with jax.enable_x64(True):
        model = model.astype(jnp.float64)  # μ⁻¹ in float64, as the tracker solves it
    rows = []
    for clip in clips:
        held_out = pose_set(clip_motions([clip]), views=1, fps=30.0, template=prior.template)
        with jax.enable_x64(True):
            features = pose_features(held_out.states, prior.template)
            latents = np.asarray(model.inverse(features).latents)
        rows.append({"prior": prior_tag(name, mirror, parts, back_constraint), "clip": clip,
                     "frames": len(latents),
                     **walk_steps(latents, held_out.sequence_ids, nu),
                     "marker_speed": marker_speed(held_out.markers_2d, held_out.sequence_ids)})
    return rows


def plot_trajectories(priors: dict, path) -> None:
    """One panel per prior: its training latents' first two dimensions, one line per training
    sequence (clip × view), each scaled to the latents' spread."""
    columns = min(len(priors), 4)
    rows = -(-len(priors) // columns)
    figure, axes = new_figure(3.2 * columns, 3.2 * rows, columns=columns, rows=rows)
    axes = np.atleast_1d(axes).ravel()
    for axis, (tag, (latents, ids)) in zip(axes, priors.items(), strict=False):
        latents = np.asarray(latents, np.float64)[:, :2]
        latents = (latents - latents.mean(0)) / np.sqrt(latents.var(0).sum())
        for k, sequence in enumerate(np.unique(ids)):
            rows_of = np.flatnonzero(np.asarray(ids) == sequence)
            axis.plot(*latents[rows_of].T, lw=0.6, color=f"C{k % 10}", alpha=0.7)
        axis.set_title(tag, fontsize=9)
        axis.set_aspect("equal")
        axis.tick_params(labelsize=6)
    for axis in axes[len(priors):]:
        axis.set_visible(False)
    save_figure(figure, path, dpi=110)


def evaluate_prior(name: str, mirror: bool, parts: bool, clips, views: int,
                   stride: int, back_constraint: float | None = None,
                   trajectories: dict | None = None) -> list[dict]:
    """Rows (one per reconstruction method) for one candidate prior; its training latents and
    sequence ids go into ``trajectories`` under its tag, when given (for
    :func:`latent_smoothness` and :func:`plot_trajectories`)."""
    tag = prior_tag(name, mirror, parts, back_constraint)
    check_disjoint(PRIOR_CLIPS[name], clips)
    prior = candidate_prior(name, mirror, parts, back_constraint)
    held_out = pose_set(clip_motions(clips), views=views, template=prior.template)
    keep = np.arange(0, len(held_out.states), stride)
    held_out = type(held_out)(held_out.states[keep], held_out.markers_2d[keep],
                              held_out.sequence_ids[keep], held_out.sequences,
                              held_out.template, held_out.fps, held_out.image_size)
    with jax.enable_x64(True):
        test = np.asarray(pose_features(held_out.states, prior.template))
        train = np.asarray(pose_features(prior.training_states, prior.template))
        model = prior.model.astype(jnp.float64)
        reconstructions = {}
        for objective in ("posterior", "reconstruction"):
            start = time.perf_counter()
            reconstructions["GPLVM, eq. 5 μ⁻¹" if objective == "posterior" else
                            "GPLVM, argmin |y − μ(x)|"] = (
                np.asarray(model.reconstruct(jnp.asarray(test), objective=objective)),
                time.perf_counter() - start)
    latent_dim = prior.model.latent_dim
    reconstructions[f"PCA, q = {latent_dim}"] = (pca_reconstruction(train, test, latent_dim), 0.0)
    reconstructions["nearest training pose"] = (nearest_reconstruction(train, test), 0.0)
    reconstructions["nearest training pose per part"] = (nearest_per_part(train, test), 0.0)
    reconstructions["mean training pose"] = (np.broadcast_to(train.mean(0), test.shape), 0.0)
    rows = []
    if trajectories is not None:
        trajectories[tag] = (np.asarray(prior.model.latents), prior.training_sequence_ids)
    for method, (features, seconds) in reconstructions.items():
        for own_lengths in (False, True):
            if own_lengths:
                features = with_lengths_of(features, test)
            errors = marker_errors(np.asarray(features), held_out)
            rows.append({"prior": tag, "training_poses": len(train),
                         "held_out_poses": len(test), "method": method,
                         "lengths": "true (oracle)" if own_lengths else "reconstructed",
                         "seconds": seconds, **errors})
    return rows


def with_lengths_of(features: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``features``' link directions with ``reference``'s link lengths (both ``(n, 22)``: 11
    link vectors). With the true pose's lengths (an oracle: in the image they also carry
    foreshortening) only the directions are scored, so the rows with and without bound how
    much of the error is the held-out subject's proportions rather than the pose."""
    links = np.asarray(features).reshape(len(features), -1, 2)
    lengths = np.linalg.norm(np.asarray(reference).reshape(len(reference), -1, 2), axis=-1)
    directions = links / np.maximum(np.linalg.norm(links, axis=-1, keepdims=True), 1e-12)
    return (directions * lengths[..., None]).reshape(len(features), -1)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m papers.tian2005.prior_generalisation",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--split", choices=("validation", "test"), default="validation")
    parser.add_argument("--priors", nargs="+", choices=tuple(PRIOR_CLIPS),
                        default=list(PRIOR_CLIPS))
    parser.add_argument("--mirror", choices=("no", "yes", "both"), default="both",
                        help="train each prior without, with, or both (both)")
    parser.add_argument("--parts", choices=("no", "yes", "both"), default="both",
                        help="one GPLVM of the whole upper body, one per part, or both (both)")
    parser.add_argument("--back-constraints", nargs="+", default=["none"], metavar="WIDTH",
                        help="free latents (none) and/or back-constrained GPLVMs of these "
                             "kernel widths (fit_gplvm's back_constraint; default none)")
    parser.add_argument("--clips", nargs="+", default=None,
                        help="score only these of the split's clips (default all)")
    parser.add_argument("--views", type=int, default=3, help="viewpoints per held-out clip (3)")
    parser.add_argument("--stride", type=int, default=3,
                        help="score every stride-th held-out pose (3)")
    parser.add_argument("--steps", action="store_true",
                        help="also each held-out clip's latent steps in units of ν (frontal "
                             "view, every frame) and its marker speed")
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    if args.views < 1 or args.stride < 1:
        parser.error("--views and --stride must be at least 1")
    try:
        widths = [None if w == "none" else float(w) for w in args.back_constraints]
    except ValueError:
        parser.error(f"--back-constraints takes 'none' or positive widths, got "
                     f"{' '.join(args.back_constraints)}")
    if any(w is not None and not w > 0 for w in widths):
        parser.error(f"--back-constraints widths must be positive, got "
                     f"{' '.join(args.back_constraints)}")
    started = time.perf_counter()
    clips = held_out_clips(args.split)
    if args.clips:
        unknown = sorted(set(args.clips) - set(clips))
        if unknown:
            parser.error(f"--clips {' '.join(unknown)}: not a gesture clip of the "
                         f"{args.split} split")
        clips = tuple(args.clips)
    choices = {"no": (False,), "yes": (True,), "both": (False, True)}
    mirrors, parted = choices[args.mirror], choices[args.parts]
    print(f"{args.split} subjects' clips: {len(clips)} x {args.views} views; "
          f"{device_description()}")
    rows, trajectories = [], {}
    for name in tqdm(args.priors, desc="priors"):
        for mirror in mirrors:
            for parts in parted:
                for width in widths:
                    rows += evaluate_prior(name, mirror, parts, clips, args.views, args.stride,
                                           width, trajectories)
    print_table(rows, [("prior", "prior", "s"), ("training_poses", "training poses", "d"),
                       ("held_out_poses", "held-out poses", "d"), ("method", "method", "s"),
                       ("lengths", "link lengths", "s"), ("error_torso", "error/torso", ".1%"),
                       ("error_px", "error px", ".1f"),
                       ("error_p95_px", "p95 px", ".1f"), ("seconds", "s", ".1f")])
    smoothness = {tag: latent_smoothness(latents, ids)
                  for tag, (latents, ids) in trajectories.items()}
    print_table([{"prior": tag, **values} for tag, values in smoothness.items()],
                [("prior", "prior", "s"), ("median_step", "median step / spread", ".3f"),
                 ("p99_step", "p99 step / spread", ".2f"),
                 ("carried_range", "carried share a", "s")])
    steps = []
    if args.steps:
        for name in args.priors:
            for mirror in mirrors:
                for parts in parted:
                    for width in widths:
                        steps += held_out_steps(name, mirror, parts, clips, width)
        print_table(steps, [("prior", "prior", "s"), ("clip", "clip", "s"),
                            ("frames", "frames", "d"), ("median_nu", "median step / ν", ".2f"),
                            ("p90_nu", "p90 / ν", ".2f"), ("p99_nu", "p99 / ν", ".2f"),
                            ("over_3nu", "steps > 3 ν", ".0%"),
                            ("marker_speed", "fastest marker / torso per frame", ".3f")])
    path = args.json or str(RUNS / f"prior_generalisation_{args.split}.json")
    write_json(path, {"benchmark": "prior_generalisation",
                      **run_header("papers.tian2005.prior_generalisation", argv, started),
                      "split": args.split,
                      "clips": list(clips), "arguments": vars(args), "rows": rows,
                      "latent_smoothness": smoothness, "held_out_steps": steps})
    figure = Path(path).with_name("prior_latent_trajectories.png")
    plot_trajectories(trajectories, figure)
    print(f"wrote {path} and {figure}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
