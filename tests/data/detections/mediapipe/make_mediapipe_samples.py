"""Run MediaPipe Pose (legacy solution, video mode, model_complexity=1) on the first 3 frames of
the Pose2Sim demo's cam01.mp4 and save (1) what jaxtrack/vision/_mediapipe_worker.py writes and
(2) the raw normalised landmarks (time, 33, 4): x, y, z, visibility.

    python make_mediapipe_samples.py VIDEO jaxtrack/vision/_mediapipe_worker.py
"""
import subprocess
import sys

import cv2
import mediapipe as mp
import numpy as np

video = sys.argv[1]
capture = cv2.VideoCapture(video)
frames = []
for _ in range(3):
    ok, frame = capture.read()
    frames.append(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB))
frames = np.stack(frames)
np.savez("in.npz", frames=frames, model_complexity=np.int64(1))
subprocess.run([sys.executable, sys.argv[2], "in.npz", "mediapipe_run.npz"], check=True)
raw = np.full((len(frames), 33, 4), np.nan)
with mp.solutions.pose.Pose(static_image_mode=False, model_complexity=1,
                            smooth_landmarks=True) as pose:
    for t, frame in enumerate(frames):
        result = pose.process(np.ascontiguousarray(frame))
        if result.pose_landmarks is not None:
            raw[t] = [(p.x, p.y, p.z, p.visibility) for p in result.pose_landmarks.landmark]
np.save("mediapipe_landmarks.npy", raw.astype(np.float32))
print(frames.shape, mp.__version__)
