"""``jaxtrack triangulate``: per-view tracks made by projecting a known 3-D skeleton through the
Pose2Sim demo's real calibration are triangulated back into a ``.trc`` (Y up, metres) within a
micrometre; a view's lost frame is left out of that frame, a marker seen by one view is blank;
bad input is one line."""

from __future__ import annotations

import json
from pathlib import Path

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body import UPPER_BODY_12, project, read_qca
from jaxtrack.cli import triangulate
from jaxtrack.cli._common import OneLineParser, UserError
from jaxtrack.vision.trc import read_trc

CALIBRATION = Path(__file__).parents[2] / "jaxtrack" / "data" / "files" / \
    "pose2sim_demo_singleperson" / "Calib.qca.txt"


def _run(argv: list[str]) -> int:
    parser = OneLineParser(prog="jaxtrack")
    triangulate.add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["triangulate", *argv])
    return args.handler(args)


def _skeleton(frames: int = 3) -> np.ndarray:
    """A person-sized cloud of 12 points near the demo's subject (Z-up world, metres)."""
    rng = np.random.default_rng(0)
    base = np.array([-0.05, 0.9, -1.4])[[2, 0, 1]]  # the reference's first hip, in the Z-up world
    return base + rng.uniform(-0.3, 0.3, size=(frames, len(UPPER_BODY_12), 3)) + \
        np.array([0.0, 0.0, 0.5])


def _tracks(folder: Path, skeleton: np.ndarray, lost: dict[int, list[int]]) -> list[Path]:
    """One track.json per camera of the calibration: the skeleton projected without lens
    distortion; ``lost[view]`` lists the frames whose status is "lost" in that view."""
    paths = []
    for view, camera in enumerate(read_qca(CALIBRATION)):
        pinhole = eqx.tree_at(lambda c: c.distortion, camera, jnp.zeros(5))
        pixels = np.asarray(project(pinhole, jnp.asarray(skeleton)))
        frames = [{"frame": 10 + t, "status": "lost" if t in lost.get(view, []) else "ok",
                   "markers": {name: pixels[t, k].tolist()
                               for k, name in enumerate(UPPER_BODY_12)}}
                  for t in range(len(skeleton))]
        path = folder / f"cam{view}"
        path.mkdir()
        (path / "track.json").write_text(json.dumps({
            "marker_names": list(UPPER_BODY_12), "frames": frames,
            "size": list(camera.image_size), "fps": 60.0}))
        paths.append(path)
    return paths


def test_tracks_projected_from_a_known_skeleton_triangulate_back_into_a_trc(tmp_path):
    skeleton = _skeleton()
    # frame 1: view 0 lost (three views left); frame 2: all but view 3 lost (one view: blank)
    tracks = _tracks(tmp_path, skeleton, {0: [1, 2], 1: [2], 2: [2]})
    out = tmp_path / "person.trc"
    assert _run(["--tracks", *map(str, tracks), "--calibration", str(CALIBRATION),
                 "--out", str(out)]) == 0
    positions, names, header = read_trc(out)
    assert names == UPPER_BODY_12 and header["DataRate"] == 60.0 and header["Units"] == "m"
    assert header["frames"].tolist() == [11, 12, 13]  # video frame + 1, as Pose2Sim's
    world = positions[..., [2, 0, 1]]  # the .trc is Y up: back to the calibration's Z-up world
    np.testing.assert_allclose(world[:2], skeleton[:2], atol=1e-6)
    assert np.isnan(world[2]).all()


@pytest.mark.parametrize(("argv", "message"), [
    (["--cameras", "0"], "1 cameras for 2 tracks"),
    (["--cameras", "0", "7"], "holds 4 cameras"),
    (["--out", "person.csv"], "give a .trc file name"),
])
def test_bad_arguments_are_one_line(tmp_path, argv, message):
    tracks = _tracks(tmp_path, _skeleton(), {})[:2]
    arguments = ["--tracks", *map(str, tracks), "--calibration", str(CALIBRATION),
                 "--out", str(tmp_path / "person.trc"), *argv]
    with pytest.raises(UserError, match=message) as error:
        _run(arguments)
    assert "\n" not in str(error.value) and not (tmp_path / "person.trc").exists()
