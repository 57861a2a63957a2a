"""``jaxtrack render``: real motion capture drawn as video, saved with exact ground truth."""

from __future__ import annotations

import argparse

from jaxtrack.cli._common import UserError, integer, output_folder, real, seed

__all__ = ["add_parser"]

# the mp4 writer (OpenCV's FFmpeg mpeg4) refuses rates below about 0.01 and above 65535
_MIN_FPS, _MAX_FPS = 0.1, 10000.0
_LIMIT_TEXT = "300 MB"  # jaxtrack._files.LARGE_OUTPUT_BYTES, for the help text


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "render",
        help="render real motion capture as video with exact 2-D/3-D ground truth",
        description=(
            "Draw a clothed figure moving as a real motion-capture clip, seen through a camera, "
            "and save the frames with per-frame ground truth (2-D markers, 3-D joints, "
            "visibility, silhouettes, camera) as a .npz sequence (jaxtrack.body.load_sequence)."),
        epilog=(
            "cameras: 'frontal' looks at the subject's front (from hips and shoulders); "
            "'random' draws a viewpoint on the view sphere (from --seed); 'qca:FILE:INDEX' uses "
            "camera INDEX (0-based, or a serial such as cam01) of a Qualisys calibration, e.g. "
            "qca:pose2sim/Calib.qca.txt:0 - the motion is moved horizontally to where the "
            "calibrated cameras look, and frames are rendered at that camera's own size "
            "(Pose2Sim: portrait 1088x1920) or, with --size, scaled to fit inside it keeping the "
            "aspect ratio. examples: jaxtrack render --mocap animateddrawings/fair1_wave_hello "
            "--camera frontal --frames 0:120 --out wave.npz --video wave.mp4"),
    )
    parser.add_argument("--mocap", required=True, metavar="FILE_OR_CLIP",
                        help="a .bvh/.amc file, or a clip name such as cmu_amc/07_01")
    parser.add_argument("--camera", default="frontal", metavar="SPEC",
                        help="frontal (default), random, or qca:FILE:INDEX")
    parser.add_argument("--out", required=True, metavar="SEQ.npz", help="sequence file to write")
    parser.add_argument("--video", metavar="OUT.mp4",
                        help="also write an mp4 with the ground-truth markers drawn on top")
    parser.add_argument("--background", default="plain", choices=("plain", "photo", "clutter"),
                        help="plain colour, a real lab photo, or random clutter (default plain)")
    parser.add_argument("--frames", metavar="START:STOP",
                        help="frame range of the clip, at its own rate (default: all)")
    parser.add_argument("--fps", metavar="F",
                        type=real(_MIN_FPS, _MAX_FPS, unit=" frames per second"),
                        help=f"resample to F frames per second ({_MIN_FPS:g} to {_MAX_FPS:g}; "
                        "default: the clip's own rate)")
    parser.add_argument("--seed", type=seed, default=0, metavar="S",
                        help="random seed, 0 to 2**32 - 1 (default 0)")
    parser.add_argument("--size", metavar="WxH",
                        help="image size (default 640x480; qca: the camera's own size)")
    parser.add_argument("--markers", default="humaneva15", choices=("humaneva15", "upper12"),
                        help="ground-truth marker set (default humaneva15)")
    parser.add_argument("--occluders", type=integer(0, 1000), default=0, metavar="N",
                        help="rectangles sweeping across the figure (default 0)")
    parser.add_argument("--noise", type=real(0.0, 255.0, unit=" grey levels"), default=0.0,
                        metavar="STD",
                        help="Gaussian pixel noise, grey levels (default 0)")
    parser.add_argument("--blur", type=real(0.0, 1000.0, unit=" pixels"), default=0.0,
                        metavar="SIGMA",
                        help="Gaussian blur, pixels (default 0)")
    parser.add_argument("--allow-large", action="store_true",
                        help="write --out even when it will be larger than "
                        f"{_LIMIT_TEXT} (the rendered frames are stored uncompressed: 640x480 "
                        "takes about 1 MB a frame); without it such a render is refused before "
                        "anything is rendered")
    parser.set_defaults(handler=run)


def _render_output(text: str, option: str):
    """An output file of ``render``: its folder must exist and take a new file (probed)."""
    from pathlib import Path

    path = Path(text)
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise UserError(f"{option} {text} is a folder; give a file name")
    if folder.exists() and not folder.is_dir():
        raise UserError(f"cannot write {option} {text}: {folder} is a file, not a folder")
    if not folder.is_dir():
        raise UserError(f"cannot write {option} {text}: folder {folder} does not exist")
    output_folder(path, option)
    return path


def sequence_bytes(num_frames: int, image_size: tuple[int, int]) -> int:
    """Bytes of a saved sequence of ``num_frames`` frames of ``image_size`` ``(width,
    height)``: its RGB frames and packed silhouettes, stored uncompressed (the ground truth
    adds a few kB)."""
    width, height = image_size
    return num_frames * height * (3 * width + (width + 7) // 8)


def _check_output_size(out, num_frames: int, image_size: tuple[int, int], allow: bool) -> None:
    """Say the size of ``--out`` before anything is rendered, and refuse one above
    :data:`jaxtrack._files.LARGE_OUTPUT_BYTES` unless ``--allow-large``."""
    import sys

    from jaxtrack import _files

    size = sequence_bytes(num_frames, image_size)
    what = f"{num_frames} frames of {image_size[0]}x{image_size[1]}"
    if size > _files.LARGE_OUTPUT_BYTES and not allow:
        limit = _files.format_bytes(_files.LARGE_OUTPUT_BYTES)
        raise UserError(f"--out {out} would be about {_files.format_bytes(size)} ({what}, "
                        f"uncompressed), more than {limit}; "
                        "render fewer frames (--frames START:STOP, a lower --fps) or smaller "
                        "ones (--size), or pass --allow-large")
    print(f"rendering {what} -> {out} (about {_files.format_bytes(size)})", file=sys.stderr,
          flush=True)


def _resampled_frames(motion, fps: float) -> int:
    """How many frames ``motion.resample(fps)`` will have (the same arithmetic, no arrays)."""
    import math

    ratio = motion.fps / fps
    return int(math.floor((motion.num_frames - 1) / ratio + 1e-9)) + 1


def _render_memory(num_frames: int, image_size: tuple[int, int] | None, noise: bool) -> float:
    """Peak bytes of resampling and rendering ``num_frames`` of ``image_size`` and saving them,
    an upper estimate measured with tracemalloc: per frame the RGB image, the silhouette and
    its packed copy for saving, and about 6 kB of geometry; per pixel about 32 bytes of
    background, texture and drawing buffers (about 200 more with pixel noise)."""
    pixels = image_size[0] * image_size[1] if image_size else 0
    per_pixel = 32 + (200 if noise else 0)
    return num_frames * (4.125 * pixels + 6000) + per_pixel * pixels + 16e6


def _check_render_memory(num_frames: int, image_size, noise: bool) -> None:
    from jaxtrack._files import NotEnoughMemoryError, check_memory

    what = f"rendering {num_frames} frames" + (
        f" of {image_size[0]}x{image_size[1]}" if image_size else "")
    try:
        check_memory(_render_memory(num_frames, image_size, noise), what)
    except NotEnoughMemoryError as error:
        raise UserError(f"{error}; render fewer frames (--frames, a lower --fps) or smaller "
                        "images (--size)") from None


def _render_camera(spec: str, motion, size, seed: int):
    from pathlib import Path

    from jaxtrack.body.camera import read_qca
    from jaxtrack.body.render import fit_camera, frontal_camera, random_camera, stage_for_cameras

    if spec in ("frontal", "random"):
        size = size or (640, 480)
        if spec == "frontal":
            return motion, frontal_camera(motion, size)
        return motion, random_camera(seed, motion, size)
    if not spec.startswith("qca:") or spec.count(":") < 2:
        raise UserError(f"--camera must be frontal, random or qca:FILE:INDEX, got {spec!r}")
    file, _, index = spec[4:].rpartition(":")
    path = Path(file)
    if not path.is_file():
        from jaxtrack.data import path as data_path

        try:
            path = data_path(file)
        except (FileNotFoundError, ValueError):
            raise UserError(f"no calibration file {file!r} (a path, or a data name such as "
                            "pose2sim/Calib.qca.txt)") from None
    try:
        cameras = read_qca(path, world_up="y")
    except (OSError, ValueError) as error:
        raise UserError(" ".join(str(error).split())) from None
    names = [camera.name for camera in cameras]
    if index.isdigit() and int(index) < len(cameras):
        camera = cameras[int(index)]
    elif index in names:
        camera = cameras[names.index(index)]
    else:
        raise UserError(f"camera {index!r} is not in {path.name}: it has {len(cameras)} "
                        f"cameras, index 0-{len(cameras) - 1} or {', '.join(names)}")
    # the lab's cameras look at their capture volume, not at the clip's own origin
    staged = stage_for_cameras(motion, cameras)
    return staged, fit_camera(camera, size) if size else camera


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from jaxtrack.body.markers import HUMANEVA_15, UPPER_BODY_12, MarkerMapError
    from jaxtrack.body.motion import MocapFormatError, load_motion

    out = _render_output(args.out, "--out")
    video = _render_output(args.video, "--video") if args.video else None
    seed, occluders, noise, blur = args.seed, args.occluders, args.noise, args.blur
    size = None
    if args.size:
        width, _, height = args.size.lower().partition("x")
        if not (width.isdigit() and height.isdigit() and int(width) >= 16 and int(height) >= 16):
            raise UserError(f"--size must look like 640x480 (at least 16x16), got {args.size!r}")
        size = (int(width), int(height))
    try:
        if Path(args.mocap).is_file():
            motion = load_motion(args.mocap)
        elif Path(args.mocap).suffix.lower() in (".bvh", ".amc"):
            raise UserError(f"no motion file {args.mocap}")
        else:
            from jaxtrack.data import load_clip

            try:
                motion = load_clip(args.mocap)
            except (FileNotFoundError, ValueError) as error:
                if isinstance(error, MocapFormatError):
                    raise
                raise UserError(f"no motion file or clip named {args.mocap!r} (clip names look "
                                "like animateddrawings/fair1_wave_hello or cmu_amc/07_01; see "
                                "jaxtrack.data.list_clips())") from None
    except (MocapFormatError, FileNotFoundError) as error:
        raise UserError(" ".join(str(error).split())) from None
    try:
        if args.frames:
            start, _, stop = args.frames.partition(":")
            motion = motion.select(int(start or 0), int(stop) if stop else None)
        if args.fps:
            fps = args.fps
            known_size = size or ((640, 480) if args.camera in ("frontal", "random") else None)
            _check_render_memory(_resampled_frames(motion, fps), known_size, noise > 0)
            motion = motion.resample(fps)
    except ValueError as error:
        raise UserError(f"--frames/--fps: {error}") from None
    markers = HUMANEVA_15 if args.markers == "humaneva15" else UPPER_BODY_12
    try:
        motion, camera = _render_camera(args.camera, motion, size, seed)
    except (MarkerMapError, ValueError) as error:  # a rig without hips/shoulders, say
        raise UserError(" ".join(str(error).split())) from None

    from jaxtrack.body.render import render_motion
    from jaxtrack.body.sequence import save_sequence
    from jaxtrack.vision import write_video

    _check_render_memory(motion.num_frames, camera.image_size, noise > 0)
    _check_output_size(out, motion.num_frames, tuple(camera.image_size), args.allow_large)
    try:
        sequence = render_motion(motion, camera, background=args.background, markers=markers,
                                 seed=seed, noise_std=noise, blur=blur, occluders=occluders)
    except (MarkerMapError, ValueError) as error:
        raise UserError(" ".join(str(error).split())) from None
    from jaxtrack.cli._common import outputs_or_nothing

    with outputs_or_nothing() as written:  # all or nothing, Ctrl-C included
        try:
            written.append(save_sequence(out, sequence))
        except OSError as error:
            raise UserError(f"cannot write --out {out}: {error.strerror or error}") from None
        if video is not None:
            try:
                written.append(write_video(sequence, video, overlay=True))
            except OSError as error:
                raise UserError(f"cannot write --video {video}: "
                                f"{error.strerror or error}") from None
    visible = sequence.visibility.mean() if sequence.visibility.size else 0.0
    print(f"rendered {sequence.num_frames} frames {sequence.image_size[0]}x"
          f"{sequence.image_size[1]} of {motion.source} ({visible:.0%} of markers visible) "
          f"-> {out}" + (f", {video}" if video else ""))
    return 0
