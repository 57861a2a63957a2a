"""MediaPipe Pose on frames; run with the MediaPipe venv's python, never imported by jaxtrack.

    .venv-mediapipe/bin/python benchmarks/_mediapipe_reference.py IN.npz OUT.npz

IN.npz: ``frames`` (time, height, width, 3) uint8 RGB, ``model_complexity`` (0 or 1: the
models bundled in the wheel; 2, "heavy", is downloaded on first use and is refused here), and
optionally ``segmentation`` (1: also MediaPipe's person segmentation, its bundled model).
The legacy ``mediapipe.solutions.pose.Pose`` runs in video mode (``static_image_mode=False``:
it tracks the person between frames, as a video application would). OUT.npz (written
atomically): ``landmarks`` (time, 33, 2) pixels (NaN where no person was found), ``visibility``
(time, 33), ``found`` (time,) bool, ``seconds`` (time,) per frame, ``first_seconds`` (the first
frame, which loads the models), ``version``; with ``segmentation``, ``masks`` (time, height,
width) bool, the person where the segmentation's probability is at least 0.5 (all False where
no person was found). stdout gets one summary line.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time

import numpy as np


def main(in_path: str, out_path: str) -> int:
    import mediapipe as mp

    with np.load(in_path) as data:
        frames = np.asarray(data["frames"], np.uint8)
        complexity = int(data["model_complexity"])
        segmentation = bool(data["segmentation"]) if "segmentation" in data.files else False
    if complexity not in (0, 1):
        raise SystemExit(f"model_complexity must be 0 or 1 (bundled models), got {complexity}")
    num_frames, height, width = frames.shape[:3]
    landmarks = np.full((num_frames, 33, 2), np.nan)
    visibility = np.zeros((num_frames, 33))
    found = np.zeros(num_frames, bool)
    seconds = np.zeros(num_frames)
    masks = np.zeros((num_frames, height, width), bool) if segmentation else None
    with mp.solutions.pose.Pose(static_image_mode=False, model_complexity=complexity,
                                smooth_landmarks=True, enable_segmentation=segmentation,
                                smooth_segmentation=segmentation) as pose:
        for t, frame in enumerate(frames):
            start = time.perf_counter()
            result = pose.process(np.ascontiguousarray(frame))
            seconds[t] = time.perf_counter() - start
            if result.pose_landmarks is None:
                continue
            found[t] = True
            if segmentation and result.segmentation_mask is not None:
                masks[t] = result.segmentation_mask >= 0.5
            points = result.pose_landmarks.landmark
            landmarks[t] = [(p.x * width, p.y * height) for p in points]
            visibility[t] = [p.visibility for p in points]
    folder = os.path.dirname(os.path.abspath(out_path))
    with tempfile.NamedTemporaryFile(dir=folder, suffix=".npz", delete=False) as handle:
        extra = {} if masks is None else {"masks": masks}
        np.savez_compressed(handle, landmarks=landmarks, visibility=visibility, found=found,
                            seconds=seconds[1:] if num_frames > 1 else seconds,
                            first_seconds=np.float64(seconds[0]),
                            version=np.str_(mp.__version__), **extra)
    os.replace(handle.name, out_path)
    later = seconds[1:] if num_frames > 1 else seconds
    print(f"mediapipe {mp.__version__}: {int(found.sum())}/{num_frames} frames with a person, "
          f"{1e3 * np.median(later):.1f} ms/frame (first {seconds[0]:.2f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(*sys.argv[1:3]))
