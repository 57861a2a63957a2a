"""MediaPipe Pose on frames, run by the detector venv's python (``make detector``); jaxtrack
never imports it (MediaPipe 0.10.21 needs numpy < 2, jaxtrack's jax numpy >= 2). It imports
only numpy and, when it runs, mediapipe.

Two ways to run it (``jaxtrack.vision.mediapipe`` does both):

    .venv-mediapipe/bin/python _mediapipe_worker.py IN.npz OUT.npz   # a whole video
    .venv-mediapipe/bin/python _mediapipe_worker.py --serve [OPTIONS.npz]  # frame by frame
    .venv-mediapipe/bin/python _mediapipe_worker.py --check  # the models load

IN.npz: ``frames`` (time, height, width, 3) uint8 RGB, ``model_complexity`` (0 or 1: the
models bundled in the wheel; 2, "heavy", is downloaded on first use and is refused here),
optionally ``segmentation`` (1: also MediaPipe's person segmentation, its bundled model),
``static`` (1: every frame on its own, ``static_image_mode=True``; default 0, video mode, where
MediaPipe tracks the person between frames as a video application would) and ``regions``
(time, 4) pixel boxes ``x0, y0, x1, y1``: each frame's detection runs on that crop only (a box
around where a tracker expects the person) and its landmarks come back in the frame's pixels.

OUT.npz (written atomically): ``landmarks`` (time, 33, 2) pixels (NaN where no person was
found), ``visibility`` (time, 33), ``found`` (time,) bool, ``seconds`` (time − 1,) per frame
after the first, ``first_seconds`` (the first frame, which loads the models), ``version``; with
``segmentation``, ``masks`` (time, height, width) bool, the person where the segmentation's
probability is at least 0.5 (all False where no person was found). stdout gets one summary line.

``--serve``: the same options (OPTIONS.npz without ``frames``), then requests on stdin and
answers on stdout, each an 8-byte little-endian length and that many bytes of ``.npz``: a
request holds ``frame`` (height, width, 3) uint8 RGB and optionally ``region`` (4,); an answer
``landmarks`` (33, 2), ``visibility`` (33,), ``found``, ``seconds`` (and ``mask``), or
``error`` (a one-line message). An empty request (length 0) ends it. The first answer also
holds ``version``.

A stand-in detector (tests: a frame's bright pixels) runs through :func:`serve` and
:func:`run_file` with its own ``process`` callable, so everything but MediaPipe itself is the
code that runs here.
"""

from __future__ import annotations

import io
import os
import struct
import sys
import tempfile
import time

import numpy as np

NUM_LANDMARKS = 33


def crop_box(region, height: int, width: int) -> tuple[int, int, int, int]:
    """The pixel box ``(x0, y0, x1, y1)`` (integers, inside the frame, at least 2 px each way)
    of a region ``x0, y0, x1, y1``, or the whole frame for None."""
    if region is None:
        return 0, 0, width, height
    x0, y0, x1, y1 = (float(value) for value in np.asarray(region, np.float64).reshape(4))
    x0, y0 = int(np.clip(np.floor(x0), 0, width - 2)), int(np.clip(np.floor(y0), 0, height - 2))
    x1 = int(np.clip(np.ceil(x1), x0 + 2, width))
    y1 = int(np.clip(np.ceil(y1), y0 + 2, height))
    return x0, y0, x1, y1


def detect_frame(process, frame: np.ndarray, region=None, *, segmentation: bool = False) -> dict:
    """One frame through ``process`` (a callable taking an RGB image and returning None or
    ``(landmarks (33, 2) normalised to that image, visibility (33,), mask or None)``), on the
    crop ``region`` when given, the landmarks mapped back to the frame's pixels."""
    height, width = frame.shape[:2]
    x0, y0, x1, y1 = crop_box(region, height, width)
    image = np.ascontiguousarray(frame[y0:y1, x0:x1])
    start = time.perf_counter()
    found = process(image)
    seconds = time.perf_counter() - start
    out = {"landmarks": np.full((NUM_LANDMARKS, 2), np.nan), "visibility": np.zeros(NUM_LANDMARKS),
           "found": np.bool_(found is not None), "seconds": np.float64(seconds)}
    if segmentation:
        out["mask"] = np.zeros((height, width), bool)
    if found is None:
        return out
    landmarks, visibility, mask = found
    size = np.array([x1 - x0, y1 - y0], np.float64)
    out["landmarks"] = np.asarray(landmarks, np.float64) * size + np.array([x0, y0], np.float64)
    out["visibility"] = np.asarray(visibility, np.float64)
    if segmentation and mask is not None:
        out["mask"][y0:y1, x0:x1] = np.asarray(mask) >= 0.5
    return out


def mediapipe_process(options: dict):
    """``(process, close, version)``: MediaPipe's legacy ``solutions.pose.Pose`` as the
    callable :func:`detect_frame` takes."""
    # this script's folder holds jaxtrack's own mediapipe.py, first on sys.path when run as a
    # script: the package must come from the venv
    here = os.path.dirname(os.path.abspath(__file__))
    sys.path[:] = [path for path in sys.path if os.path.abspath(path or os.curdir) != here]
    import mediapipe as mp

    complexity = int(options.get("model_complexity", 1))
    if complexity not in (0, 1):
        raise SystemExit(f"model_complexity must be 0 or 1 (bundled models), got {complexity}")
    segmentation = bool(options.get("segmentation", False))
    pose = mp.solutions.pose.Pose(static_image_mode=bool(options.get("static", False)),
                                  model_complexity=complexity, smooth_landmarks=True,
                                  enable_segmentation=segmentation,
                                  smooth_segmentation=segmentation)

    def process(image):
        result = pose.process(image)
        if result.pose_landmarks is None:
            return None
        points = result.pose_landmarks.landmark
        mask = result.segmentation_mask if segmentation else None
        return ([(p.x, p.y) for p in points], [p.visibility for p in points], mask)

    return process, pose.close, mp.__version__


def _options(data) -> dict:
    return {key: data[key].item() for key in ("model_complexity", "segmentation", "static")
            if key in data.files}


def run_file(in_path: str, out_path: str, make_process=mediapipe_process) -> int:
    """The whole-video mode: IN.npz → OUT.npz (the module docstring)."""
    with np.load(in_path) as data:
        frames = np.asarray(data["frames"], np.uint8)
        options = _options(data)
        regions = np.asarray(data["regions"], np.float64) if "regions" in data.files else None
    segmentation = bool(options.get("segmentation", False))
    process, close, version = make_process(options)
    answers = []
    try:
        for t, frame in enumerate(frames):
            region = None if regions is None else regions[t]
            answers.append(detect_frame(process, frame, region, segmentation=segmentation))
    finally:
        close()
    seconds = np.array([answer["seconds"] for answer in answers], np.float64)
    found = np.array([answer["found"] for answer in answers], bool)
    extra = {"masks": np.stack([a["mask"] for a in answers])} if segmentation else {}
    folder = os.path.dirname(os.path.abspath(out_path))
    with tempfile.NamedTemporaryFile(dir=folder, suffix=".npz", delete=False) as handle:
        np.savez_compressed(handle, landmarks=np.stack([a["landmarks"] for a in answers]),
                            visibility=np.stack([a["visibility"] for a in answers]),
                            found=found, seconds=seconds[1:] if len(seconds) > 1 else seconds,
                            first_seconds=np.float64(seconds[0]), version=np.str_(version),
                            **extra)
    os.replace(handle.name, out_path)
    later = seconds[1:] if len(seconds) > 1 else seconds
    print(f"mediapipe {version}: {int(found.sum())}/{len(frames)} frames with a person, "
          f"{1e3 * np.median(later):.1f} ms/frame (first {seconds[0]:.2f} s)")
    return 0


def _read_message(stream) -> dict | None:
    header = stream.read(8)
    if len(header) < 8:
        return None
    (length,) = struct.unpack("<Q", header)
    if length == 0:
        return None
    payload = stream.read(length)
    with np.load(io.BytesIO(payload)) as data:
        return {key: data[key] for key in data.files}


def write_message(stream, arrays: dict) -> None:
    """One length-prefixed ``.npz`` message (the ``--serve`` protocol)."""
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    payload = buffer.getvalue()
    stream.write(struct.pack("<Q", len(payload)) + payload)
    stream.flush()


def serve(options: dict, make_process=mediapipe_process) -> int:
    """The frame-by-frame mode: answer requests on stdin until an empty one (module docstring).
    Anything the detector's libraries print goes to stderr, never into the answers."""
    answers = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    requests = sys.stdin.buffer
    segmentation = bool(options.get("segmentation", False))
    process, close, version = make_process(options)
    first = True
    try:
        while (request := _read_message(requests)) is not None:
            try:
                answer = detect_frame(process, np.asarray(request["frame"], np.uint8),
                                      request.get("region"), segmentation=segmentation)
            except Exception as error:  # one bad frame is answered, not a dead pipe
                answer = {"error": np.str_(" ".join(f"{type(error).__name__}: {error}".split()))}
            if first:
                answer["version"], first = np.str_(version), False
            write_message(answers, answer)
    finally:
        close()
        answers.close()
    return 0


def main(argv: list[str], make_process=mediapipe_process) -> int:
    """``IN.npz OUT.npz``, ``--serve [OPTIONS.npz]``, or ``--check`` (load the models once and
    print the version: what ``make detector`` runs last)."""
    if argv[:1] == ["--check"]:
        process, close, version = make_process({})
        found = process(np.zeros((64, 64, 3), np.uint8))
        close()
        print(f"mediapipe {version}: pose models load (a blank frame: "
              f"{'a person' if found is not None else 'no person'})")
        return 0
    if argv[:1] == ["--serve"]:
        options = {}
        if len(argv) > 1:
            with np.load(argv[1]) as data:
                options = _options(data)
        return serve(options, make_process)
    if len(argv) != 2:
        raise SystemExit("usage: _mediapipe_worker.py IN.npz OUT.npz | --serve [OPTIONS.npz] "
                         "| --check")
    return run_file(argv[0], argv[1], make_process)


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
