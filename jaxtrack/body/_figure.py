"""Drawing a clothed human figure from projected joints: shaded, textured capsules, painter's order.

Private to the renderer (`jaxtrack.body.render`). The figure is built from the HumanEva-15 joints
plus the thorax, which every rig supplies, and a few points derived from them in 3-D (head centre,
hand tips, toes, the torso's front and back surfaces), so it looks right from any viewpoint. Each
frame is drawn with OpenCV into one `(height, width, 3)` uint8 buffer holding, per pixel, the part
index (0 = not the figure), the material and the shade; the renderer turns that into colour with
per-material textures, looked up through per-part affine maps (`FigureDrawer.texture_maps`) so
the texture moves with each part. cv2 is imported inside the functions so `import jaxtrack` never
needs it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jaxtrack.body.markers import HUMANEVA_15

FIGURE_MARKERS = (*HUMANEVA_15, "thorax")
"""The joints the figure is built from (every rig in `RIG_MARKER_MAPS` supplies them)."""

MATERIALS = ("none", "skin", "shirt", "stripe", "trousers", "shoes", "hair")
SKIN, SHIRT, STRIPE, TROUSERS, SHOES, HAIR = range(1, 7)

PARTS = (
    "none", "torso", "hips", "neck", "head",
    "right_upper_arm", "right_forearm", "right_hand", "left_upper_arm", "left_forearm",
    "left_hand", "right_thigh", "right_shin", "right_shoe", "left_thigh", "left_shin", "left_shoe",
)
_PART = {name: i for i, name in enumerate(PARTS)}

# Which parts a marker belongs to: a marker seen on one of its own parts is visible whatever the
# (per-part, approximate) depth says.
MARKER_OWNERS = {
    "head": ("head", "neck"), "neck": ("neck", "torso", "head"), "thorax": ("torso",),
    "pelvis": ("torso", "hips"),
    **{f"{side}_{joint}": tuple(f"{side}_{part}" if part not in ("torso", "hips") else part
                                for part in parts)
       for side in ("right", "left")
       for joint, parts in {"shoulder": ("torso", "upper_arm"), "elbow": ("upper_arm", "forearm"),
                            "wrist": ("forearm", "hand"), "hip": ("hips", "thigh", "torso"),
                            "knee": ("thigh", "shin"), "ankle": ("shin", "shoe")}.items()},
}

# Limb capsules: part, start point, end point, radius at start and end (metres for a body of leg
# length 0.84 m, scaled with the subject), material (None: the sleeve material).
_CAPSULES = tuple(
    (f"{s}_{part}", start.format(s=s), end.format(s=s), r0, r1, material)
    for s in ("right", "left")
    for part, start, end, r0, r1, material in (
        ("upper_arm", "{s}_shoulder", "{s}_elbow", 0.055, 0.045, SHIRT),
        ("forearm", "{s}_elbow", "{s}_wrist", 0.045, 0.035, None),
        ("hand", "{s}_wrist", "{s}_hand_tip", 0.040, 0.030, SKIN),
        ("thigh", "{s}_hip", "{s}_knee", 0.085, 0.060, TROUSERS),
        ("shin", "{s}_knee", "{s}_ankle", 0.060, 0.045, TROUSERS),
        ("shoe", "{s}_ankle", "{s}_toe", 0.050, 0.045, SHOES),
    )
) + (("neck", "neck", "head", 0.050, 0.045, SKIN),)

_LIGHT = np.array([-0.45, -0.89])  # light from the upper left of the image
# Shade layers from the outline inwards: (size factor, offset towards the light, shade 0-255).
_LAYERS = ((1.0, 0.0, 120), (0.75, 0.1, 185), (0.4, 0.3, 245))
_SHIFT = 4  # cv2 fixed-point bits: sub-pixel accurate outlines
_ONE = 1 << _SHIFT


@dataclass(frozen=True)
class Appearance:
    """Colours (RGB) and cut of the figure's clothes, chosen per seed."""

    skin: tuple[int, int, int]
    shirt: tuple[int, int, int]
    stripe: tuple[int, int, int]
    trousers: tuple[int, int, int]
    shoes: tuple[int, int, int]
    hair: tuple[int, int, int]
    long_sleeves: bool
    num_stripes: int

    def colours(self) -> np.ndarray:
        """`(len(MATERIALS), 3)` uint8 base colour per material (row 0 unused)."""
        return np.array([(0, 0, 0), self.skin, self.shirt, self.stripe, self.trousers,
                         self.shoes, self.hair], dtype=np.uint8)


_SKINS = ((241, 194, 167), (224, 172, 135), (198, 134, 96), (161, 102, 70), (112, 70, 46),
          (234, 189, 157))
_HAIRS = ((30, 22, 18), (70, 45, 25), (120, 85, 50), (200, 170, 110), (90, 90, 90))


def random_appearance(rng: np.random.Generator) -> Appearance:
    """Skin from a palette of real skin tones; clothes in saturated or muted random colours."""

    def colour(low: int, high: int) -> tuple[int, int, int]:
        return tuple(int(c) for c in rng.integers(low, high, size=3))

    shirt = colour(30, 230)
    return Appearance(
        skin=_SKINS[rng.integers(len(_SKINS))], shirt=shirt,
        stripe=tuple(int(255 - c) for c in shirt), trousers=colour(20, 150),
        shoes=colour(10, 90), hair=_HAIRS[rng.integers(len(_HAIRS))],
        long_sleeves=bool(rng.random() < 0.5), num_stripes=int(rng.choice([0, 0, 3, 4, 6])),
    )


def body_scale(joints: np.ndarray) -> float:
    """Subject size relative to an adult with 0.84 m legs (hip to ankle), from `(time, 16, 3)`."""
    index = {name: i for i, name in enumerate(FIGURE_MARKERS)}
    legs = []
    for side in ("right", "left"):
        hip, knee, ankle = (joints[:, index[f"{side}_{j}"]] for j in ("hip", "knee", "ankle"))
        legs.append(np.linalg.norm(hip - knee, axis=-1) + np.linalg.norm(knee - ankle, axis=-1))
    return float(np.clip(np.median(legs) / 0.84, 0.4, 1.5))


def _unit(vectors: np.ndarray) -> np.ndarray:
    return vectors / np.maximum(np.linalg.norm(vectors, axis=-1, keepdims=True), 1e-9)


def figure_points(joints: np.ndarray, scale: float,
                  appearance: Appearance) -> tuple[np.ndarray, dict[str, int], np.ndarray]:
    """The 3-D points the figure is drawn from.

    Args:
        joints: `(time, 16, 3)` world metres, Y up, ordered as `FIGURE_MARKERS`.
        scale: `body_scale(joints)`.
        appearance: decides how many shirt stripes need end points.

    Returns:
        points `(time, points, 3)`, name -> index into the points axis, and the subject's facing
        direction `(time, 3)` (horizontal unit vectors).
    """
    named = {name: joints[:, i] for i, name in enumerate(FIGURE_MARKERS)}
    up = np.array([0.0, 1.0, 0.0])
    # forward = left x up for a right-handed, Y-up world (a subject facing +z has its left on +x)
    across = (named["left_hip"] - named["right_hip"]) + (
        named["left_shoulder"] - named["right_shoulder"])
    forward = np.cross(across, up)
    forward[:, 1] = 0.0
    forward = _unit(forward)
    lateral = _unit(across)[:, None]
    extra = {"head_centre": named["head"] + 0.08 * scale * _unit(named["head"] - named["neck"])}
    for side, sign in (("right", -1.0), ("left", 1.0)):
        wrist, elbow = named[f"{side}_wrist"], named[f"{side}_elbow"]
        extra[f"{side}_hand_tip"] = wrist + 0.13 * scale * _unit(wrist - elbow)
        extra[f"{side}_toe"] = named[f"{side}_ankle"] + scale * (0.15 * forward - 0.05 * up)
        side_out = sign * lateral[:, 0]
        extra[f"{side}_shoulder_out"] = named[f"{side}_shoulder"] + scale * (
            0.05 * side_out + 0.03 * up)
        extra[f"{side}_hip_out"] = named[f"{side}_hip"] + 0.06 * scale * side_out
        extra[f"{side}_waist_out"] = 0.3 * extra[f"{side}_shoulder_out"] + 0.7 * extra[
            f"{side}_hip_out"]
    # front and back surfaces of the torso, so a side view still shows a body of some thickness
    for name in ("right_shoulder_out", "left_shoulder_out", "right_waist_out", "left_waist_out",
                 "right_hip_out", "left_hip_out"):
        depth = 0.11 if "shoulder" in name else 0.1
        extra[f"{name}_front"] = extra[name] + depth * scale * forward
        extra[f"{name}_back"] = extra[name] - depth * scale * forward
    for k in range(appearance.num_stripes):
        t = (k + 1) / (appearance.num_stripes + 1)
        for side in ("right", "left"):
            extra[f"stripe{k}_{side}"] = ((1 - t) * extra[f"{side}_shoulder_out"]
                                          + t * extra[f"{side}_waist_out"])
    names = list(FIGURE_MARKERS) + list(extra)
    points = np.concatenate([joints, np.stack(list(extra.values()), axis=1)], axis=1)
    return points, {name: i for i, name in enumerate(names)}, forward


def _fixed(values: np.ndarray) -> np.ndarray:
    return np.round(values * _ONE).astype(np.int32)


def _texture_map(origin: np.ndarray, axis: np.ndarray, depth: np.ndarray,
                 depth_change: np.ndarray, focal_length: float,
                 reference_depth: float) -> np.ndarray:
    """Affine maps from pixels to a body part's texture coordinates, `(time, 2, 3)` float32.

    The coordinates are texels along `axis` (the part's long axis in the image) and across it,
    measured from `origin` (a point fixed on the part), one texel per pixel at `reference_depth`:
    a texel is a fixed size on the body, so the texture moves, turns and scales with the part.
    Along the axis the texels are compressed as the part turns towards the camera (from the
    depth change over its length, at most 4 times).

    Args:
        origin: `(time, 2)` pixels.
        axis: `(time, 2)` pixels, the part's long axis (any length; zero leaves it upright).
        depth: `(time,)` the part's depth, metres.
        depth_change: `(time,)` the depth change along `axis`, metres.
    """
    length = np.linalg.norm(axis, axis=-1)
    along = np.where(length[:, None] > 1e-6, axis / np.maximum(length, 1e-6)[:, None],
                     np.array([0.0, -1.0]))
    across = np.stack([-along[:, 1], along[:, 0]], -1)
    depth = np.maximum(depth, 1e-3)
    texels_per_pixel = depth / reference_depth
    # the fraction of the part's length that the image shows (pinhole camera)
    visible = length / np.maximum(np.hypot(length, depth_change * focal_length / depth), 1e-9)
    rows = np.stack([along * (texels_per_pixel / np.maximum(visible, 0.25))[:, None],
                     across * texels_per_pixel[:, None]], axis=1)  # (time, 2, 2)
    offset = -np.einsum("tij,tj->ti", rows, origin)
    return np.concatenate([rows, offset[..., None]], axis=-1).astype(np.float32)


class FigureDrawer:
    """Plans every frame's drawing at once (vectorised over time), then draws one frame at a time
    into a `(height, width, 3)` uint8 buffer whose channels are part index, material and shade.

    Args:
        index: point name -> index, from `figure_points`.
        appearance: clothing.
        scale: `body_scale` of the subject.
        focal_length: the camera's focal length in pixels (limb widths are `radius * f / depth`).
        pixels: `(time, points, 2)` projected `figure_points`.
        depths: `(time, points)` their camera depths, metres.
        faces_camera: `(time,)` whether the subject's front is towards the camera.
        min_depth: points nearer than this (or behind the camera) are not drawn.

    Attributes:
        texture_maps: `(time, parts, 2, 3)` float32 affine maps from pixel `(x, y, 1)` to each
            part's texture coordinates (texels along and across the part, see `_texture_map`),
            so that clothing texture is carried along by the part it is on.
    """

    def __init__(self, index: dict[str, int], appearance: Appearance, scale: float,
                 focal_length: float, pixels: np.ndarray, depths: np.ndarray,
                 faces_camera: np.ndarray, min_depth: float = 0.05):
        self.pixels_per_metre = scale * focal_length  # at 1 m depth
        self.faces_camera = np.asarray(faces_camera, bool)
        num_frames = pixels.shape[0]
        sleeve = SHIRT if appearance.long_sleeves else SKIN
        self.capsule_parts = [_PART[c[0]] for c in _CAPSULES]
        self.capsule_materials = [sleeve if c[5] is None else c[5] for c in _CAPSULES]
        a = np.array([index[c[1]] for c in _CAPSULES])
        b = np.array([index[c[2]] for c in _CAPSULES])
        radii = np.array([(c[3], c[4]) for c in _CAPSULES])  # (capsules, 2) metres
        self.part_depths = np.full((num_frames, len(PARTS)), np.inf)

        # capsules: every frame, capsule and shade layer at once
        ends = np.stack([pixels[:, a], pixels[:, b]], axis=2)  # (time, capsules, 2, 2)
        end_depths = np.stack([depths[:, a], depths[:, b]], axis=2)
        capsule_ok = end_depths.min(axis=2) > min_depth
        radius = self.radius(radii, end_depths)  # (time, capsules, 2)
        direction = ends[:, :, 1] - ends[:, :, 0]
        length = np.linalg.norm(direction, axis=-1, keepdims=True)
        normal = np.stack([-direction[..., 1], direction[..., 0]], -1) / np.maximum(length, 1e-6)
        towards_light = np.where((normal @ _LIGHT)[..., None] >= 0, normal, -normal)
        self.quads, self.circles, self.circle_radii = [], [], []
        for size, offset, _ in _LAYERS:
            shift = towards_light * offset * radius.mean(axis=-1, keepdims=True)
            centres = ends + shift[:, :, None]
            r = radius * size
            side = normal[:, :, None] * r[..., None]  # (time, capsules, 2 ends, 2)
            quad = np.concatenate([centres + side, (centres - side)[:, :, ::-1]], axis=2)
            self.quads.append(_fixed(quad))
            self.circles.append(_fixed(centres))
            self.circle_radii.append(_fixed(r))
        self.capsule_ok = capsule_ok
        self.part_depths[:, self.capsule_parts] = np.where(capsule_ok, end_depths.mean(axis=2),
                                                           np.inf)

        # torso and hips: convex hulls of their surface points, drawn per frame
        side_names = [f"{side}_{place}_out{face}" for side in ("right", "left")
                      for place in ("shoulder", "waist", "hip") for face in ("", "_front", "_back")]
        self.torso = [index[n] for n in side_names if "_hip_" not in n] + [index["neck"]]
        self.hips = [index[n] for n in side_names if "_shoulder_" not in n] + [index["pelvis"]]
        torso_joints = [index[n] for n in ("right_shoulder", "left_shoulder", "right_hip",
                                           "left_hip")]
        torso_depth = depths[:, torso_joints].mean(axis=1)
        self.torso_ok = depths[:, self.torso + self.hips].min(axis=1) > min_depth
        for part in ("torso", "hips"):
            self.part_depths[:, _PART[part]] = np.where(self.torso_ok, torso_depth, np.inf)
        stripes = [(index[f"stripe{k}_right"], index[f"stripe{k}_left"])
                   for k in range(appearance.num_stripes)]
        self.stripes = _fixed(np.stack([pixels[:, [r for r, _ in stripes]],
                                        pixels[:, [l for _, l in stripes]]], axis=2)) \
            if stripes else None  # (time, stripes, 2, 2)
        self.stripe_thickness = np.maximum(1, np.round(self.radius(
            0.02, depths[:, [r for r, _ in stripes]]))).astype(int) if stripes else None
        self.pixels = pixels

        # head: an ellipse whose long axis follows the neck-to-head direction
        centre = pixels[:, index["head_centre"]]
        upward = centre - pixels[:, index["head"]]
        upward_length = np.linalg.norm(upward, axis=-1, keepdims=True)
        self.head_ok = depths[:, index["head_centre"]] > min_depth
        self.part_depths[:, _PART["head"]] = np.where(self.head_ok,
                                                      depths[:, index["head_centre"]], np.inf)
        self.head_angle = np.where(upward_length[:, 0] > 1e-6,
                                   np.degrees(np.arctan2(upward[:, 1], upward[:, 0])) - 90.0, 0.0)
        head_depth = depths[:, index["head_centre"]]
        width, height = self.radius(0.085, head_depth), self.radius(0.115, head_depth)
        self.head_layers = [
            (_fixed(centre + _LIGHT * offset * width[:, None]),
             _fixed(np.stack([width * size, height * size], -1)), shade)
            for size, offset, shade in _LAYERS]
        crown = centre + 0.2 * height[:, None] * upward / np.maximum(upward_length, 1e-6)
        self.crown = (_fixed(crown), _fixed(np.stack([1.02 * width, 0.85 * height], -1)))

        # painter's order: capsules, then torso, then head, sorted far to near per frame
        job_depths = np.concatenate([self.part_depths[:, self.capsule_parts],
                                     self.part_depths[:, [_PART["torso"], _PART["head"]]]], 1)
        self.order = np.argsort(-job_depths, axis=1, kind="stable")
        self.job_ok = np.isfinite(job_depths)
        torso_radius = self.radius(0.085, depths[:, torso_joints])
        self.widest = np.where(depths[:, torso_joints] > min_depth, torso_radius, 0.0).max(axis=1)

        # texture coordinates in each part's own frame: capsules along their bone, torso and hips
        # along the spine (pelvis to neck), the head along its long axis
        usual = torso_depth[self.torso_ok]
        reference = float(np.median(usual)) if usual.size else 1.0
        self.texture_maps = np.zeros((num_frames, len(PARTS), 2, 3), np.float32)
        for job, part in enumerate(self.capsule_parts):
            self.texture_maps[:, part] = _texture_map(
                ends[:, job, 0], direction[:, job], end_depths[:, job].mean(axis=1),
                end_depths[:, job, 1] - end_depths[:, job, 0], focal_length, reference)
        pelvis, neck = index["pelvis"], index["neck"]
        spine = _texture_map(pixels[:, pelvis], pixels[:, neck] - pixels[:, pelvis], torso_depth,
                             depths[:, neck] - depths[:, pelvis], focal_length, reference)
        self.texture_maps[:, _PART["torso"]] = self.texture_maps[:, _PART["hips"]] = spine
        self.texture_maps[:, _PART["head"]] = _texture_map(
            centre, upward, head_depth, np.zeros(num_frames), focal_length, reference)

    def radius(self, metres, depth):
        """Pixels spanned by `metres` at `depth` metres (scaled with the subject)."""
        return metres * self.pixels_per_metre / np.maximum(depth, 1e-3)

    def draw(self, buffer: np.ndarray, t: int) -> None:
        """Draw frame `t` over `buffer` (channels part index, material, shade), far to near."""
        import cv2

        num_capsules = len(self.capsule_parts)
        circles = [layer[t].tolist() for layer in self.circles]
        circle_radii = [layer[t].tolist() for layer in self.circle_radii]
        for job in self.order[t]:
            if not self.job_ok[t, job]:
                continue
            if job < num_capsules:
                part, material = self.capsule_parts[job], self.capsule_materials[job]
                for layer, (_, _, shade) in enumerate(_LAYERS):
                    colour = (part, material, shade)
                    cv2.fillConvexPoly(buffer, self.quads[layer][t, job], colour, cv2.LINE_8,
                                       _SHIFT)
                    for end in (0, 1):
                        cv2.circle(buffer, circles[layer][job][end],
                                   circle_radii[layer][job][end], colour, -1, cv2.LINE_8, _SHIFT)
            elif job == num_capsules:
                self._torso(buffer, t)
            else:
                self._head(buffer, t)

    def _polygon_layers(self, buffer, points, part, material):
        import cv2

        hull = cv2.convexHull(points.astype(np.float32))[:, 0].astype(np.float64)
        centre = hull.mean(axis=0)
        extent = float(np.max(np.linalg.norm(hull - centre, axis=1)))
        for size, offset, shade in _LAYERS:
            layer = centre + size * (hull - centre) + _LIGHT * offset * extent * 0.5
            cv2.fillConvexPoly(buffer, _fixed(layer), (part, material, shade), cv2.LINE_8, _SHIFT)

    def _torso(self, buffer, t):
        import cv2

        self._polygon_layers(buffer, self.pixels[t, self.hips], _PART["hips"], TROUSERS)
        self._polygon_layers(buffer, self.pixels[t, self.torso], _PART["torso"], SHIRT)
        if self.stripes is not None:
            for (right, left), thickness in zip(self.stripes[t].tolist(),
                                                self.stripe_thickness[t].tolist(), strict=True):
                cv2.line(buffer, right, left, (_PART["torso"], STRIPE, 185), thickness,
                         cv2.LINE_8, _SHIFT)

    def _head(self, buffer, t):
        import cv2

        angle = float(self.head_angle[t])
        material = SKIN if self.faces_camera[t] else HAIR
        for centre, axes, shade in self.head_layers:
            cv2.ellipse(buffer, centre[t].tolist(), axes[t].tolist(), angle, 0.0, 360.0,
                        (_PART["head"], material, shade), -1, cv2.LINE_8, _SHIFT)
        if self.faces_camera[t]:  # hair on the crown: the upper half of a larger ellipse
            centre, axes = self.crown
            cv2.ellipse(buffer, centre[t].tolist(), axes[t].tolist(), angle, 0.0, 180.0,
                        (_PART["head"], HAIR, 150), -1, cv2.LINE_8, _SHIFT)
