"""``jaxtrack triangulate``: per-view 2-D tracks of one person (``jaxtrack track`` runs on each
calibrated camera's video) → one 3-D track, written as a ``.trc`` file (OpenSim, Pose2Sim).

Each frame's markers are triangulated by the weighted DLT (:func:`jaxtrack.vision.triangulation.
triangulate`, Hartley & Zisserman §12.2) from the views whose track has the frame with status
``ok`` (a lost, degenerate or personless frame is left out of that view); a marker seen by fewer
than two views is missing (blank in the ``.trc``). The calibration is a Pose2Sim ``Calib*.toml``
or a Qualisys ``.qca.txt``; their world is Z-up, and the ``.trc`` is written Y-up in metres, as
Pose2Sim writes its own (``trc = world[..., [1, 2, 0]]``, the inverse of
``jaxtrack.evaluation.reference.trc_to_world``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from jaxtrack.cli._common import UserError, integer, one_line, read_calibration

__all__ = ["add_parser", "read_tracks", "run"]


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "triangulate",
        help="triangulate per-view 2-D tracks from calibrated cameras into a 3-D .trc",
        description=("Triangulate the 2-D tracks jaxtrack track wrote for each calibrated "
                     "camera's video (DLT, weighted by each frame's status) into one 3-D "
                     "track; writes a .trc file (Y up, metres) that OpenSim and Pose2Sim read."))
    parser.add_argument("--tracks", required=True, nargs="+", type=Path, metavar="DIR",
                        help="the output folders (or track.json files) of jaxtrack track, one "
                        "per camera, in the order of --cameras")
    parser.add_argument("--calibration", required=True, type=Path, metavar="FILE",
                        help="the cameras' calibration: Pose2Sim's Calib*.toml or Qualisys's "
                        ".qca.txt")
    parser.add_argument("--cameras", type=integer(0), nargs="+", default=None, metavar="INDEX",
                        help="which cameras of --calibration (0-based, in its order) filmed "
                        "the tracks, one per track (default: the first ones, in order)")
    parser.add_argument("--out", required=True, type=Path, metavar="FILE.trc",
                        help="the .trc file to write")
    parser.set_defaults(handler=run)


def read_tracks(paths: list[Path]) -> tuple[list[dict], tuple[str, ...]]:
    """Each ``--tracks`` entry's ``track.json``, checked to share the markers; or a one-line
    error naming it."""
    records = []
    for path in paths:
        file = path / "track.json" if path.is_dir() else path
        try:
            record = json.loads(file.read_text())
            names = tuple(record["marker_names"])
            frames = record["frames"]
            for frame in frames:
                frame["frame"], frame["status"], frame["markers"]  # noqa: B018
        except FileNotFoundError:
            raise UserError(f"--tracks {path}: no track.json there; give the folders "
                            f"jaxtrack track wrote") from None
        except (OSError, ValueError, KeyError, TypeError) as error:
            raise UserError(f"--tracks {file}: not a jaxtrack track record ({one_line(error)})"
                            ) from None
        if records and names != records[0]["marker_names_tuple"]:
            raise UserError(f"--tracks {file}: its markers differ from {paths[0]}'s")
        record["marker_names_tuple"] = names
        records.append(record)
    return records, records[0]["marker_names_tuple"]


def _cameras(args, count: int) -> list:
    path = args.calibration
    cameras = read_calibration(path)
    chosen = list(range(count)) if args.cameras is None else list(args.cameras)
    if len(chosen) != count:
        raise UserError(f"--cameras: {len(chosen)} cameras for {count} tracks; give one per "
                        f"track")
    if max(chosen) >= len(cameras):
        raise UserError(f"--cameras: {path} holds {len(cameras)} cameras (0 to "
                        f"{len(cameras) - 1}), got {max(chosen)}")
    return [cameras[index] for index in chosen]


def run(args: argparse.Namespace) -> int:
    """``jaxtrack triangulate`` (module docstring)."""
    from jaxtrack.vision.trc import TrcFileError, write_trc
    from jaxtrack.vision.triangulation import triangulate

    if len(args.tracks) < 2:
        raise UserError(f"--tracks: triangulation needs at least 2 views, got "
                        f"{len(args.tracks)}")
    if args.out.suffix != ".trc":
        raise UserError(f"--out {args.out}: give a .trc file name")
    records, names = read_tracks(args.tracks)
    cameras = _cameras(args, len(records))
    for path, record, camera in zip(args.tracks, records, cameras, strict=True):
        # a few pixels of padding apart (the Pose2Sim videos are 1080 wide, their .qca 1088)
        if not np.allclose(record["size"], camera.image_size, rtol=0.02):
            raise UserError(f"--tracks {path}: its video is {record['size'][0]}x"
                            f"{record['size'][1]}, camera {camera.name or '?'} of "
                            f"--calibration is {camera.image_size[0]}x{camera.image_size[1]}; "
                            f"give the tracks in the cameras' order (--cameras)")
    indices = sorted(set.intersection(*({frame["frame"] for frame in record["frames"]}
                                        for record in records)))
    if not indices:
        raise UserError("--tracks: no video frame is in every track; track the same frames "
                        "of each camera's video")
    steps = set(np.diff(indices).tolist()) or {1}
    if len(steps) != 1:
        raise UserError("--tracks: the video frames every track holds are not evenly spaced; "
                        "track the same frames of each camera's video (--frames)")
    points = np.full((len(records), len(indices), len(names), 2), np.nan)
    for view, record in enumerate(records):
        by_frame = {frame["frame"]: frame for frame in record["frames"]}
        for row, index in enumerate(indices):
            frame = by_frame[index]
            if frame["status"] == "ok":
                points[view, row] = [[np.nan if value is None else value
                                      for value in frame["markers"][name]] for name in names]
    world, _ = triangulate(points, cameras)
    rates = {record.get("fps") for record in records}
    rate = rates.pop() if len(rates) == 1 and None not in rates else None
    if rate is None:
        raise UserError("--tracks: their videos' frame rates differ or are unknown; the .trc "
                        "needs one rate")
    try:
        write_trc(args.out, world[..., [1, 2, 0]], names, rate / steps.pop(), "m",
                  first_frame=int(indices[0]) + 1)
    except TrcFileError as error:
        raise UserError(f"--out: {one_line(error)}") from None
    missing = int(np.isnan(world).any(-1).sum())
    print(f"triangulated {len(indices)} frames of {len(names)} markers from {len(records)} "
          f"views ({missing} marker-frames seen by fewer than 2 views, left blank)\n  wrote "
          f"{args.out}")
    return 0
