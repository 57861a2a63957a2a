"""``jaxtrack track``: one command for the five trackers over a video file.

``--method`` picks the tracker; ``--model`` is what ``jaxtrack train`` wrote for it (for
CONDENSATION and MHT: the latent tracker's prior, whose training poses their dynamics are
learned from); without it, the model bundled with jaxtrack for the method
(:func:`jaxtrack.data.models.default_model`). This module parses the arguments; the tracker
and its first pose are built by

- ``latent`` (Tian, Li & Sclaroff 2005), ``condensation``, ``mht``: ``jaxtrack.cli._track_image``
  (the first pose by hand, ``--init manual:x,y,...``, from a detector's keypoints, or found
  automatically, ``--init face``: ``jaxtrack.cli._pose``);
- ``linear-combination`` (Ong & Gong 2002), one video per calibrated camera:
  ``jaxtrack.cli._track_linear_combination``;
- ``mixed-state`` (Kwatra, Bobick & Johnson 2002): ``jaxtrack.cli._track_mixed_state``;

and the video is decoded in chunks, tracked, and ``DIR/overlay.mp4`` (the estimate drawn on the
video's own frames, at its own size) and ``DIR/track.json`` (what ran, per frame the markers in
the video's own pixels, ESS, log-likelihood and a status, ok, degenerate, no person or lost) are
written by :func:`jaxtrack.experiments.pipeline.track_video`, nothing left half-written when
anything fails or Ctrl-C interrupts. Every argument, output folder included, is checked before
the first frame is decoded.

A run on a real video, and the memory estimate's measurements: ``papers/tian2005/history.md``,
``papers/tian2005/history.md`` (section "Memory").
"""

from __future__ import annotations

import argparse
from pathlib import Path

from jaxtrack.cli._common import integer, model_or_default, real, seed
from jaxtrack.cli._detector import add_detection_options
from jaxtrack.cli._options import add_tracker_options
from jaxtrack.cli._track_image import BYTES_PER_PARTICLE

__all__ = ["METHODS", "add_parser"]

METHODS = ("latent", "condensation", "mht", "linear-combination", "mixed-state")


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "track",
        help="track the upper body in a video with one of the five trackers",
        description=(
            "Track a person's upper body through a video with --method's tracker (default: "
            "CONDENSATION in a GPLVM latent space, 12 markers, initialised on the first frame "
            "by hand or automatically); writes DIR/overlay.mp4 and DIR/track.json."),
        epilog=(
            "--init face: face boxes (OpenCV Haar cascades) and head boxes from the top of "
            "moving foreground blobs (median background of the video; needs a static camera "
            "and a person who moves), then the prior's training poses are searched for the one "
            "that best covers the foreground. --init manual:x,y,...: the 24 numbers are the "
            "first frame's 12 markers in video pixels, in the order head, neck, thorax, pelvis, "
            "right shoulder, elbow, wrist, hip, left shoulder, elbow, wrist, hip. example, on "
            "the bundled Pose2Sim clip (jaxtrack.data.path('pose2sim/videos/cam03_half.mp4')): "
            "jaxtrack track --video CLIP.mp4 --out p2s (the bundled latent.npz; or --model "
            "jaxtrack-demo/gplvm_waves.npz, the demo's)"),
    )
    parser.add_argument("--method", choices=METHODS, default="latent",
                        help="the tracker (default latent); --model must come from jaxtrack "
                        "train with the same --method (condensation and mht: with --method "
                        "latent, whose training poses their dynamics are learned from)")
    parser.add_argument("--model", default=None, type=Path, metavar="MODEL.npz",
                        help="a model from jaxtrack train with the same --method (or "
                        "jaxtrack-demo/gplvm_waves.npz); default: the one bundled with "
                        "jaxtrack for --method, trained on training subjects only "
                        "(jaxtrack.data.models: latent.npz for latent, condensation and mht, "
                        "linear_combination.npz, postures.npz; python -m jaxtrack.data.models "
                        "says what each was trained on)")
    parser.add_argument("--video", required=True, type=Path, nargs="+", metavar="FILE",
                        help="the video to track (anything OpenCV's FFmpeg reads: mp4, avi, "
                        "mov); linear-combination: one per calibrated camera")
    parser.add_argument("--init", default=None, metavar="face|keypoints|manual:x,y,...",
                        help="first-frame pose: found automatically (face, the default without "
                        "detections), the first frame's detections (keypoints, the default "
                        "with --keypoints or --detector), or the 12 markers given by hand "
                        "(see below)")
    parser.add_argument("--out", required=True, type=Path, metavar="DIR",
                        help="folder to write overlay.mp4 and track.json into (created)")
    parser.add_argument("--particles", type=integer(1), default=None,
                        help="particles of the filter (default 200 for latent, 1000 for "
                        "condensation, 10 modes for mht, 300 for linear-combination, 500 for "
                        "mixed-state; latent: memory grows by "
                        f"about {BYTES_PER_PARTICLE // 1000} kB per particle)")
    parser.add_argument("--seed", type=seed, default=0,
                        help="random seed of the particle filter, 0 to 2**32 - 1 (default 0)")
    add_tracker_options(parser)
    parser.add_argument("--max-size", type=integer(32), default=960, metavar="PX",
                        help="downscale so the longer side is at most PX (default 960)")
    parser.add_argument("--frames", metavar="START:STOP", help="frame range (default: all)")
    group = parser.add_argument_group("linear-combination and mixed-state")
    # linear-combination options
    group.add_argument("--calibration", type=Path, default=None, metavar="FILE",
                       help="linear-combination: the cameras' calibration (a Pose2Sim "
                       "Calib.qca.txt), one camera per --video in order")
    group.add_argument("--iterations", type=integer(1), default=None,
                       help="linear-combination: CONDENSATION iterations per frame (default 5)")
    group.add_argument("--cameras", type=integer(0), nargs="+", default=None, metavar="INDEX",
                       help="linear-combination: which cameras of --calibration (0-based, in "
                       "its order) filmed the --video files, one per video (default: all)")
    group.add_argument("--view-selection", choices=("ambiguity", "fitness", "paper"),
                       default=None,
                       help="linear-combination, several videos: pick each frame's view by its "
                       "least ambiguity over +-5 frames (the default, chosen on validation), "
                       "its greatest fitness over +-5 frames, or the paper's greatest fitness "
                       "x 1/ambiguity")
    group.add_argument("--skeleton", choices=("mean", "best"), default=None,
                       help="linear-combination: the 3-D skeleton reported, the particles' "
                       "weighted mean (the default, chosen on validation) or the best "
                       "particle's (the paper's)")
    parser.add_argument("--coverage-weight", type=real(0.0), default=None, metavar="NU",
                        help="latent, with --masks: also charge the masks for what the body "
                        "leaves unexplained, NU nats per unit of the coverage term "
                        "(jaxtrack.likelihoods.edges; default off)")
    parser.add_argument("--keypoints", type=Path, default=None, metavar="FILE_OR_FOLDER",
                        help="latent, condensation, mht, mixed-state: a per-frame detector's "
                        "keypoints of the "
                        "video, one row per video frame from the first: a folder of OpenPose "
                        "JSON, a COCO .json, MediaPipe's .npz, jaxtrack's detections .npz, or a "
                        ".npz with one person's 'keypoints' (frames, 12, 2) in SPM_MARKERS "
                        "order (jaxtrack.vision.keypoints); the detection density "
                        "(jaxtrack.likelihoods.detections), fitted on them first, times the "
                        "image likelihood scores them. mixed-state: the confident head, "
                        "wrists and ankles become part hypotheses beside the silhouette's")
    parser.add_argument("--person", default=None, metavar="x0,y0,x1,y1",
                        help="with --keypoints of several people: the box around the person to "
                        "follow in the first frame with anyone (default: the most confident); "
                        "with --detector: the person to detect (frames where the detector "
                        "finds someone else or nobody are detected again around them; while "
                        "tracking, also on the region the tracker predicts: --guided, the "
                        "default)")
    add_detection_options(parser)
    parser.add_argument("--keypoint-weight", type=real(0.0), default=None, metavar="ETA",
                        help="with detections: score them by the image likelihood's keypoint "
                        "term of weight ETA (a Cauchy density per marker, "
                        "jaxtrack.likelihoods.edges; 1.5 is its own) instead of the detection "
                        "density, which is fitted (the default)")
    parser.add_argument("--masks", type=Path, nargs="+", default=None, metavar="FILE",
                        help="the person's masks, one .npz ('masks') or .npy of (frames, height, "
                        "width) bool per --video, in order (a person segmenter's): the "
                        "silhouettes of linear-combination and mixed-state, the foreground of "
                        "latent's likelihood (default: the video's median background)")
    group.add_argument("--skin", default=None, metavar="R,G,B",
                       help="linear-combination: a sample of the person's skin colour (default: "
                       "a fixed chroma box)")
    # mixed-state options
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """``jaxtrack track``: the method's tracker over the video (module docstring)."""
    args.model = model_or_default(args.model, args.method)
    if args.init is None:  # the detections' first frame where there are any
        detections = args.keypoints is not None or args.detector is not None
        args.init = "keypoints" if detections and args.method in ("latent", "condensation",
                                                                  "mht") else "face"
    if args.method == "linear-combination":
        from jaxtrack.cli import _track_linear_combination

        return _track_linear_combination.track(args)
    if args.method == "mixed-state":
        from jaxtrack.cli import _track_mixed_state

        return _track_mixed_state.track(args)
    from jaxtrack.cli import _track_image

    return _track_image.run(args)
