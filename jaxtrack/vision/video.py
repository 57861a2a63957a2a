"""Video files in, RGB frames out (whole clips, bounded-memory chunks, grey-level images), and
RGB frames out to a video file.

:func:`read_video` decodes a file (anything OpenCV's FFmpeg backend reads: mp4, avi, mov, ...)
into one ``(time, height, width, 3)`` uint8 RGB array; :func:`iter_video_chunks` yields the same
frames a chunk at a time, so a long video never has to fit in memory. Frames can be skipped
(``start``, ``stride``), counted (``max_frames``) and resized (``scale``) while decoding.
:func:`to_grey` turns RGB frames into the float grey images the NCC likelihood samples.

Frames are read in order and skipped with ``grab`` (decode without colour conversion), never by
seeking: seeking by frame number lands on the nearest key frame in many codecs, so the frame
indices reported would be wrong.

:func:`write_frames` encodes RGB frames as an mp4 (OpenCV `mp4v`), atomically: a failed write
leaves no partial file.

OpenCV is imported inside the functions, so importing this module needs no cv2. Where OpenCV
sits among the layers: ``docs/layers.md``.
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jaxtrack._files import write_atomically

__all__ = ["VideoError", "VideoFrames", "iter_video_chunks", "read_video", "to_grey",
           "write_frames"]

# ITU-R BT.601 luma weights, the ones cv2.COLOR_RGB2GRAY uses
_LUMA = np.array([0.299, 0.587, 0.114], np.float32)


class VideoError(ValueError):
    """A video file is missing, not a video OpenCV can decode, or has no frames to read.

    The message names the file and what is wrong with it.
    """


@dataclass(frozen=True, eq=False)
class VideoFrames:
    """Frames decoded from a video file.

    Attributes:
        frames: ``(time, height, width, 3)`` uint8 RGB (``(time, height, width)`` float32 grey
            levels from ``iter_video_chunks(..., grey=True)``).
        fps: frames per second of *these* frames: the file's rate divided by ``stride`` (NaN when
            the file does not say its rate), so consecutive frames are ``1 / fps`` seconds apart.
        path: the file the frames come from.
        frame_indices: ``(time,)`` int64 index of each frame in the file (0 = the file's first).
        source_fps: the file's own frame rate (NaN when unknown).
    """

    frames: np.ndarray
    fps: float
    path: Path
    frame_indices: np.ndarray
    source_fps: float = math.nan

    @property
    def num_frames(self) -> int:
        return self.frames.shape[0]

    @property
    def image_size(self) -> tuple[int, int]:
        """``(width, height)``."""
        return self.frames.shape[2], self.frames.shape[1]

    @property
    def times(self) -> np.ndarray:
        """``(time,)`` seconds from the file's first frame (NaN when the rate is unknown)."""
        return self.frame_indices / self.source_fps


def _check_options(start: int, max_frames: int | None, stride: int, scale: float) -> None:
    if start < 0:
        raise ValueError(f"start must be a frame index ≥ 0, got {start}")
    if max_frames is not None and max_frames < 1:
        raise ValueError(f"max_frames must be ≥ 1 (or None for all frames), got {max_frames}")
    if stride < 1:
        raise ValueError(f"stride must be ≥ 1 (1 reads every frame), got {stride}")
    if not scale > 0 or not math.isfinite(scale):
        raise ValueError(f"scale must be a positive resize factor, got {scale}")


@contextlib.contextmanager
def _quiet_opencv():
    """Keep FFmpeg's and OpenCV's own log lines (``moov atom not found``, ``Could not open
    codec``) off stderr while a video is opened or written: every failure there becomes a
    ``VideoError``/``OSError`` that names the file, so the lines only repeat it, before it.

    FFmpeg reads ``OPENCV_FFMPEG_LOGLEVEL`` once, when the process opens its first video, so
    it is set (to quiet) if the user has not set it; OpenCV's log level is lowered for the
    duration only, unless the user set ``OPENCV_LOG_LEVEL``.
    """
    import cv2

    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET
    if "OPENCV_LOG_LEVEL" in os.environ:
        yield
        return
    logging = cv2.utils.logging
    previous = logging.getLogLevel()
    logging.setLogLevel(logging.LOG_LEVEL_SILENT)
    try:
        yield
    finally:
        logging.setLogLevel(previous)


def _open(path: Path):
    """An opened ``cv2.VideoCapture`` and the file's frame rate; VideoError if it cannot be."""
    import cv2

    if not path.exists():
        raise VideoError(f"{path}: no such video file")
    if not path.is_file():
        raise VideoError(f"{path}: not a file (a video file is needed)")
    with _quiet_opencv():
        capture = cv2.VideoCapture(str(path))
    if not capture.isOpened():
        capture.release()
        raise VideoError(f"{path}: OpenCV cannot open it as a video (not a video file, damaged, "
                         f"or in a format this OpenCV build does not decode)")
    fps = float(capture.get(cv2.CAP_PROP_FPS))
    return capture, fps if fps > 0 and math.isfinite(fps) else math.nan


def frame_count(path: str | os.PathLike) -> int | None:
    """The number of frames the video's container states (None where it states none): what
    a command checks per-frame inputs against before decoding. Containers may round it; the
    frames decoded are the truth."""
    import cv2

    capture, _ = _open(Path(path))
    try:
        count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT))
    finally:
        capture.release()
    return count if count > 0 else None


def _resize(frame: np.ndarray, scale: float) -> np.ndarray:
    import cv2

    if scale == 1.0:
        return frame
    height, width = frame.shape[:2]
    size = (max(1, round(width * scale)), max(1, round(height * scale)))
    # area averaging when shrinking avoids aliasing; bilinear when enlarging
    interpolation = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
    return cv2.resize(frame, size, interpolation=interpolation)


def _decode(capture, path: Path, start: int, max_frames: int | None, stride: int,
            scale: float) -> Iterator[tuple[int, np.ndarray]]:
    """Yield ``(file index, RGB frame)``; VideoError if not one frame could be read."""
    import cv2

    for index, frame in _decode_bgr(capture, path, start, max_frames, stride, scale):
        yield index, cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)


def _decode_bgr(capture, path: Path, start: int, max_frames: int | None, stride: int,
                scale: float) -> Iterator[tuple[int, np.ndarray]]:
    """Yield ``(file index, BGR frame)`` as OpenCV decodes them, resized; VideoError if not
    one frame could be read."""
    import cv2

    index = 0
    for _ in range(start):
        if not capture.grab():
            raise VideoError(f"{path}: has {index} frames, none at or after start={start}"
                             if index else f"{path}: the video has no frames that can be read")
        index += 1
    count = 0
    while max_frames is None or count < max_frames:
        ok, frame = capture.read()
        if not ok or frame is None:
            break
        if frame.ndim == 2:  # some codecs decode to one grey channel
            frame = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
        yield index, _resize(frame, scale)
        index += 1
        count += 1
        skipped = 0
        while skipped < stride - 1 and capture.grab():
            skipped += 1
        index += skipped
        if skipped < stride - 1:
            break
    if count == 0:
        raise VideoError(f"{path}: has {index} frames, none at or after start={start}"
                         if index else f"{path}: the video has no frames that can be read "
                         f"(empty or damaged)")


def _grey_into(bgr: np.ndarray, out: np.ndarray, scratch: np.ndarray) -> None:
    """:func:`to_grey` of the RGB image whose BGR decoding is ``bgr``, written into ``out``:
    the same float32 operations in the same order (so the same values, bit for bit), without
    the colour conversion, the frame's copies or temporaries (several times cheaper than
    ``to_grey(cvtColor(bgr))``, which makes four fresh frame-sized arrays)."""
    weights = _LUMA / np.float32(255)
    np.multiply(bgr[..., 2], weights[0], out=out)
    np.multiply(bgr[..., 1], weights[1], out=scratch)
    out += scratch
    np.multiply(bgr[..., 0], weights[2], out=scratch)
    out += scratch


def _frames(path: Path, chunk: list[np.ndarray], indices: list[int], fps: float,
            stride: int) -> VideoFrames:
    return VideoFrames(frames=np.stack(chunk), fps=fps / stride, path=path,
                       frame_indices=np.asarray(indices, np.int64), source_fps=fps)


def read_video(path: str | os.PathLike, *, start: int = 0, max_frames: int | None = None,
               stride: int = 1, scale: float = 1.0) -> VideoFrames:
    """Decode a video file into RGB frames.

    Args:
        path: the video file.
        start: index of the first frame to return (earlier frames are decoded and dropped).
        max_frames: return at most this many frames (None: to the end of the file).
        stride: return every ``stride``-th frame from ``start``.
        scale: resize factor applied to each frame (area averaging when < 1).

    Returns:
        :class:`VideoFrames` with ``frames`` ``(time, height, width, 3)`` uint8 RGB.

    Raises:
        VideoError: the file is missing, is not a video OpenCV can decode, or has no frame at or
            after ``start``.
        ValueError: an option is out of range.
    """
    _check_options(start, max_frames, stride, scale)
    path = Path(path)
    capture, fps = _open(path)
    try:
        frames, indices = [], []
        for index, frame in _decode(capture, path, start, max_frames, stride, scale):
            frames.append(frame)
            indices.append(index)
    finally:
        capture.release()
    return _frames(path, frames, indices, fps, stride)


def iter_video_chunks(path: str | os.PathLike, chunk_size: int, *, start: int = 0,
                      max_frames: int | None = None, stride: int = 1,
                      scale: float = 1.0, grey: bool = False,
                      first_chunk_size: int | None = None) -> Iterator[VideoFrames]:
    """Decode a video file a chunk at a time, holding at most ``chunk_size`` frames in memory.

    The chunks, concatenated, are what :func:`read_video` returns with the same options; every
    chunk but the first (``first_chunk_size`` frames, when given) and the last has exactly
    ``chunk_size`` frames.

    The file is checked (it exists and opens as a video) when this is called, so a wrong path
    raises here rather than at the first ``next``; a file with no frames to read raises at the
    first ``next``.

    Args:
        path: the video file.
        chunk_size: frames per chunk (≥ 1).
        start, max_frames, stride, scale: as for :func:`read_video`.
        grey: the chunks' ``frames`` are ``(time, height, width)`` float32 grey levels, equal
            to :func:`to_grey` of the RGB frames, made straight from the decoded frames (no
            RGB copy is made: what a tracker that reads grey frames needs, at a fraction of the
            cost).
        first_chunk_size: frames in the first chunk (≥ 1; None: ``chunk_size``).

    Yields:
        :class:`VideoFrames` of at most ``chunk_size`` frames each (the first at most
        ``first_chunk_size``), in order.

    Raises:
        VideoError: as for :func:`read_video`.
    """
    if chunk_size < 1:
        raise ValueError(f"chunk_size must be ≥ 1, got {chunk_size}")
    if first_chunk_size is not None and first_chunk_size < 1:
        raise ValueError(f"first_chunk_size must be ≥ 1 (or None), got {first_chunk_size}")
    _check_options(start, max_frames, stride, scale)
    path = Path(path)
    _open(path)[0].release()  # fail now on a missing or undecodable file
    if grey:
        return _grey_chunks(path, chunk_size, first_chunk_size or chunk_size, start,
                            max_frames, stride, scale)

    def chunks() -> Iterator[VideoFrames]:
        capture, fps = _open(path)
        try:
            frames, indices, size = [], [], first_chunk_size or chunk_size
            for index, frame in _decode(capture, path, start, max_frames, stride, scale):
                frames.append(frame)
                indices.append(index)
                if len(frames) == size:
                    yield _frames(path, frames, indices, fps, stride)
                    frames, indices, size = [], [], chunk_size
            if frames:
                yield _frames(path, frames, indices, fps, stride)
        finally:
            capture.release()

    return chunks()


def _grey_chunks(path: Path, chunk_size: int, first_chunk_size: int, start: int,
                 max_frames: int | None, stride: int, scale: float) -> Iterator[VideoFrames]:
    """:func:`iter_video_chunks` with ``grey``: each chunk's grey frames written in place into
    one array made for the chunk."""
    capture, fps = _open(path)
    try:
        chunk = scratch = None
        indices: list[int] = []
        size = first_chunk_size
        for index, frame in _decode_bgr(capture, path, start, max_frames, stride, scale):
            if chunk is None:
                chunk = np.empty((size, *frame.shape[:2]), np.float32)
            if scratch is None:
                scratch = np.empty(frame.shape[:2], np.float32)
            _grey_into(frame, chunk[len(indices)], scratch)
            indices.append(index)
            if len(indices) == size:
                yield VideoFrames(frames=chunk, fps=fps / stride, path=path,
                                  frame_indices=np.asarray(indices, np.int64), source_fps=fps)
                chunk, indices, size = None, [], chunk_size
        if indices:
            yield VideoFrames(frames=chunk[:len(indices)], fps=fps / stride, path=path,
                              frame_indices=np.asarray(indices, np.int64), source_fps=fps)
    finally:
        capture.release()


def to_grey(images: np.ndarray) -> np.ndarray:
    """Grey levels of RGB images: ``(..., height, width, 3)`` → float32 ``(..., height, width)``.

    The ITU-R BT.601 luma ``0.299 R + 0.587 G + 0.114 B`` (as ``cv2.COLOR_RGB2GRAY``), scaled to
    [0, 1]: uint8 images are divided by 255, floating-point images are taken to be in [0, 1]
    already.

    Raises:
        ValueError: the last axis is not 3 colour channels, or the dtype is neither uint8 nor
            floating point.
    """
    images = np.asarray(images)
    if images.ndim < 3 or images.shape[-1] != 3:
        raise ValueError(f"to_grey expects RGB images (..., height, width, 3), got shape "
                         f"{images.shape}")
    if images.dtype == np.uint8:
        weights = _LUMA / np.float32(255)
    elif np.issubdtype(images.dtype, np.floating):
        weights = _LUMA
    else:
        raise ValueError(f"to_grey expects uint8 (0..255) or float (0..1) images, got "
                         f"{images.dtype}")
    # one channel at a time: no float copy of the whole colour array
    grey = images[..., 0] * weights[0]
    grey += images[..., 1] * weights[1]
    grey += images[..., 2] * weights[2]
    return grey.astype(np.float32, copy=False)


def write_frames(frames: Iterable[np.ndarray], path: str | os.PathLike, fps: float,
                 image_size: tuple[int, int]) -> Path:
    """Encode RGB uint8 frames of ``image_size`` ``(width, height)`` as an mp4 (mp4v) at
    ``path``, atomically: a failure leaves no partial file.

    Raises:
        OSError: OpenCV cannot open a writer for the file.
    """
    import cv2

    path = Path(path)

    def write(temporary: Path) -> None:
        with _quiet_opencv():
            writer = cv2.VideoWriter(str(temporary), cv2.VideoWriter_fourcc(*"mp4v"),
                                     float(fps), tuple(image_size))
        if not writer.isOpened():
            raise OSError(f"{path}: OpenCV cannot write an mp4v video here")
        try:
            for frame in frames:
                writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
        finally:
            writer.release()

    # the temporary name ends in .mp4 because OpenCV picks the container from the extension
    write_atomically(path, write, suffix=".mp4")
    return path
