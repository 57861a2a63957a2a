"""The video of several views tracked side by side, written as the views' frames arrive: a
stream of frames (one list of the views' images per frame, decoded a chunk at a time by the
caller) in, an ``.mp4`` out, no more than one frame of each view held here.

Per frame each view's :func:`jaxtrack.vision.panels.contour_panel` (view ``v`` in
``METHOD_COLOURS[v]``), put together by :func:`jaxtrack.vision.panels.compose_views` with the
ambiguity bars and the selected view framed (Ong & Gong 2002, Fig. 17), and with skeletons the
recovered 3-D skeleton at the right (:func:`jaxtrack.vision.panels.skeleton_panel`). The
whole-clip version, :func:`jaxtrack.vision.panels.write_views_video`, takes the views' images
as arrays; this one is what ``jaxtrack track --method linear-combination`` writes through
:func:`jaxtrack.experiments.pipeline.track_video`.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np

from jaxtrack.vision.overlay import METHOD_COLOURS
from jaxtrack.vision.panels import compose_views, contour_panel, skeleton_panel
from jaxtrack.vision.video import write_frames

__all__ = ["write_views_stream"]


def write_views_stream(frames: Iterable[Sequence[np.ndarray]], contours: Sequence[np.ndarray],
                       markers: Sequence[np.ndarray], path: str | os.PathLike, *, fps: float,
                       names: Sequence[str], marker_names: Sequence[str],
                       labels: Sequence[Sequence[str]] | None = None,
                       ambiguity: np.ndarray | None = None,
                       selected: Sequence[int | None] | None = None, zoom: int = 1,
                       skeletons: np.ndarray | None = None,
                       skeleton_names: Sequence[str] | None = None) -> Path:
    """Write an ``.mp4`` of several views tracked, frame by frame as ``frames`` yields them.

    Args:
        frames: per frame a list of the views' ``(height, width, 3)`` uint8 RGB images (one
            size), exactly as many frames as ``contours`` holds.
        contours: per view ``(time, points, 2)`` pixels of its images.
        markers: per view ``(time, markers, 2)`` pixels of its images.
        path: the video file, written atomically.
        fps: frames per second of the video.
        names: per view its legend.
        marker_names: ``(markers,)`` names.
        labels: per view and frame the text of the panel's bottom-left corner, or None.
        ambiguity: ``(time, views)`` (bars scaled to the clip's largest finite value), or
            None: no bars.
        selected: per frame the view to frame, or None there; None: none framed.
        zoom: integer enlargement of every panel.
        skeletons: ``(time, joints, 3)`` the 3-D skeleton to draw per frame (x right, y up,
            metres); NaN where there is none. None: no skeleton panel.
        skeleton_names: ``(joints,)`` their names; needed with ``skeletons``.

    Returns:
        The path.

    Raises:
        ValueError: shapes that disagree, or a stream of another length or number of views.
        OSError: OpenCV cannot open a writer for the file.
    """
    views = len(names)
    if not views or not len(contours) == len(markers) == views:
        raise ValueError(f"give one array of contours and markers and one name per view, got "
                         f"{len(contours)}, {len(markers)} and {views}")
    count = len(contours[0])
    if any(len(values) != count for values in (*contours, *markers)):
        raise ValueError(f"every view's contours and markers must hold {count} frames")
    if labels is not None and any(len(texts) != count for texts in labels):
        raise ValueError(f"labels must hold {count} texts per view")
    if ambiguity is not None:
        ambiguity = np.asarray(ambiguity, np.float64)
        if ambiguity.shape != (count, views):
            raise ValueError(f"ambiguity must be ({count}, {views}), got {ambiguity.shape}")
    if skeletons is not None:
        skeletons = np.asarray(skeletons, np.float64)
        if skeleton_names is None or skeletons.shape != (count, len(skeleton_names), 3):
            raise ValueError(f"skeletons must be ({count}, joints, 3) with one name per joint "
                             f"in skeleton_names, got {skeletons.shape}")
    finite = np.zeros(0) if ambiguity is None else ambiguity[np.isfinite(ambiguity)]
    largest = max(float(finite.max(initial=0.0)), 1e-9)

    def frame(t: int, images: Sequence[np.ndarray]) -> np.ndarray:
        if len(images) != views:
            raise ValueError(f"frame {t} holds {len(images)} views' images, not {views}")
        panels = [contour_panel(images[v], np.asarray(contours[v][t]),
                                np.asarray(markers[v][t]), marker_names, name=names[v],
                                colour=METHOD_COLOURS[v % len(METHOD_COLOURS)],
                                label=None if labels is None else labels[v][t], zoom=zoom)
                  for v in range(views)]
        composed = compose_views(panels, ambiguity=None if ambiguity is None else ambiguity[t],
                                 full_scale=largest,
                                 selected=None if selected is None else selected[t])
        if skeletons is None:
            return composed
        return np.concatenate([composed, skeleton_panel(skeletons[t], skeleton_names,
                                                        height=composed.shape[0])], axis=1)

    stream = iter(frames)
    head = next(stream, None)
    if head is None:
        raise ValueError("frames yielded no frame")
    first = frame(0, head)

    def drawn() -> Iterator[np.ndarray]:
        yield first
        done = 1
        for images in stream:
            if done == count:
                raise ValueError(f"frames yielded more than the {count} frames tracked")
            yield frame(done, images)
            done += 1
        if done != count:
            raise ValueError(f"frames yielded {done} frames, not the {count} frames tracked")

    return write_frames(drawn(), path, fps, (first.shape[1], first.shape[0]))
