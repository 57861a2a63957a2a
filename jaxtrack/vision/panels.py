"""Views of one frame drawn as panels: a contour and markers over an enlarged frame, and several
views side by side with an ambiguity bar under each and the selected one framed; and the video
made of them (:func:`write_views_video`).

They draw the linear-combination tracker's overlay (Ong & Gong 2002, Fig. 17: the views of a
frame, their ambiguity and the view the tracker reads); the markers are drawn by the one drawer,
:func:`jaxtrack.vision.overlay.draw_tracks`, and the video is written by
:func:`jaxtrack.vision.video.write_frames` (atomically). Contours are drawn with NumPy (no
OpenCV): sampled along each segment at least once per pixel, two pixels wide. Why drawing lives
here: ``docs/layers.md``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from jaxtrack.vision.overlay import draw_tracks

__all__ = ["AMBIGUITY_COLOUR", "SELECTED_COLOUR", "SKELETON_REACH", "compose_views",
           "contour_panel", "draw_contour", "skeleton_panel", "write_views_video"]

AMBIGUITY_COLOUR = (200, 80, 80)
"""RGB of the ambiguity bars."""

SELECTED_COLOUR = (255, 224, 0)
"""RGB of the frame around the selected view."""

SKELETON_REACH = 1.0
"""Metres from the root joint to the top and bottom edges of :func:`skeleton_panel`'s drawings
(0.8 of that to their sides): an upper body (about 0.8 m from head to pelvis, hands 0.8 m from
the neck at full stretch) fits whatever its pose."""

# the 1-pixel offsets each sample is drawn at: a line two pixels wide in x and in y
_PEN = ((0, 0), (1, 0), (0, 1))


def draw_contour(image: np.ndarray, contour: np.ndarray, colour: Sequence[int]) -> np.ndarray:
    """A copy of ``image`` with the closed polyline through ``contour`` drawn two pixels wide.

    Args:
        image: ``(height, width, 3)`` uint8 RGB.
        contour: ``(points, 2)`` pixels ``(x, y)``, joined in order and last to first. A contour
            with a non-finite point (a frame without one) is not drawn; points outside the
            image are clipped.
        colour: RGB.

    Returns:
        ``(height, width, 3)`` uint8 RGB.
    """
    image = np.array(image, dtype=np.uint8)
    points = np.asarray(contour, np.float64)
    if points.ndim != 2 or not np.all(np.isfinite(points)):
        return image
    following = np.roll(points, -1, axis=0)
    steps = int(np.ceil(np.abs(following - points).max(initial=0))) + 1
    fractions = np.linspace(0.0, 1.0, steps)[:, None, None]
    samples = (points + fractions * (following - points)).reshape(-1, 2).round().astype(int)
    height, width = image.shape[:2]
    for dx, dy in _PEN:
        x, y = samples[:, 0] + dx, samples[:, 1] + dy
        inside = (x >= 0) & (x < width) & (y >= 0) & (y < height)
        image[y[inside], x[inside]] = colour
    return image


def contour_panel(image: np.ndarray, contour: np.ndarray, markers: np.ndarray,
                  marker_names: Sequence[str], *, name: str, colour: Sequence[int],
                  label: str | None = None, zoom: int = 1) -> np.ndarray:
    """One view: the frame enlarged ``zoom`` times (each pixel repeated), with the contour
    (:func:`draw_contour`) and the markers (:func:`draw_tracks`, legend ``name``) drawn over it.

    Args:
        image: ``(height, width, 3)`` uint8 RGB.
        contour: ``(points, 2)`` pixels of ``image`` (pixel centres at integers).
        markers: ``(markers, 2)`` pixels of ``image``; non-finite ones are not drawn.
        marker_names: ``(markers,)`` names (their skeleton is ``jaxtrack.body.marker_edges``).
        name: the legend's text.
        colour: RGB of the contour, the markers and the legend.
        label: text for the bottom-left corner (a frame counter, a status).
        zoom: integer enlargement (≥ 1).

    Returns:
        ``(zoom × height, zoom × width, 3)`` uint8 RGB.
    """
    if not (isinstance(zoom, int | np.integer) and zoom >= 1):
        raise ValueError(f"zoom must be a positive integer, got {zoom!r}")
    panel = np.repeat(np.repeat(np.asarray(image, np.uint8), zoom, axis=0), zoom, axis=1)

    def enlarged(points):  # pixel centres stay at integers
        return (np.asarray(points, np.float64) + 0.5) * zoom - 0.5

    panel = draw_contour(panel, enlarged(contour), colour)
    return draw_tracks(panel, {name: enlarged(markers)}, marker_names, label=label,
                       colours={name: tuple(colour)})


def compose_views(panels: Sequence[np.ndarray], *, ambiguity: Sequence[float] | None = None,
                  full_scale: float = 1.0, selected: int | None = None, bar_height: int = 18,
                  border: int = 4) -> np.ndarray:
    """Views side by side; with ``ambiguity`` a bar under each, with ``selected`` that view
    framed (Ong & Gong 2002, Fig. 17).

    Args:
        panels: ``(height, width, 3)`` uint8 RGB views of one size.
        ambiguity: one value per view, drawn as a bar of ``width × value / full_scale`` pixels
            (at least 1, at most the panel's width); a non-finite value (a view that did not
            observe the frame) leaves its bar empty. None: no bars.
        full_scale: the ambiguity that fills a bar (the largest over a clip keeps bars of
            different frames comparable); > 0.
        selected: the index of the view to frame in :data:`SELECTED_COLOUR`, or None.
        bar_height: rows of each bar (the bar itself leaves 3 rows above and below).
        border: width of the frame, pixels.

    Returns:
        ``(height [+ bar_height], views × width, 3)`` uint8 RGB.
    """
    panels = [np.asarray(panel, np.uint8) for panel in panels]
    if not panels:
        raise ValueError("panels is empty; give at least one view")
    shapes = {panel.shape for panel in panels}
    if len(shapes) != 1 or panels[0].ndim != 3 or panels[0].shape[-1] != 3:
        raise ValueError(f"panels must be (height, width, 3) images of one size, got shapes "
                         f"{sorted(shapes)}")
    if ambiguity is not None and len(ambiguity) != len(panels):
        raise ValueError(f"ambiguity has {len(ambiguity)} values for {len(panels)} panels")
    if not full_scale > 0:
        raise ValueError(f"full_scale must be > 0, got {full_scale}")
    if selected is not None and not 0 <= selected < len(panels):
        raise ValueError(f"selected must index one of the {len(panels)} panels, got {selected}")
    if bar_height < 7 or border < 1:
        raise ValueError(f"bar_height must be at least 7 and border at least 1, got "
                         f"{bar_height} and {border}")
    columns = []
    for index, panel in enumerate(panels):
        column = panel.copy()
        if ambiguity is not None:
            bar = np.zeros((bar_height, panel.shape[1], 3), np.uint8)
            value = float(ambiguity[index])
            if np.isfinite(value):
                bar[3:-3, :max(1, round(panel.shape[1] * value / full_scale))] = AMBIGUITY_COLOUR
            column = np.concatenate([column, bar])
        if selected == index:
            column[:border] = column[-border:] = SELECTED_COLOUR
            column[:, :border] = column[:, -border:] = SELECTED_COLOUR
        columns.append(column)
    return np.concatenate(columns, axis=1)


def skeleton_panel(skeleton: np.ndarray, joint_names: Sequence[str], *, height: int,
                   colour: Sequence[int] = SELECTED_COLOUR, label: str | None = None,
                   reach: float = SKELETON_REACH) -> np.ndarray:
    """A recovered 3-D skeleton drawn twice, orthographically: from the front (x right, y up)
    and from the side (z right, y up), on a dark panel (Ong & Gong 2002, Fig. 17's 3-D
    skeletons).

    Args:
        skeleton: ``(joints, 3)`` metres, x right, y up, z toward the viewer, relative to any
            point near the body (the linear-combination tracker's are relative to the neck);
            a skeleton with a non-finite joint (a frame without one) leaves the panel empty.
        joint_names: ``(joints,)`` names (the stick figure is ``jaxtrack.body.marker_edges``).
        height: rows of the panel; each drawing is ``0.8 × height`` wide.
        colour: RGB of the figures.
        label: text for the bottom-left corner, or None.
        reach: metres from the root joint (``joint_names[1]``, the neck, when there are two
            or more joints) to the top and the bottom of the panel, the same for every frame
            so that sizes compare across frames.

    Returns:
        ``(height, 2 × round(0.8 × height), 3)`` uint8 RGB.
    """
    skeleton = np.asarray(skeleton, np.float64)
    if skeleton.shape != (len(joint_names), 3):
        raise ValueError(f"skeleton has shape {skeleton.shape}, expected "
                         f"({len(joint_names)}, 3) for {len(joint_names)} joint names")
    if not (isinstance(height, int | np.integer) and height >= 16):
        raise ValueError(f"height must be an integer of at least 16, got {height!r}")
    if not reach > 0:
        raise ValueError(f"reach must be > 0 metres, got {reach!r}")
    half = round(0.8 * height)
    halves = []
    for name, across in (("3-D front", 0), ("3-D side", 2)):
        canvas = np.full((height, half, 3), 24, np.uint8)
        if np.all(np.isfinite(skeleton)):
            root = skeleton[1 if len(skeleton) > 1 else 0]
            scale = (height / 2) / reach
            points = np.stack([half / 2 + scale * (skeleton[:, across] - root[across]),
                               height / 2 - scale * (skeleton[:, 1] - root[1])], axis=-1)
        else:
            points = np.full((len(joint_names), 2), np.nan)
        halves.append(draw_tracks(canvas, {name: points}, joint_names,
                                  colours={name: tuple(int(c) for c in colour)},
                                  label=label if across == 0 else None))
    panel = np.concatenate(halves, axis=1)
    panel[:, half - 1:half + 1] = 80  # a line between the two drawings
    return panel


def write_views_video(images: Sequence[np.ndarray], contours: Sequence[np.ndarray],
                      markers: Sequence[np.ndarray], path: str | os.PathLike, *, fps: float,
                      names: Sequence[str], marker_names: Sequence[str],
                      labels: Sequence[Sequence[str]] | None = None,
                      ambiguity: np.ndarray | None = None,
                      selected: Sequence[int | None] | None = None, zoom: int = 1,
                      skeletons: np.ndarray | None = None,
                      skeleton_names: Sequence[str] | None = None) -> Path:
    """Write an ``.mp4`` of one or several views tracked side by side: per frame each view's
    :func:`contour_panel` (view ``v`` in ``METHOD_COLOURS[v]``) put together by
    :func:`compose_views`, the ambiguity bars scaled to the largest finite ambiguity of the
    clip; with ``skeletons``, the recovered 3-D skeleton at the right (:func:`skeleton_panel`).

    Args:
        images: per view ``(time, height, width, 3)`` uint8 RGB (one size; the first ``time``
            frames of the shortest are written).
        contours: per view ``(time, points, 2)`` pixels of its images.
        markers: per view ``(time, markers, 2)`` pixels of its images.
        path: the video file, written atomically.
        fps: frames per second of the video.
        names: per view its legend.
        marker_names: ``(markers,)`` names.
        labels: per view and frame the text of the panel's bottom-left corner, or None.
        ambiguity: ``(time, views)`` (:func:`compose_views`), or None: no bars.
        selected: per frame the view to frame, or None there; None: none framed.
        zoom: integer enlargement of every panel.
        skeletons: ``(time, joints, 3)`` the 3-D skeleton to draw per frame (x right, y up,
            metres; :func:`skeleton_panel`), e.g. the selected view's; NaN where there is
            none. None: no skeleton panel.
        skeleton_names: ``(joints,)`` their names; needed with ``skeletons``.

    Returns:
        The path.

    Raises:
        OSError: OpenCV cannot open a writer for the file.
    """
    # the stream writer draws every frame; here the views' arrays are cut to the shortest view
    from jaxtrack.vision.overlay_views import write_views_stream

    if not images or not len(images) == len(contours) == len(markers) == len(names):
        raise ValueError(f"give one array of images, contours and markers and one name per "
                         f"view, got {len(images)}, {len(contours)}, {len(markers)} and "
                         f"{len(names)}")
    count = min(len(frames) for frames in images)
    cut = lambda values: None if values is None else [  # noqa: E731
        np.asarray(view)[:count] for view in values]
    return write_views_stream(
        zip(*(frames[:count] for frames in images), strict=True), cut(contours), cut(markers),
        path, fps=fps, names=names, marker_names=marker_names,
        labels=None if labels is None else [list(texts)[:count] for texts in labels],
        ambiguity=None if ambiguity is None else np.asarray(ambiguity, np.float64)[:count],
        selected=None if selected is None else list(selected)[:count], zoom=zoom,
        skeletons=None if skeletons is None else np.asarray(skeletons, np.float64)[:count],
        skeleton_names=skeleton_names)
