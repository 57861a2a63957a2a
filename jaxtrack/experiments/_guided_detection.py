"""Tracker-guided detection: a detector run, inside the tracking pass, on the region the
tracker's own prediction says its person is in, its detection scored beside the given one by
the detection density's mixture over people.

At frame t the tracker predicts its person's markers at constant velocity from its own
estimates, ``m̂_t = m_{t−1} + (m_{t−1} − m_{t−2})``, and the detector runs on the square around
``m_{t−1}`` and ``m̂_t`` (:func:`guided_region`: their box grown by
``jaxtrack.vision.mediapipe.region_around``'s margin; the whole frame where the tracker holds
no finite estimate). Its detection joins the frame's given one (the detector's pass before
tracking) as a second person of that frame: the normalised detection density
(``jaxtrack.likelihoods.detections``, ``p(D_1..D_n | μ) = ρ Π_j B(D_j) + (1 − ρ)/n Σ_j L(D_j | μ)
Π_{i≠j} B(D_i)``) then weighs each particle by whichever of the two its pose explains, the
other being a passer-by ``B``; where both are the person the two terms agree. No gate decides
which detection is the person: the particles do.

It stays one pass over the video: :class:`GuidedDetections` wraps the tracker the pipeline runs
(:class:`jaxtrack.experiments.detection_tracking.ChunkDetections`); its ``observe`` keeps each
chunk's colour frames on the host (:class:`RegionGuide`), and its ``update`` asks for frame t's
detection through ``jax.experimental.io_callback`` inside the compiled scan, given the
estimates it carries, so the tracker's chunked ``lax.scan`` (``jaxtrack.trackers.track``) is
unchanged. The detector is any object with ``detect(frame, region) -> dict`` as
:class:`jaxtrack.vision.mediapipe.MediaPipeDetector` (MediaPipe in its own process: jaxtrack
never imports it); its time is summed apart from the tracker's (:meth:`RegionGuide.report`).
"""

from __future__ import annotations

import threading

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import io_callback
from jaxtyping import Array, Float, Int

from jaxtrack.trackers import FrameInChunk, Tracker, VideoChunk

__all__ = ["GuidedDetections", "GuidedObservation", "GuidedState", "RegionGuide",
           "guided_region"]

FROM_PREDICTION, FROM_FULL_FRAME = "tracker prediction", "full frame"
"""Where a frame's detection region came from (``track.json``'s ``region_from``)."""


def guided_region(previous, before, frame_size: tuple[float, float], *,
                  margin: float = 0.5) -> tuple[np.ndarray, str]:
    """The detection region of frame t from the tracker's estimates of frames t−1 and t−2.

    Args:
        previous: ``(markers, 2)`` the estimate at t−1 (pixels).
        before: ``(markers, 2)`` the estimate at t−2 (the same as ``previous`` at t = 1).
        frame_size: ``(width, height)`` of the frames.
        margin: as :func:`jaxtrack.vision.mediapipe.region_around`'s.

    Returns:
        ``(region (4,) x0, y0, x1, y1, source)``: the square around ``previous`` and the
        constant-velocity prediction ``2 previous − before`` (markers where both are finite),
        and ``"tracker prediction"``; the whole frame and ``"full frame"`` where ``previous``
        has no finite marker.
    """
    from jaxtrack.vision.mediapipe import region_around

    previous = np.asarray(previous, np.float64)
    before = np.asarray(before, np.float64)
    if previous.ndim != 2 or previous.shape[-1] != 2 or before.shape != previous.shape:
        raise ValueError(f"previous and before must be (markers, 2) estimates of the same "
                         f"markers, got shapes {previous.shape} and {before.shape}")
    width, height = (float(value) for value in frame_size)
    if not (np.isfinite(width) and np.isfinite(height) and width > 0 and height > 0):
        raise ValueError(f"frame_size must be a positive (width, height), got {frame_size}")
    if not np.isfinite(previous).all(-1).any():
        return np.array([0.0, 0.0, width, height]), FROM_FULL_FRAME
    predicted = np.where(np.isfinite(before), 2 * previous - before, previous)
    return region_around(np.concatenate([previous, predicted]), (width, height),
                         margin=margin), FROM_PREDICTION


def _one_person(found: dict) -> tuple[np.ndarray, np.ndarray]:
    """A detector's answer for one frame as the 12 markers ``(12, 2)`` (0 where not found)
    and their confidences ``(12,)``."""
    from jaxtrack.vision.mediapipe import detected_keypoints

    points, confidence = detected_keypoints(found)
    return np.nan_to_num(points), confidence


class RegionGuide:
    """The host side of tracker-guided detection: the colour frames of the chunks being
    tracked, the detector, and what it did per frame.

    Args:
        open_detector: makes the detector when the first frame is detected (so that no
            detector process outlives a run that fails before tracking): an object with
            ``detect(frame (height, width, 3) uint8, region (4,)) -> dict`` of ``landmarks``
            (33, 2) frame pixels, ``visibility`` (33,), ``found``, ``seconds`` (the
            detector's own time) and ``wall_seconds``, and ``close()``
            (:class:`jaxtrack.vision.mediapipe.MediaPipeDetector`).
        margin: the region's margin (:func:`guided_region`; 0.5 as ``region_around``'s
            default: the prediction is not exact, and MediaPipe wants the whole person).

    One guide serves one tracking run at a time (its frames are numbered from the first
    observed; :meth:`close` ends the run).
    """

    def __init__(self, open_detector, *, margin: float = 0.5):
        if not callable(open_detector):
            raise TypeError(f"open_detector must make the detector, got "
                            f"{type(open_detector).__name__}")
        if not (np.isfinite(margin) and margin >= 0):
            raise ValueError(f"margin must be a non-negative number, got {margin}")
        self.open_detector, self.margin = open_detector, float(margin)
        self.detector = None
        self._frames: dict[int, np.ndarray] = {}
        self._records: dict[int, dict] = {}
        self._answers: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._observed = 0
        self._lock = threading.Lock()
        self.error: Exception | None = None

    def keep(self, colour: np.ndarray) -> np.ndarray:
        """Keep a chunk's ``(time, height, width, 3)`` uint8 RGB frames until detected;
        returns their ``(time,)`` int32 positions in the run."""
        colour = np.asarray(colour)
        if colour.ndim != 4 or colour.shape[-1] != 3 or colour.dtype != np.uint8:
            raise ValueError(f"guided detection reads the tracked frames' colour: give "
                             f"(time, height, width, 3) uint8 RGB, got {colour.shape} "
                             f"{colour.dtype}")
        with self._lock:
            first = self._observed
            for offset, image in enumerate(colour):
                self._frames[first + offset] = image
            self._observed += len(colour)
        return np.arange(first, first + len(colour), dtype=np.int32)

    def detect(self, position, previous, before, given_points, given_confidence
               ) -> tuple[np.ndarray, np.ndarray]:
        """Frame ``position``'s detection on the region :func:`guided_region` gives (called
        from the compiled scan; a padded frame's second call returns the first answer).
        ``given_*``: the frame's given detection, kept to report which one the track
        followed. Returns ``(points (12, 2), confidence (12,))`` float32, 0 where absent."""
        position = int(position)
        if position in self._answers:
            return self._answers[position]
        with self._lock:
            frame = self._frames.get(position)
            for old in [index for index in self._frames if index < position]:
                del self._frames[old]  # the scan has passed them
        points, confidence = np.zeros((len(given_confidence), 2)), np.zeros(
            len(given_confidence))
        if frame is None or self.error is not None:
            if frame is None and self.error is None:
                self.error = RuntimeError(f"guided detection: frame {position} was not kept")
            answer = (points.astype(np.float32), confidence.astype(np.float32))
            self._answers[position] = answer
            return answer
        region, source = guided_region(previous, before, frame.shape[1::-1],
                                       margin=self.margin)
        try:
            if self.detector is None:
                self.detector = self.open_detector()
            found = self.detector.detect(frame, region)
            points, confidence = _one_person(found)
        except Exception as error:  # raised after the scan (report), never inside XLA
            self.error = error
            found = {"found": False, "seconds": 0.0, "wall_seconds": 0.0}
        self._records[position] = {
            "region": region, "region_from": source, "found": bool(found["found"]),
            "seconds": float(found["seconds"]), "wall_seconds": float(found["wall_seconds"]),
            "detected": (points.copy(), confidence.copy()),
            "given": (np.asarray(given_points, np.float64).copy(),
                      np.asarray(given_confidence, np.float64).copy())}
        answer = (points.astype(np.float32), confidence.astype(np.float32))
        self._answers[position] = answer
        return answer

    def report(self, markers: np.ndarray, factors) -> dict:
        """What the detector did, for ``track.json``.

        Args:
            markers: ``(time, markers, 2)`` the track (tracking pixels).
            factors: ``(2,)`` tracking pixels per video pixel.

        Returns:
            ``{"record": totals, "frames": per frame a dict or None}``: per frame its region
            (video pixels), where it came from, whether the detector found someone there,
            the detector's seconds, and which detection the track followed (``region``,
            ``given``, ``both`` where they coincide, or ``neither``: the one nearer the
            estimate, within half its keypoint box's diagonal).

        Raises:
            ValueError: the detector failed during the run (one line).
        """
        if self.error is not None:
            text = " ".join(str(self.error).split())
            raise ValueError(f"guided detection failed: {text}")
        factors = np.asarray(factors, np.float64)
        frames, chosen_counts = [], {}
        for t in range(len(markers)):
            entry = self._records.get(t)
            if entry is None:
                frames.append(None)
                continue
            chosen = _followed(np.asarray(markers[t], np.float64), *entry["given"],
                               *entry["detected"])
            chosen_counts[chosen] = chosen_counts.get(chosen, 0) + 1
            region = entry["region"] / np.r_[factors, factors]
            frames.append({"region": [round(float(v), 1) for v in region],
                           "region_from": entry["region_from"], "found": entry["found"],
                           "followed": chosen, "seconds": round(entry["seconds"], 5)})
        records = list(self._records.values())
        return {"record": {
            "frames_detected": len(records),
            "frames_found": sum(entry["found"] for entry in records),
            "region_from": {source: sum(entry["region_from"] == source for entry in records)
                            for source in (FROM_PREDICTION, FROM_FULL_FRAME)},
            "followed": chosen_counts,
            "detector_seconds": round(sum(entry["seconds"] for entry in records), 4),
            "detector_wall_seconds": round(sum(entry["wall_seconds"] for entry in records), 4),
            "margin": self.margin},
            "frames": frames,
            "wall_seconds": sum(entry["wall_seconds"] for entry in records)}

    def close(self) -> None:
        """Close the detector and forget the run (its frames, answers and record), so that
        the guide may serve another."""
        with self._lock:
            self._frames.clear()
            self._records.clear()
            self._answers.clear()
            self._observed, self.error = 0, None
        detector, self.detector = self.detector, None
        if detector is not None and callable(getattr(detector, "close", None)):
            detector.close()


def _followed(estimate, given_points, given_confidence, points, confidence) -> str:
    """Which detection of a frame the estimate ``(markers, 2)`` follows (:meth:`RegionGuide.
    report`)."""
    known = estimate[np.isfinite(estimate).all(-1)]
    if len(known) == 0:
        return "neither"
    diagonal = float(np.hypot(*(known.max(0) - known.min(0))))

    def distance(candidate, weights):
        found = (weights > 0) & np.isfinite(estimate).all(-1)
        if not found.any():
            return np.inf
        return float(np.median(np.linalg.norm(candidate[found] - estimate[found], axis=-1)))

    given, region = distance(given_points, given_confidence), distance(points, confidence)
    near = 0.5 * max(diagonal, 1.0)
    if min(given, region) > near:
        return "neither"
    if max(given, region) <= near and abs(given - region) <= 0.1 * near:
        return "both"
    return "region" if region < given else "given"


class GuidedObservation(eqx.Module):
    """A chunk's observations for :class:`GuidedDetections`: the wrapped tracker's (its
    detections with a second person's slot for the guided detection) and each frame's
    position in the run."""

    observation: object
    position: Int[Array, " time"]


class GuidedState(eqx.Module):
    """The wrapped tracker's state and its last two estimates (the prediction's)."""

    inner: object
    previous: Float[Array, "markers 2"]
    before: Float[Array, "markers 2"]


def _with_guided_slot(detections):
    """The detections ``(time, people, ...)`` with one more person's slot, empty."""
    def pad(leaf):
        leaf = np.asarray(leaf)
        return np.concatenate([leaf, np.zeros_like(leaf[:, :1])], axis=1)

    return eqx.tree_at(lambda d: (d.points, d.confidence), detections,
                       (pad(detections.points), pad(detections.confidence)))


class GuidedDetections(Tracker):
    """A tracker on detections (``ChunkDetections``) whose each frame also gets a detection on
    the region its own prediction gives (module docstring).

    Attributes:
        tracker: the wrapped tracker, whose observation carries ``detections`` (a
            ``DetectionsFrame``) and whose likelihood is the detection density.
        guide: the :class:`RegionGuide` (host side: frames, detector, record).
    """

    tracker: Tracker
    guide: RegionGuide = eqx.field(static=True)

    @property
    def likelihood(self):
        return self.tracker.likelihood

    @property
    def reads(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys((*self.tracker.reads, "colour")))

    @property
    def num_particles(self) -> int:
        return self.tracker.num_particles

    def observe(self, chunk: VideoChunk, out=None) -> GuidedObservation:
        if chunk.colour is None:
            raise ValueError("guided detection reads the tracked frames' colour: give "
                             "colour=...")
        observation = self.tracker.observe(chunk)
        detections = getattr(observation, "detections", None)
        if detections is None:
            raise ValueError(f"guided detection adds a person to the detections the "
                             f"{type(self.tracker).__name__} observes; its observation has none")
        observation = eqx.tree_at(lambda o: o.detections, observation,
                                  _with_guided_slot(detections))
        return GuidedObservation(observation, self.guide.keep(chunk.colour))

    def start(self, key, first_frame: GuidedObservation, initial_pose) -> GuidedState:
        inner = self.tracker.start(key, first_frame.observation, initial_pose)
        markers = jnp.asarray(self.tracker.first_estimate(inner).markers)
        return GuidedState(inner, markers, markers)

    def first_estimate(self, state: GuidedState):
        return self.tracker.first_estimate(state.inner)

    def update(self, key, state: GuidedState, frame):
        chunk = frame.frames if isinstance(frame, FrameInChunk) else jax.tree.map(
            lambda leaf: leaf[None], frame)
        index = frame.index if isinstance(frame, FrameInChunk) else jnp.asarray(0)
        detections = chunk.observation.detections
        given_points, given_confidence = detections.points[index, 0], detections.confidence[
            index, 0]
        dtype = detections.points.dtype
        shapes = (jax.ShapeDtypeStruct(given_points.shape, jnp.float32),
                  jax.ShapeDtypeStruct(given_confidence.shape, jnp.float32))
        points, confidence = io_callback(self.guide.detect, shapes, chunk.position[index],
                                         state.previous, state.before, given_points,
                                         given_confidence)
        # the guided detection is the frame's second person; a frame whose given slot is empty
        # gets it first (the density reads people 0 .. num_people − 1)
        frame_points = jnp.stack([given_points, points.astype(dtype)])
        frame_confidence = jnp.stack([given_confidence, confidence.astype(dtype)])
        present = jnp.any(frame_confidence > 0, -1)
        order = jnp.argsort(~present, stable=True)
        updated = eqx.tree_at(
            lambda d: (d.points, d.confidence, d.num_people), detections,
            (detections.points.at[index].set(frame_points[order]),
             detections.confidence.at[index].set(frame_confidence[order]),
             detections.num_people.at[index].set(jnp.sum(present).astype(
                 detections.num_people.dtype))))
        observation = eqx.tree_at(lambda o: o.detections, chunk.observation, updated)
        inner, estimate = self.tracker.update(key, state.inner,
                                              FrameInChunk(observation, index))
        markers = estimate.markers.astype(state.previous.dtype)
        return GuidedState(inner, markers, state.previous), estimate

    def options(self) -> dict:
        return {**self.tracker.options(),
                "guided_detection": {"region": "tracker prediction (constant velocity)",
                                     "margin": self.guide.margin}}

    def smooth(self, estimates):
        return self.tracker.smooth(estimates)

    def host_report(self, markers: np.ndarray, factors) -> dict:
        """:meth:`RegionGuide.report` (the pipeline calls it after tracking)."""
        return self.guide.report(markers, factors)

    def close(self) -> None:
        """Close the guide's detector (the pipeline calls it when the run ends)."""
        self.guide.close()
