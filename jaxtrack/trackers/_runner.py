"""Running any tracker over a video: chunks of one compiled scan, a progress bar, timings.

:func:`track` asks a tracker (``jaxtrack.trackers.Tracker``) to observe each chunk of the video
(``Tracker.observe``: its own preprocessing, on the host), starts it on frame 0 and scans its
``update`` over chunks of observations inside one ``jit`` (compiled once for the chunk shape,
the last chunk padded), so memory is bounded by the chunk, not the video. It never asks which
tracker it runs: every tracker gets each frame as a ``FrameInChunk`` and reads it from the chunk
in place, and observations are pytrees of any structure.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jaxtyping import Array, ArrayLike, Float, PRNGKeyArray
from tqdm.auto import tqdm

from jaxtrack.trackers._tracker import FrameEstimate, FrameInChunk, Tracker, VideoChunk

__all__ = ["TrackResult", "track"]


@dataclass(frozen=True)
class TrackResult:
    """A tracked sequence (NumPy arrays, frame 0 included).

    Attributes:
        markers, best_markers: ``(time, markers, 2)`` estimates per frame.
        ess, log_likelihood, degenerate: ``(time,)`` per-frame diagnostics.
        seconds_per_frame: run time per frame (observing and tracking), compilation excluded.
        compile_seconds: time to compile the chunk scan (0 where a compiled one was reused).
        num_particles: particles (modes) used.
        options: the tracker's ``options()``: the method and every option that produced it.
        estimates: every field of the tracker's per-frame estimate (its ``FrameEstimate``
            subclass) with a leading ``time`` axis.
        observe_seconds: of the run time, the time spent observing frames (preprocessing).
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
    estimates: FrameEstimate | None = None
    observe_seconds: float = 0.0


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


def _frame_bytes(observations) -> int:
    """Bytes of one frame of a chunk of observations (every leaf's frame)."""
    return sum(math.prod(np.shape(leaf)[1:]) * np.asarray(leaf).dtype.itemsize
               for leaf in jax.tree.leaves(observations))


def _frames_per_chunk(chunk_size: int, frame_bytes: int) -> int:
    """``chunk_size`` capped so that a chunk of frames of ``frame_bytes`` each fits
    :data:`CHUNK_BYTES` (never below one frame)."""
    return max(1, min(int(chunk_size), CHUNK_BYTES // max(int(frame_bytes), 1)))


def _num_frames(observations) -> int:
    leaves = jax.tree.leaves(observations)
    if not leaves:
        raise ValueError("the observations hold no arrays")
    lengths = {int(np.shape(leaf)[0]) if np.ndim(leaf) else -1 for leaf in leaves}
    if len(lengths) != 1 or -1 in lengths:
        raise ValueError(f"every leaf of the observations needs the same leading time axis, "
                         f"got leading sizes {sorted(lengths)}")
    return lengths.pop()


def _video_chunks(frames, masks, keypoints, chunk_size: int) -> tuple[Iterator, int | None]:
    """``(chunks, number of frames or None)`` of what :func:`track` was given: a
    :class:`VideoChunk` per ``chunk_size`` frames, or, for observations made beforehand, the
    observations themselves cut into chunks."""
    if isinstance(frames, VideoChunk):
        if masks is not None or keypoints is not None:
            raise ValueError("give masks and keypoints inside the VideoChunk, not beside it")
        video = frames
    elif isinstance(frames, eqx.Module):  # observations made beforehand
        if masks is not None or keypoints is not None:
            raise ValueError("observations made beforehand carry their own masks and "
                             "keypoints: leave masks= and keypoints= out")
        count = _num_frames(frames)
        return ((False, jax.tree.map(lambda leaf, cut=slice(begin, begin + chunk_size):
                                     leaf[cut], frames))
                for begin in range(0, count, chunk_size)), count
    elif isinstance(frames, np.ndarray | jax.Array | list | tuple):
        video = VideoChunk(grey=np.asarray(frames), masks=masks, keypoints=keypoints)
    else:  # a stream of VideoChunks (a video decoded chunk by chunk)
        if masks is not None or keypoints is not None:
            raise ValueError("give masks and keypoints inside each VideoChunk of a stream")
        return ((True, chunk) for chunk in frames), None
    count = len(video)
    return ((True, video.frames(begin, begin + chunk_size))
            for begin in range(0, count, chunk_size)), count


def _check_video(video: VideoChunk) -> None:
    """Refuse a video whose parts disagree in length or hold non-finite grey levels (all of it,
    before anything runs)."""
    count = len(video)
    for name in ("grey", "colour", "masks"):
        value = getattr(video, name)
        if value is not None and np.shape(value)[0] != count:
            raise ValueError(f"{name} must be one per frame of the video: they hold "
                             f"{np.shape(value)[0]} frames, the video {count}")
    if video.keypoints is not None:
        from jaxtrack.vision.keypoints import check_keypoint_input

        check_keypoint_input(video.keypoints, num_frames=count)
    if video.masks is not None and video.grey is not None and np.ndim(video.grey) == 3:
        from jaxtrack.vision.masks import check_masks

        check_masks(video.masks, np.shape(video.grey))
    if video.grey is not None and np.size(video.grey) and not np.all(
            np.isfinite(np.asarray(video.grey[:1]))):
        raise ValueError("frames hold non-finite values")


_COMPILED: dict = {}


def _compiled(function, *args):
    """``function`` compiled ahead of time for ``args`` (so that compilation is timed apart),
    kept per structure and shapes: runs of one chunk shape reuse it. Returns ``(executable,
    seconds spent compiling)``, 0 when reused."""
    leaves, structure = jax.tree.flatten(args)
    signature = (function, structure, tuple(
        (np.shape(leaf), str(jnp.result_type(leaf))) if eqx.is_array(leaf) else leaf
        for leaf in leaves))
    try:
        hash(signature)
    except TypeError:  # an unhashable static leaf: compile afresh
        signature = None
    if signature is not None and signature in _COMPILED:
        return _COMPILED[signature], 0.0
    if len(_COMPILED) > 48:  # a sweep over shapes should not hold every executable
        _COMPILED.clear()
    tick = time.perf_counter()
    executable = function.lower(*args).compile()
    if signature is not None:
        _COMPILED[signature] = executable
    return executable, time.perf_counter() - tick


def release_compiled() -> None:
    """Forget the executables :func:`track` compiled ahead of time (as ``jax.clear_caches``
    forgets ``jax.jit``'s): each holds memory mappings, of which a process may hold a limited
    number."""
    _COMPILED.clear()


def _aligned_like(observations, frames: int):
    """Uninitialised aligned host buffers shaped like ``observations`` with ``frames`` frames."""
    return jax.tree.map(lambda leaf: _aligned_empty((frames, *np.shape(leaf)[1:]),
                                                    np.asarray(leaf).dtype), observations)


@eqx.filter_jit
def _start_estimate(tracker, state):
    return tracker.first_estimate(state)


@eqx.filter_jit
def _chunk(tracker, state, keys, frames):
    def body(state, inputs):
        key, index = inputs
        return tracker.update(key, state, FrameInChunk(frames, index))

    return jax.lax.scan(body, state, (keys, jnp.arange(keys.shape[0])))


def track(tracker: Tracker, key: PRNGKeyArray,
          frames: Float[ArrayLike, "time height width"] | VideoChunk | eqx.Module
          | Iterable[VideoChunk],
          initial_pose: Float[ArrayLike, "markers 2"] | None = None, *, chunk_size: int = 64,
          progress: bool = True, description: str = "tracking",
          masks: np.ndarray | None = None,
          keypoints: tuple[np.ndarray, np.ndarray] | np.ndarray | None = None) -> TrackResult:
    """Track a video from ``initial_pose``, the ``(markers, 2)`` pose in frame 0 (None for
    trackers that start from the first frame alone).

    Args:
        tracker: any :class:`jaxtrack.trackers.Tracker`.
        key: PRNG key.
        frames: the video: ``(time, height, width)`` grey frames (the image trackers also take
            ``(time, 3 or 4, height, width)`` edge observations made beforehand), a
            :class:`VideoChunk` holding whatever the tracker reads (``tracker.reads``), an
            iterable of :class:`VideoChunk` (a video decoded chunk by chunk: memory bounded by
            the chunk), or the tracker's own observations made beforehand (a pytree whose
            leaves have a leading ``time`` axis).
        masks: ``(time, height, width)`` bool person masks of grey ``frames``.
        keypoints: a per-frame detector's keypoints of grey ``frames``, ``(points (time, 12,
            2), confidence (time, 12))`` in their pixels, or the points alone (NaN where not
            found; :mod:`jaxtrack.vision.keypoints`).
        chunk_size: frames per compiled chunk (fewer where a chunk would pass
            :data:`CHUNK_BYTES`).

    Each chunk is observed by the tracker (``tracker.observe``, counted in the run time and in
    ``observe_seconds``), then frames after the first run in equal chunks through one compiled
    scan; the last chunk is padded by repeating its final frame and the padding's output is
    dropped. The result does not depend on the chunk size.
    """
    if not isinstance(tracker, Tracker):
        raise TypeError(f"tracker must be a jaxtrack.trackers.Tracker, got "
                        f"{type(tracker).__name__}")
    if not isinstance(chunk_size, int) or chunk_size < 1:
        raise ValueError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    chunks, num_frames = _video_chunks(frames, masks, keypoints, chunk_size)
    if num_frames is not None and num_frames < 1:
        raise ValueError("frames hold no frame")
    if isinstance(frames, VideoChunk) or (num_frames is not None
                                          and not isinstance(frames, eqx.Module)):
        _check_video(frames if isinstance(frames, VideoChunk)
                     else VideoChunk(grey=np.asarray(frames), masks=masks,
                                     keypoints=keypoints))
    key_start, key_frames = jr.split(key)
    frame_keys = None if num_frames is None else jr.split(key_frames, max(num_frames - 1, 1))
    observe_seconds = 0.0

    def observed(item, out=None):
        nonlocal observe_seconds
        is_video, chunk = item
        if not is_video:
            return chunk
        tick = time.perf_counter()
        result = tracker.observe(chunk, out=out)
        observe_seconds += time.perf_counter() - tick
        return result

    def keys_for(begin: int, count: int) -> Array:
        """Keys of frames ``begin .. begin + count − 1`` (≥ 1)."""
        if frame_keys is not None:
            return frame_keys[begin - 1:begin - 1 + count]
        return jax.vmap(lambda index: jr.fold_in(key_frames, index))(
            jnp.arange(begin, begin + count))

    chunks = iter(chunks)
    first_item = next(chunks, None)
    if first_item is None:
        raise ValueError("frames hold no frame")
    head = observed(first_item)
    head_seconds = observe_seconds  # the first chunk's frames after frame 0 count as run time
    if _num_frames(head) < 1:
        raise ValueError("frames hold no frame")
    state = tracker.start(key_start, jax.tree.map(lambda leaf: leaf[0], head), initial_pose)
    first = _start_estimate(tracker, state)
    outputs = [jax.tree.map(lambda leaf: np.asarray(leaf)[None], first)]
    chunk_size = _frames_per_chunk(chunk_size, _frame_bytes(head))
    if num_frames is not None:  # equal chunks, so that little of the last one is padding
        num_chunks = max(1, math.ceil((num_frames - 1) / chunk_size))
        chunk_size = max(1, math.ceil((num_frames - 1) / num_chunks))

    def pieces() -> Iterator:
        """The observations after frame 0 in pieces of at most ``chunk_size`` frames."""
        rest = jax.tree.map(lambda leaf: leaf[1:], head)
        items = chunks
        while True:
            count = _num_frames(rest)
            while count >= chunk_size:
                yield jax.tree.map(lambda leaf: leaf[:chunk_size], rest)
                rest = jax.tree.map(lambda leaf: leaf[chunk_size:], rest)
                count -= chunk_size
            item = next(items, None)
            if item is None:
                if count:
                    yield rest
                return
            more = observed(item)
            rest = more if count == 0 else jax.tree.map(
                lambda a, b: np.concatenate([a, b]), rest, more)

    # Observations reach the compiled scan through 64-byte aligned host buffers, reused from
    # chunk to chunk, which jax.device_put hands to XLA on CPU without a copy:
    # jnp.asarray(chunk) would copy each chunk into freshly allocated memory, ~1–2 ms per
    # 640 × 480 frame (page faults), several times the latent tracker's step. Two buffers, so
    # that the next chunk is copied in while the current one is tracked.
    buffers: list = []

    def stage(piece, index: int):
        count = _num_frames(piece)
        if len(buffers) < 2:
            buffers.append(_aligned_like(piece, chunk_size))
        buffer = buffers[index % 2]

        def fill(target, source):
            target[:count] = source
            target[count:] = source[count - 1]  # padding repeats the last frame
            return target

        return jax.device_put(jax.tree.map(fill, buffer, piece)), count

    def collect(estimates, count: int) -> None:
        # converting the estimates waits for their chunk, after which its buffer may be reused
        outputs.append(jax.tree.map(lambda leaf: np.asarray(leaf)[:count], estimates))
        bar.update(count)

    bar = tqdm(total=num_frames, desc=description, unit="frame", disable=not progress,
               dynamic_ncols=True)
    bar.update(1)
    compile_seconds, pending, begin = 0.0, None, 1
    tick = time.perf_counter()
    for index, piece in enumerate(pieces()):
        chunk, count = stage(piece, index)
        keys = keys_for(begin, count)
        if count < chunk_size:  # pad to the compiled shape
            keys = jnp.concatenate([keys, jr.split(keys[-1], chunk_size - count)])
        arguments = (tracker, state, keys, chunk)
        compiled, seconds = _compiled(_chunk, *arguments)
        compile_seconds += seconds
        new_state, estimates = compiled(*arguments)  # runs asynchronously
        if count == chunk_size:
            state = new_state
        if pending is not None:
            collect(*pending)  # the previous chunk, whose buffer the next one reuses
        pending = (estimates, count)
        begin += count
    if pending is not None:
        collect(*pending)
    run_seconds = time.perf_counter() - tick - compile_seconds + head_seconds
    bar.close()
    merged = jax.tree.map(lambda *leaves: np.concatenate(leaves), *outputs)
    total = _num_frames(merged.markers)
    return TrackResult(
        markers=merged.markers, best_markers=merged.best_markers, ess=merged.ess,
        log_likelihood=merged.log_likelihood, degenerate=merged.degenerate,
        seconds_per_frame=run_seconds / max(total - 1, 1), compile_seconds=compile_seconds,
        num_particles=int(tracker.num_particles), options=tracker.options(), estimates=merged,
        observe_seconds=observe_seconds)
