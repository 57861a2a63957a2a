"""Running any tracker over a video: chunks of one compiled scan, a progress bar, timings.

:func:`track` starts a tracker (``jaxtrack.trackers.Tracker``) on frame 0 and scans its
``update`` over chunks of frames inside one ``jit`` (compiled once for the chunk shape, the last
chunk padded), so memory is bounded by the chunk, not the video. It never asks which tracker it
runs: every tracker gets each frame as a ``FrameInChunk`` and reads it from the chunk in place.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray
from tqdm.auto import tqdm

from jaxtrack.likelihoods import check_observations
from jaxtrack.trackers._tracker import FrameInChunk, Tracker

__all__ = ["TrackResult", "track"]


@dataclass(frozen=True)
class TrackResult:
    """A tracked sequence (NumPy arrays, frame 0 included).

    Attributes:
        markers, best_markers: ``(time, markers, 2)`` estimates per frame.
        ess, log_likelihood, degenerate: ``(time,)`` per-frame diagnostics.
        seconds_per_frame: run time per frame, compilation excluded.
        compile_seconds: time to compile the chunk scan.
        num_particles: particles (modes) used.
        options: the tracker's ``options()``: the method and every option that produced it.
    """

    markers: np.ndarray
    best_markers: np.ndarray
    ess: np.ndarray
    log_likelihood: np.ndarray
    degenerate: np.ndarray
    seconds_per_frame: float
    compile_seconds: float
    num_particles: int
    options: dict


def _aligned_empty(shape: tuple[int, ...], dtype, alignment: int = 64) -> np.ndarray:
    """An uninitialised C-contiguous NumPy array whose data start on an ``alignment``-byte
    boundary (XLA's CPU client aliases such host memory instead of copying it)."""
    dtype = np.dtype(dtype)
    size = math.prod(shape) * dtype.itemsize
    raw = np.empty(size + alignment, np.uint8)
    offset = -raw.ctypes.data % alignment
    return raw[offset:offset + size].view(dtype).reshape(shape)


CHUNK_BYTES = 256 * 2**20
"""The most bytes of observations one of :func:`track`'s two chunk buffers holds: 64 grey or
edge-map frames at 640 × 480 fit (3.7 MB each with edge maps), 960 × 544 edge maps take 40."""


def _frames_per_chunk(chunk_size: int, frame_shape: tuple[int, ...], dtype) -> int:
    """``chunk_size`` capped so that a chunk of frames of ``frame_shape`` fits CHUNK_BYTES."""
    frame_bytes = math.prod(frame_shape) * np.dtype(dtype).itemsize
    return max(1, min(int(chunk_size), CHUNK_BYTES // max(frame_bytes, 1)))


def _edge_observations(frames: np.ndarray, out: np.ndarray | None = None,
                       masks: np.ndarray | None = None,
                       keypoints: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    from jaxtrack.vision import edge_observations

    return edge_observations(frames, out=out, masks=masks, keypoints=keypoints)


def _copy_frames(frames: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    if out is None:
        return np.asarray(frames)
    out[...] = frames
    return out


@eqx.filter_jit
def _first_estimate(tracker, state):
    return tracker.first_estimate(state)


@eqx.filter_jit
def _chunk(tracker, state, keys, frames):
    def body(state, inputs):
        key, index = inputs
        return tracker.update(key, state, FrameInChunk(frames, index))

    return jax.lax.scan(body, state, (keys, jnp.arange(frames.shape[0])))


def track(tracker: Tracker, key: PRNGKeyArray, frames: Float[Array, "time height width"],
          initial_pose: Float[ArrayLike, "markers 2"], *, chunk_size: int = 64,
          progress: bool = True, description: str = "tracking",
          masks: np.ndarray | None = None,
          keypoints: tuple[np.ndarray, np.ndarray] | np.ndarray | None = None) -> TrackResult:
    """Track ``frames`` (grey) from ``initial_pose``, the ``(markers, 2)`` pose in frame 0.

    A tracker scored by ``"limbs+edges"`` also needs each frame's edge maps: they are computed
    here chunk by chunk (``jaxtrack.vision.edge_observations``, OpenCV, counted in the run
    time), or may be given, ``frames`` being ``(time, 3, height, width)`` (or ``(time, 4,
    height, width)`` with the person's mask). ``masks``: ``(time, height, width)`` bool person
    masks of grey ``frames``, added to each chunk's edge maps as the foreground term's
    per-frame mask (``jaxtrack.likelihoods.edges``). ``keypoints``: a per-frame detector's
    keypoints of grey ``frames``, ``(points (time, 12, 2), confidence (time, 12))`` in their
    pixels, or the points alone (NaN where not found; :mod:`jaxtrack.vision.keypoints`), for
    the likelihood's keypoint term (``Likelihood(keypoint_weight=...)``), which needs them.

    Frames after the first run in equal chunks of at most ``chunk_size`` frames (fewer for
    frames so large that a chunk would pass :data:`CHUNK_BYTES`) through one compiled scan;
    the last chunk is padded by repeating its final frame and the padding's output is dropped.
    The result does not depend on the chunk size.
    """
    if not isinstance(tracker, Tracker):
        raise TypeError(f"tracker must be a jaxtrack.trackers.Tracker, got "
                        f"{type(tracker).__name__}")
    frames = np.asarray(frames)
    add_edges = check_observations(tracker.likelihood.kind, frames.shape)
    if frames.shape[0] < 1:
        raise ValueError("frames hold no frame")
    if not np.all(np.isfinite(frames[:1])):
        raise ValueError("frames hold non-finite values")
    likelihood = tracker.likelihood
    if add_edges:
        with_keypoints, with_mask = keypoints is not None, masks is not None
    else:  # observations made beforehand: channels beyond the edge maps (mask, keypoints)
        extra = frames.shape[1] - 3 if frames.ndim == 4 else 0
        with_keypoints = likelihood.has_keypoints and extra >= 1
        with_mask = extra - with_keypoints >= 1
    if likelihood.has_coverage and not with_mask:
        raise ValueError("the likelihood's coverage term (coverage_weight) reads the person's "
                         "masks: give masks=..., or observations with a mask channel")
    if likelihood.has_keypoints and not with_keypoints:
        raise ValueError("the likelihood's keypoint term (keypoint_weight) reads a detector's "
                         "keypoints: give keypoints=..., or observations with a keypoint channel")
    if keypoints is not None and not likelihood.has_keypoints:
        raise ValueError("keypoints are read by the likelihood's keypoint term only: give "
                         "Likelihood(keypoint_weight=...) or leave keypoints out")
    if keypoints is not None:
        from jaxtrack.vision.keypoints import check_keypoint_input

        if not add_edges:
            raise ValueError("keypoints go with grey frames and the 'limbs+edges' likelihood "
                             "(edge observations made beforehand carry their own keypoints)")
        keypoints = check_keypoint_input(keypoints, num_frames=frames.shape[0])
    if masks is not None:
        from jaxtrack.vision.masks import check_masks

        if not add_edges:
            raise ValueError("masks go with grey frames and the 'limbs+edges' likelihood (edge "
                             "observations made beforehand carry their own mask channel)")
        masks = check_masks(masks, frames.shape)  # all of them, before anything runs
    num_frames = frames.shape[0]
    key_start, key_frames = jr.split(key)

    def observe(begin: int, count: int, out: np.ndarray | None = None) -> np.ndarray:
        if not add_edges:
            return _copy_frames(frames[begin:begin + count], out=out)
        return _edge_observations(
            frames[begin:begin + count], out=out,
            masks=None if masks is None else masks[begin:begin + count],
            keypoints=None if keypoints is None else tuple(
                values[begin:begin + count] for values in keypoints))

    state = tracker.start(key_start, observe(0, 1)[0], initial_pose)
    first = _first_estimate(tracker, state)
    outputs = [jax.tree.map(lambda leaf: np.asarray(leaf)[None], first)]
    channels = 3 + (masks is not None) + (keypoints is not None)
    shape, dtype = (((channels, *frames.shape[1:]), np.float32) if add_edges
                    else (frames.shape[1:], jax.dtypes.canonicalize_dtype(frames.dtype)))
    chunk_size = _frames_per_chunk(chunk_size, shape, dtype)
    # equal chunks of at most chunk_size frames, so that little of the last one is padding
    num_chunks = max(1, math.ceil((num_frames - 1) / max(1, chunk_size)))
    chunk_size = max(1, math.ceil((num_frames - 1) / num_chunks))
    keys = jr.split(key_frames, max(num_frames - 1, 1))
    begins = list(range(1, num_frames, chunk_size))
    counts = [min(chunk_size, num_frames - begin) for begin in begins]
    chunk_keys = [keys[begin - 1:begin - 1 + count] for begin, count in zip(begins, counts,
                                                                            strict=True)]
    if begins and counts[-1] < chunk_size:  # pad to the compiled shape
        chunk_keys[-1] = jnp.concatenate(
            [chunk_keys[-1], jr.split(chunk_keys[-1][-1], chunk_size - counts[-1])])
    # Frames reach the compiled scan through 64-byte aligned host buffers, reused from chunk
    # to chunk, which jax.device_put hands to XLA on CPU without a copy: jnp.asarray(chunk)
    # would copy each chunk into freshly allocated memory, ~1–2 ms per 640 × 480 frame (page
    # faults), several times the latent tracker's step. Two buffers, so that the next chunk
    # is copied in while the current one is tracked.
    buffers = [_aligned_empty((chunk_size, *shape), dtype) for _ in range(min(2, len(begins)))]

    def stage(index: int) -> Array:
        buffer, begin, count = buffers[index % 2], begins[index], counts[index]
        observe(begin, count, out=buffer[:count])
        buffer[count:] = buffer[count - 1]  # padding repeats the last frame
        return jax.device_put(buffer)

    def collect(estimates, count: int) -> None:
        # converting the estimates waits for their chunk, after which its buffer may be reused
        outputs.append(jax.tree.map(lambda leaf: np.asarray(leaf)[:count], estimates))
        bar.update(count)

    bar = tqdm(total=num_frames, desc=description, unit="frame", disable=not progress,
               dynamic_ncols=True)
    bar.update(1)
    compile_seconds, pending = 0.0, None
    tick = time.perf_counter()
    chunk = stage(0) if begins else None
    for index, count in enumerate(counts):
        arguments = (tracker, state, chunk_keys[index], chunk)
        if index == 0:  # compile ahead of time, so that compilation is timed apart
            compile_tick = time.perf_counter()
            compiled = _chunk.lower(*arguments).compile()
            compile_seconds = time.perf_counter() - compile_tick
        new_state, estimates = compiled(*arguments)  # runs asynchronously
        if count == chunk_size:
            state = new_state
        if pending is not None:
            collect(*pending)  # the previous chunk, whose buffer the next one reuses
        if index + 1 < len(begins):
            chunk = stage(index + 1)
        pending = (estimates, count)
    if pending is not None:
        collect(*pending)
    run_seconds = time.perf_counter() - tick - compile_seconds
    bar.close()
    merged = jax.tree.map(lambda *leaves: np.concatenate(leaves), *outputs)
    return TrackResult(
        markers=merged.markers, best_markers=merged.best_markers, ess=merged.ess,
        log_likelihood=merged.log_likelihood, degenerate=merged.degenerate,
        seconds_per_frame=run_seconds / max(num_frames - 1, 1), compile_seconds=compile_seconds,
        num_particles=int(tracker.num_particles), options=tracker.options(),
    )
