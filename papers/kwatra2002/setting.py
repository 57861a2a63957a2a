"""The paper's own setting on HDM05: one actor, one fixed side camera, 640 × 480.

Kwatra, Bobick & Johnson (2002, §4) filmed one person from one fixed camera through an
11-second sequence of standing, sitting, crawling and lying, and learned the posture model from
that camera. Here one HDM05 actor (``bd``) plays that person:

- every take is staged the same way (:func:`stage`): its first frame's pelvis moved to the
  origin and the body turned so that it first faces +z, as an actor who starts each take on
  the same mark facing the same way;
- one camera (:func:`side_camera`) looks at the actor from their left, level but for a small
  elevation, and is framed (:func:`jaxtrack.body.viewpoints.frame_subject`) on every point of
  the drawn figure — top of the head, hand tips, toes — over *all* the actor's staged takes, so
  the whole body stays in the image when they lie down, squat or crouch;
- the training takes are every take of the actor but the held-out test takes, rendered through
  that camera, and also mirrored left to right (a body lying the other way), as the paper's
  training set held lying facing left and right;
- the test takes are the held-out lie-down, squat and crouch takes (:data:`TEST_TAKES`).

Data: ``../shared/data/hdm05_cut`` (CC BY-SA 3.0, cite the HDM05 report; SOURCE.txt there). Its
files are read in place and never copied.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jaxtrack.priors.postures import LYING_LEFT, LYING_RIGHT

__all__ = ["ACTOR", "BACKGROUND", "DATA_ROOT", "FPS", "IMAGE_SIZE", "MODEL_OPTIONS",
           "TEST_TAKES", "VALIDATION_GRID", "VALIDATION_TAKES", "Take", "actor_takes",
           "data_root", "extremity_points", "load_take", "mirrored", "render_take",
           "side_camera", "stage"]

DATA_ROOT = Path(__file__).resolve().parents[3] / "shared" / "data" / "hdm05_cut"
"""Where the HDM05 cut clips are by default (``JAXTRACK_HDM05`` overrides)."""
ACTOR = "bd"
IMAGE_SIZE = (640, 480)
FPS = 30.0
"""Frames per second the 120 Hz takes are resampled to (video rate)."""
TEST_TAKES = ("lieDownFloor_001", "squat1Reps_001", "depositFloorR_001")
"""The held-out lie-down, squat and crouch (put an object on the floor) takes."""
VALIDATION_TAKES = ("lieDownFloor_002", "squat1Reps_002", "depositFloorR_002")
"""Where the tracker's settings are chosen (trained without them and the test takes)."""
VALIDATION_GRID = (
    {"initial_std": 20.0, "redraw_on_switch": True},
    {"initial_std": 5.0, "redraw_on_switch": True},
    {"initial_std": 20.0, "redraw_on_switch": False},
    {"initial_std": 20.0, "redraw_on_switch": True, "part_proposal": "posterior"},
)
"""The mixed-state model's settings tried on the validation takes
(:class:`jaxtrack.trackers.mixed_state.MixedStateModel`'s keywords): the library default
first."""
MODEL_OPTIONS = {"initial_std": 20.0, "redraw_on_switch": True}
"""The settings of the test run: :data:`VALIDATION_GRID`'s best smoothed MSE."""
ELEVATION = 0.1
"""The side camera's elevation (radians): nearly level, as a camera on a tripod."""
MARGIN = 0.05
"""Empty border of the image (fraction of its width and height) around the actor's extent."""


def data_root() -> Path:
    """The HDM05 folder (``$JAXTRACK_HDM05`` or :data:`DATA_ROOT`), checked to exist."""
    root = Path(os.environ.get("JAXTRACK_HDM05", DATA_ROOT))
    if not (root / "asf").is_dir():
        raise FileNotFoundError(f"no HDM05 cut clips at {root} (expected asf/ and one folder "
                                "per motion class); set JAXTRACK_HDM05 to the hdm05_cut folder")
    return root


@dataclass(frozen=True)
class Take:
    """One take of one actor: ``name`` is ``<class>_<take>``, e.g. ``squat1Reps_001``."""

    actor: str
    name: str
    path: Path

    @property
    def motion_class(self) -> str:
        return self.name.rsplit("_", 1)[0]


def actor_takes(actor: str = ACTOR, root: Path | None = None) -> list[Take]:
    """Every take of ``actor`` in the HDM05 folder, sorted by name."""
    root = data_root() if root is None else Path(root)
    takes = []
    for path in sorted(root.glob(f"*/HDM_{actor}_*_120.amc")):
        stem = path.name[len(f"HDM_{actor}_"):-len("_120.amc")]
        takes.append(Take(actor, stem, path))
    if not takes:
        raise FileNotFoundError(f"no takes of actor {actor!r} under {root} (files "
                                f"*/HDM_{actor}_*_120.amc); actors: bd, bk, dg, mm, tr")
    return takes


def load_take(take: Take, root: Path | None = None):
    """The take as a :class:`jaxtrack.body.Motion` at :data:`FPS`, staged (:func:`stage`)."""
    from jaxtrack.body import load_motion

    root = data_root() if root is None else Path(root)
    motion = load_motion(take.path, asf=root / "asf" / f"HDM_{take.actor}.asf")
    return stage(motion.resample(FPS))


def stage(motion):
    """The motion moved so its first frame's pelvis is above the origin and turned about the
    vertical so that it first faces +z (its first ten frames' facing from hips and
    shoulders)."""
    from jaxtrack.body import Motion
    from jaxtrack.body._staging import _facing
    from jaxtrack.body.markers import HUMANEVA_15, marker_positions

    joints = marker_positions(motion, HUMANEVA_15)
    forward = _facing(joints[:10])
    angle = np.arctan2(forward[0], forward[2])  # rotate by −angle: forward → +z
    cosine, sine = np.cos(-angle), np.sin(-angle)
    rotation = np.array([[cosine, 0.0, sine], [0.0, 1.0, 0.0], [-sine, 0.0, cosine]])
    pelvis = joints[0, HUMANEVA_15.index("pelvis")]
    origin = np.array([pelvis[0], 0.0, pelvis[2]])
    positions = (motion.positions - origin) @ rotation.T
    return Motion(positions, motion.joint_names, motion.parents, motion.fps, motion.source,
                  motion.rig)


def extremity_points(motion) -> np.ndarray:
    """``(time, points, 3)`` every drawn figure point that can be outermost: the figure's
    joints and the top of the head, the hand tips and the toes
    (:func:`jaxtrack.experiments.mixed_state.extremities`)."""
    from jaxtrack.body._figure import FIGURE_MARKERS
    from jaxtrack.body.markers import marker_positions
    from jaxtrack.experiments.mixed_state import extremities

    joints = marker_positions(motion, FIGURE_MARKERS)
    return np.concatenate([joints, extremities(joints)], axis=1)


def side_camera(motions, image_size: tuple[int, int] = IMAGE_SIZE, *,
                elevation: float = ELEVATION, margin: float = MARGIN):
    """One camera on the staged actor's left (+x), framed on every extremity of every motion
    in ``motions`` (:func:`extremity_points`): the whole body in the image in every frame."""
    from jaxtrack.body.camera import look_at
    from jaxtrack.body.viewpoints import frame_subject

    points = np.concatenate([extremity_points(m).reshape(-1, 3) for m in motions])
    low, high = points.min(axis=0), points.max(axis=0)
    centre = 0.5 * (low + high)
    radius = float(np.max(np.linalg.norm(points - centre, axis=-1)))
    distance = max(5.0, radius + 1.0)  # outside the motion, far enough for little perspective
    direction = np.array([np.cos(elevation), np.sin(elevation), 0.0])
    camera = look_at(centre + distance * direction, centre, np.array([0.0, 1.0, 0.0]), 1.0,
                     tuple(image_size), name="side")
    return frame_subject(points, camera, tuple(image_size), margin)


@dataclass(frozen=True)
class RenderedTake:
    """One take through the side camera: silhouettes and the truth (as
    :class:`jaxtrack.experiments.mixed_state.PostureSequence`)."""

    name: str
    masks: np.ndarray
    parts: np.ndarray
    labels: np.ndarray
    silhouette_iou: float = float("nan")
    """Mean over frames of the background-subtraction silhouette's intersection over union
    with the renderer's exact one (1 where both are empty)."""


BACKGROUND = "clutter"
"""The empty scene behind the actor. Over the ``photo`` background (a real frame of a lab
video) some of the renderer's clothing colours are too close to the floor for background
subtraction: the largest blob kept then loses the legs or the trunk (mean intersection over
union with the exact silhouette 0.47 on the crouch take at seed 1002, 0.63 on the squat at
seed 1001, against 0.96–0.99 over ``clutter``). The paper's silhouettes were whole; the
intersection over union is reported with every result."""


def render_take(motion, camera, name: str, *, background: str = BACKGROUND, seed: int = 0
                ) -> RenderedTake:
    """Render a staged motion through ``camera`` over a known empty scene, take its
    silhouettes by background subtraction, and keep the true extremities (head top, hand tips,
    toes: ``(time, 5, 2)`` pixels) and postures
    (:func:`jaxtrack.priors.postures.posture_labels`)."""
    from jaxtrack.body._backgrounds import make_background
    from jaxtrack.body._figure import FIGURE_MARKERS
    from jaxtrack.body._staging import project_numpy
    from jaxtrack.body.render import render_motion
    from jaxtrack.experiments.mixed_state import extremities
    from jaxtrack.priors.postures import posture_labels
    from jaxtrack.vision.histograms import silhouettes

    scene, _ = make_background(background, camera.image_size, np.random.default_rng(seed))
    rendered = render_motion(motion, camera, image_size=camera.image_size, background=scene,
                             markers=FIGURE_MARKERS, seed=seed, progress=False)
    truth, _ = project_numpy(rendered.camera, extremities(rendered.joints_3d))
    labels = posture_labels(rendered.joints_3d, rendered.markers_2d, rendered.marker_names)
    masks = silhouettes(rendered.images, scene)
    exact = np.asarray(rendered.silhouettes, bool)
    union = np.sum(masks | exact, axis=(1, 2))
    iou = np.where(union > 0, np.sum(masks & exact, axis=(1, 2)) / np.maximum(union, 1), 1.0)
    return RenderedTake(name, masks, np.asarray(truth, np.float64), labels, float(iou.mean()))


def mirrored(take: RenderedTake) -> RenderedTake:
    """The take's left-right mirror image: silhouettes flipped, lying left ↔ lying right (the
    body lying the other way; what a camera on the actor's other side sees)."""
    width = take.masks.shape[2]
    labels = take.labels.copy()
    labels[take.labels == LYING_LEFT] = LYING_RIGHT
    labels[take.labels == LYING_RIGHT] = LYING_LEFT
    parts = take.parts.copy()
    parts[..., 0] = width - 1 - parts[..., 0]
    return RenderedTake(f"{take.name}_mirrored", take.masks[:, :, ::-1].copy(), parts, labels,
                        take.silhouette_iou)
