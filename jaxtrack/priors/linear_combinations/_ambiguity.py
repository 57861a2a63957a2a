"""How ambiguous a view is: Ong & Gong's (2002, §5.5–5.7) ambiguity of hybrid vectors, and view
selection.

A view is ambiguous where one silhouette (contour and hands) is shared by different 3-D
skeletons. For training vector i, with d_ob(i, j) the distance between the observation parts
(contour and hands) of vectors i and j and d_s(i, j) that between their skeletons:

    G(d_ob, σ) = exp(−d_ob² / 2σ²)                             similar observations (eq. 11)
    S(d_s) = 1 / (1 + exp(−β (d_s − t)))                       different skeletons (eq. 12)
    a_i = Σ_{j ≠ i} G(d_ob(i, j), σ) S(d_s(i, j))              ambiguity (eq. 10, 13)

A new vector (a tracker's estimate) takes the ambiguity of its nearest training vector in the
observation part (eq. 14). With several calibrated views, each frame is read from the view that
maximises fitness × 1/ambiguity (§5.7): ``select_views``.

d_ob is the root-mean-square distance between corresponding contour and hand points (pixels),
d_s the mean distance between corresponding skeleton vertices (the skeleton's units, metres).
NumPy on the host: ambiguities are computed once per training set and once per frame and view.
"""

from __future__ import annotations

import numpy as np

from jaxtrack.body.hybrid import HybridLayout

__all__ = ["nearest_ambiguity", "select_views", "training_ambiguity", "view_scores"]

_MEMORY_BUDGET = 128 * 2**20  # bytes training_ambiguity's temporaries hold at most by default


def _parts(vectors: np.ndarray, layout: HybridLayout) -> tuple[np.ndarray, np.ndarray]:
    vectors = np.asarray(vectors, np.float64)
    if vectors.ndim != 2 or vectors.shape[1] != layout.size:
        raise ValueError(f"vectors must be (examples, {layout.size}) hybrid vectors, got shape "
                         f"{vectors.shape}")
    if not np.all(np.isfinite(vectors)):
        raise ValueError("vectors hold non-finite values")
    observed = vectors[:, :layout.skeleton_slice.start]
    skeleton = vectors[:, layout.skeleton_slice].reshape(len(vectors), layout.num_skeleton, 3)
    return observed, skeleton


def _observation_distances(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """RMS point distance between observation parts: ``(len(first), len(second))``."""
    points = first.shape[1] / 2
    squared = (np.sum(first**2, axis=1)[:, None] + np.sum(second**2, axis=1)[None]
               - 2 * first @ second.T)
    return np.sqrt(np.maximum(squared, 0.0) / points)


def _pair_bytes(layout: HybridLayout) -> int:
    """Peak bytes of temporaries per pair (i, j) of a block, as measured with tracemalloc: the
    skeleton differences and their squares (joints × 3 float64 each), the squared and the
    root distances per joint (joints each), and four (rows, examples) float64 arrays."""
    return 8 * (8 * layout.num_skeleton + 4)


def training_ambiguity(vectors: np.ndarray, layout: HybridLayout, *, sigma: float = 4.0,
                       beta: float = 100.0, threshold: float = 0.05, chunk: int | None = None
                       ) -> np.ndarray:
    """Ong & Gong eq. 10–13: the ambiguity a_i of every training vector (module docstring).

    Args:
        vectors: ``(examples, layout.size)`` hybrid vectors.
        layout: their part sizes.
        sigma: σ of G, pixels (how alike two observations must be to be confused).
        beta: β of the sigmoid, per skeleton unit (its steepness).
        threshold: t, the skeleton distance (metres) from which two skeletons count as
            different.
        chunk: rows i per block; the block's temporaries peak at chunk × examples ×
            8 (8 joints + 4) bytes (2.4 MB per row at 3000 examples of 12 joints). None:
            as many rows as fit in 128 MiB (at least one row, however large the set). The
            result does not depend on it beyond rounding.

    Returns:
        ``(examples,)`` ambiguities, ≥ 0.
    """
    if not (sigma > 0 and beta > 0 and threshold >= 0):
        raise ValueError(f"sigma and beta must be > 0 and threshold >= 0, got {sigma}, {beta}, "
                         f"{threshold}")
    observed, skeleton = _parts(vectors, layout)
    if chunk is None:
        chunk = max(1, _MEMORY_BUDGET // (max(1, len(vectors)) * _pair_bytes(layout)))
    elif not (isinstance(chunk, int | np.integer) and chunk >= 1):
        raise ValueError(f"chunk must be a positive integer or None, got {chunk!r}")
    flat = skeleton.reshape(len(skeleton), -1)
    result = np.empty(len(vectors))
    for start in range(0, len(vectors), chunk):
        stop = min(start + chunk, len(vectors))
        similar = np.exp(-_observation_distances(observed[start:stop], observed) ** 2
                         / (2 * sigma**2))  # eq. 11
        distance = np.linalg.norm(skeleton[start:stop, None] - skeleton[None], axis=-1).mean(
            axis=-1) if len(vectors) * (stop - start) * flat.shape[1] < 5e8 else None
        if distance is None:  # very large sets: one row at a time
            distance = np.stack([np.linalg.norm(skeleton[i] - skeleton, axis=-1).mean(axis=-1)
                                 for i in range(start, stop)])
        different = 0.5 * (1 + np.tanh(0.5 * beta * (distance - threshold)))  # eq. 12 sigmoid
        terms = similar * different
        terms[np.arange(stop - start), np.arange(start, stop)] = 0.0  # j ≠ i
        result[start:stop] = terms.sum(axis=1)  # eq. 10, 13
    return result


def nearest_ambiguity(vectors: np.ndarray, training_vectors: np.ndarray,
                      ambiguities: np.ndarray, layout: HybridLayout) -> np.ndarray:
    """Ong & Gong eq. 14: each vector's ambiguity is that of its nearest training vector in the
    observation part (contour and hands). Returns ``(vectors,)``."""
    observed, _ = _parts(np.atleast_2d(vectors), layout)
    training, _ = _parts(training_vectors, layout)
    ambiguities = np.asarray(ambiguities, np.float64)
    if ambiguities.shape != (len(training),):
        raise ValueError(f"ambiguities must hold one value per training vector ({len(training)})"
                         f", got shape {ambiguities.shape}")
    nearest = np.argmin(_observation_distances(observed, training), axis=1)
    return ambiguities[nearest]


def view_scores(log_fitness: np.ndarray, ambiguity: np.ndarray, found: np.ndarray | None = None,
                *, fitness_weight: float = 1.0, ambiguity_weight: float = 1.0, window: int = 0,
                floor: float = 1e-3) -> np.ndarray:
    """Each view's score per frame: ``fitness_weight`` × log f − ``ambiguity_weight`` ×
    log(ambiguity + ``floor``), averaged over ±``window`` frames (those that exist). Weights
    of 1 and 1 are Ong & Gong's fitness × 1/ambiguity (§5.7).

    Args:
        log_fitness: ``(time, views)`` log f of each view's estimate.
        ambiguity: ``(time, views)`` its ambiguity (eq. 14).
        found: ``(time, views)`` whether each view observed the frame; a view that did not (or
            whose log f is not finite) scores −inf there, and its values there do not enter
            the window of the frames beside it.
        fitness_weight, ambiguity_weight: ≥ 0, not both 0.
        window: frames on each side over which a view's score is averaged (0: the frame's
            own); a single frame's fluke of fitness then does not switch the view.
        floor: added to the ambiguity so that an unambiguous view (a = 0) is not infinitely
            preferred over the fitness.

    Returns:
        ``(time, views)`` scores; NaN scores are −inf.
    """
    log_fitness = np.asarray(log_fitness, np.float64)
    ambiguity = np.asarray(ambiguity, np.float64)
    if log_fitness.shape != ambiguity.shape or log_fitness.ndim != 2:
        raise ValueError(f"log_fitness {log_fitness.shape} and ambiguity {ambiguity.shape} must "
                         "both be (time, views)")
    if not floor > 0:
        raise ValueError(f"floor must be > 0, got {floor}")
    if not (fitness_weight >= 0 and ambiguity_weight >= 0
            and fitness_weight + ambiguity_weight > 0):
        raise ValueError(f"fitness_weight and ambiguity_weight must be >= 0 and not both 0, got "
                         f"{fitness_weight} and {ambiguity_weight}")
    if not (isinstance(window, int | np.integer) and window >= 0):
        raise ValueError(f"window must be a whole number of frames >= 0, got {window!r}")
    seen = np.isfinite(log_fitness)
    if found is not None:
        seen &= np.asarray(found, bool)
    log_fitness = np.where(seen, log_fitness, 0.0)
    ambiguity = np.where(seen, np.maximum(ambiguity, 0.0), 0.0)
    score = fitness_weight * log_fitness - ambiguity_weight * np.log(ambiguity + floor)
    if window:  # sums over [t − window, t + window] from cumulative sums
        frames = np.arange(len(score))
        low, high = np.maximum(frames - window, 0), np.minimum(frames + window + 1, len(score))

        def windowed(values):
            cumulative = np.concatenate([np.zeros((1, values.shape[1])),
                                         np.cumsum(values, axis=0)])
            return cumulative[high] - cumulative[low]

        score = windowed(np.where(seen, score, 0.0)) / np.maximum(windowed(seen * 1.0), 1.0)
    score = np.where(seen, score, -np.inf)
    return np.where(np.isnan(score), -np.inf, score)


def select_views(log_fitness: np.ndarray, ambiguity: np.ndarray, found: np.ndarray | None = None,
                 *, fitness_weight: float = 1.0, ambiguity_weight: float = 1.0, window: int = 0,
                 floor: float = 1e-3) -> np.ndarray:
    """Per frame, the view of greatest :func:`view_scores` (by default Ong & Gong §5.7: the
    greatest fitness × 1/ambiguity); a view that did not observe the frame is never chosen
    unless none did (then view 0).

    Returns:
        ``(time,)`` the chosen view per frame.
    """
    return np.argmax(view_scores(log_fitness, ambiguity, found, fitness_weight=fitness_weight,
                                 ambiguity_weight=ambiguity_weight, window=window, floor=floor),
                     axis=1)
