"""Ground-truth video from real motion: a clothed figure drawn from projected mocap joints.

:func:`render_motion` draws, per frame, a human figure whose limbs are shaded, textured capsules
(torso and hips as solid hulls, skin-coloured head and hands, clothes coloured per seed) in
painter's order by depth, over a plain, photographic or cluttered background, with optional noise,
blur, lighting changes and moving occluders. Every frame comes with exact ground truth: the 2-D
markers, their 3-D positions, whether each is visible, and the figure's silhouette.

The fabric is fixed to the body, as real clothes are: each part looks its texture up in its own
frame (along and across the part), so the pattern moves, turns and scales with the part it is on,
and a template taken around a joint stays on the joint.

Limb widths are physical (metres, scaled with the subject's leg length) and become pixels through
the camera's focal length and each joint's depth. Visibility is approximate where body parts
overlap: each part has one depth (the mean of its end points), and a marker is hidden when the
pixel it projects to shows a part that is not its own and lies more than ~8 cm nearer.

cv2 is imported inside the functions, so `import jaxtrack` works without OpenCV.
"""

from __future__ import annotations

import sys
from dataclasses import asdict, dataclass

import numpy as np

from jaxtrack.body import _backgrounds, _figure
from jaxtrack.body._staging import (
    fit_camera,
    frontal_camera,
    project_numpy,
    random_camera,
    scale_camera,
    stage_for_cameras,
)
from jaxtrack.body.camera import Camera
from jaxtrack.body.markers import HUMANEVA_15, marker_positions
from jaxtrack.body.motion import Motion
from jaxtrack.body.sequence import RenderedSequence

__all__ = ["BACKGROUNDS", "Lighting", "fit_camera", "frontal_camera", "random_camera",
           "render_motion", "scale_camera", "stage_for_cameras"]

BACKGROUNDS = _backgrounds.BACKGROUNDS
_MIN_DEPTH = 0.05  # metres; nearer points (or behind the camera) are not drawn


@dataclass(frozen=True)
class Lighting:
    """Slow brightness and contrast changes, as from clouds or an auto-exposure camera.

    Attributes:
        brightness: amplitude of the offset, in grey levels.
        contrast: amplitude of the relative gain change around mid-grey.
        period: seconds per cycle (brightness cycles at 0.7 times this rate, so they drift).
    """

    brightness: float = 25.0
    contrast: float = 0.25
    period: float = 3.0


def _streams(seed: int, count: int) -> list[np.random.Generator]:
    # one independent stream per purpose, so e.g. adding noise does not change the clothes
    return [np.random.default_rng([int(seed), purpose]) for purpose in range(count)]


def _progress(iterable, total: int, enabled: bool):
    if not (enabled and sys.stderr.isatty()):
        return iterable
    from tqdm.auto import tqdm

    return tqdm(iterable, total=total, desc="rendering", unit="frame", leave=False)


def _compose(image, region, textures, texture_maps, origin, background, widest) -> np.ndarray:
    """Colour the figure's pixels in one frame's region of interest.

    Args:
        image: `(h, w, 3)` uint8 region of the frame (not modified).
        region: `(h, w, 3)` uint8 part index, material, shade, as drawn by `FigureDrawer`.
        textures: `(materials * tile * tile, 3)` uint8 colour per material and texel, flat; `tile`
            is a power of two.
        texture_maps: `(parts, 2, 3)` float32 this frame's affine map per part from pixel
            `(x, y, 1)` to texture coordinates (texels along and across the part), so the texture
            moves with the part it is on.
        origin: `(x, y)` pixel position of the region's top left corner in the frame.
        background: `(h, w, 3)` uint8 background under the region (for the anti-aliased rim).
        widest: the widest limb radius in pixels (sets how far shading is smoothed).

    Returns:
        The region's new pixels `(h, w, 3)` uint8.
    """
    import cv2

    part = np.ascontiguousarray(region[..., 0])
    inside = part.astype(bool)
    tile_bits = (textures.shape[0] // len(_figure.MATERIALS)).bit_length() // 2
    # everything per pixel is done only where the figure is (often a fifth of the region)
    where = np.flatnonzero(inside)
    parts = np.take(part, where)
    row, column = np.divmod(where, part.shape[1])
    x = (column + origin[0]).astype(np.float32)
    y = (row + origin[1]).astype(np.float32)
    # texture coordinates from each part's affine map, wrapped into the tiles
    coefficients = texture_maps.reshape(len(texture_maps), 6).T  # (6, parts)
    index = np.take(np.ascontiguousarray(region[..., 1]), where).astype(np.int32)
    index <<= 2 * tile_bits
    for axis in (0, 1):  # along the part (texture columns), across it (texture rows)
        a, b, c = (np.take(coefficients[3 * axis + k], parts) for k in range(3))
        texel = np.floor(a * x + b * y + c).astype(np.int32)
        texel &= (1 << tile_bits) - 1
        index |= texel << axis * tile_bits
    colour = np.take(textures, index, axis=0).astype(np.float32)
    # soften the shade layers into a gradient across each limb; the zero shade outside the figure
    # darkens its rim, as the edge of a rounded limb looks
    kernel = 2 * int(0.4 * widest) + 1
    shade = np.ascontiguousarray(region[..., 2])
    if kernel > 1:
        shade = cv2.stackBlur(shade, (kernel, kernel))
    colour *= np.take(shade, where)[:, None] * np.float32(1 / 255)
    # anti-alias the inner rim: blend figure pixels that touch the background
    coverage = np.take(cv2.blur(inside.view(np.uint8) * np.uint8(255), (3, 3)), where)
    rim = np.flatnonzero(coverage < 255)
    alpha = coverage[rim, None] * np.float32(1 / 255)
    colour[rim] = alpha * colour[rim] + (1 - alpha) * background[row[rim], column[rim]]
    colour += 0.5
    result = np.array(image)  # contiguous, so that whole pixels can be written by flat index
    pixel = np.dtype((np.void, 3))
    result.view(pixel).reshape(-1)[where] = colour.astype(np.uint8).view(pixel)[:, 0]
    return result


def render_motion(
    motion: Motion,
    camera: Camera,
    *,
    image_size: tuple[int, int] | None = None,
    background: str | np.ndarray = "plain",
    markers: tuple[str, ...] = HUMANEVA_15,
    seed: int = 0,
    noise_std: float = 0.0,
    blur: float = 0.0,
    lighting: Lighting | bool | None = None,
    occluders: int = 0,
    progress: bool = True,
) -> RenderedSequence:
    """Render a real motion seen through `camera` as video with exact ground truth.

    Args:
        motion: the performance (metres, Y up); every frame is rendered.
        camera: the camera; see `frontal_camera`, `random_camera`, `read_qca` + `stage_for_cameras`.
        image_size: `(width, height)`; None renders at `camera.image_size`. A camera of another
            size is scaled uniformly to fit inside (`fit_camera`): its aspect ratio is kept, so
            the frames may come out smaller than asked in one direction.
        background: "plain" (one colour), "photo" (a real frame of Pose2Sim's lab video),
            "clutter" (random shapes, stripes, checks and skin-coloured blobs), or an RGB image.
        markers: marker names for the ground truth, a subset of HUMANEVA_15 + ("thorax",)
            (e.g. `UPPER_BODY_12`).
        seed: decides clothes, background colours/clutter, occluders, noise and lighting phase.
        noise_std: standard deviation of Gaussian pixel noise, grey levels (each frame takes a
            random window of one pre-drawn noise field twice the image size).
        blur: Gaussian blur sigma in pixels (0: none).
        lighting: a `Lighting` (or True for the default one) to vary brightness and contrast.
        occluders: number of rectangles that sweep across the figure; they hide silhouette
            pixels and markers.
        progress: show a progress bar (only when stderr is a terminal).

    Returns:
        A `RenderedSequence`: images `(time, height, width, 3)` uint8 RGB, silhouettes
        `(time, height, width)` bool, markers_2d `(time, markers, 2)`, joints_3d
        `(time, markers, 3)`, visibility `(time, markers)` bool, and the metadata.
    """
    import cv2

    unknown = [name for name in markers if name not in _figure.FIGURE_MARKERS]
    if unknown:
        raise ValueError(f"markers {unknown} are not drawn by the renderer; choose from "
                         f"{_figure.FIGURE_MARKERS}")
    if occluders < 0 or noise_std < 0 or blur < 0:
        raise ValueError("occluders, noise_std and blur must be non-negative")
    if lighting is True:
        lighting = Lighting()
    if image_size is not None and tuple(image_size) != camera.image_size:
        camera = fit_camera(camera, image_size)
    width, height = camera.image_size
    (rng_clothes, rng_background, rng_texture, rng_occluders, rng_noise,
     rng_lighting) = _streams(seed, 6)

    joints = marker_positions(motion, _figure.FIGURE_MARKERS)
    scale = _figure.body_scale(joints)
    appearance = _figure.random_appearance(rng_clothes)
    points, index, forward = _figure.figure_points(joints, scale, appearance)
    pixels, depths = project_numpy(camera, points)
    centre = np.asarray(camera.centre, dtype=np.float64)
    faces_camera = np.einsum("ti,ti->t", forward, centre - joints[:, index["head"]]) > 0
    drawer = _figure.FigureDrawer(index, appearance, scale, float(camera.focal_length[0]),
                                  pixels, depths, faces_camera, _MIN_DEPTH)

    background_image, background_name = _backgrounds.make_background(
        background, (width, height), rng_background)
    tile = _backgrounds.texture_tile((width, height))
    textures = _backgrounds.material_textures(appearance.colours(), tile, rng_texture)
    textures = textures.reshape(-1, 3)
    # each part starts at its own place in the tiles, so e.g. the two thighs differ
    texture_maps = drawer.texture_maps.copy()
    texture_maps[..., 2] += rng_texture.integers(0, tile, size=(len(_figure.PARTS), 2))
    in_front = depths > _MIN_DEPTH
    boxes = np.stack([np.min(np.where(in_front, pixels[..., 0], np.inf), axis=1),
                      np.min(np.where(in_front, pixels[..., 1], np.inf), axis=1),
                      np.max(np.where(in_front, pixels[..., 0], -np.inf), axis=1),
                      np.max(np.where(in_front, pixels[..., 1], -np.inf), axis=1)], axis=1)
    boxes = np.where(np.isfinite(boxes), boxes, 0.0)
    tracks = _backgrounds.occluder_tracks(occluders, boxes, rng_occluders)
    occluder_colours = rng_occluders.integers(0, 256, size=(occluders, 3))

    marker_index = np.array([index[name] for name in markers])
    markers_2d, marker_depths = pixels[:, marker_index], depths[:, marker_index]
    owners = [np.array([_figure.PARTS.index(part) for part in _figure.MARKER_OWNERS[name]])
              for name in markers]
    tolerance = 0.08 * scale

    num_frames = motion.num_frames
    images = np.empty((num_frames, height, width, 3), np.uint8)
    silhouettes = np.zeros((num_frames, height, width), bool)
    visibility = np.zeros((num_frames, len(markers)), bool)
    buffer = np.zeros((height, width, 3), np.uint8)
    light_phase = rng_lighting.uniform(0.0, 2 * np.pi, 2)
    if noise_std > 0:
        noise_field = np.round(rng_noise.standard_normal((2 * height, 2 * width, 3)) * noise_std)
        noise_field = np.clip(noise_field, -255, 255).astype(np.int16)
    for t in _progress(range(num_frames), num_frames, progress):
        buffer.fill(0)
        drawer.draw(buffer, t)
        image = background_image.copy()
        widest = float(drawer.widest[t])
        margin = 1.6 * widest + 4
        x0, y0 = (max(0, int(np.floor(boxes[t, i] - margin))) for i in (0, 1))
        x1 = min(width, int(np.ceil(boxes[t, 2] + margin)) + 1)
        y1 = min(height, int(np.ceil(boxes[t, 3] + margin)) + 1)
        if x1 > x0 and y1 > y0:
            image[y0:y1, x0:x1] = _compose(
                image[y0:y1, x0:x1], buffer[y0:y1, x0:x1], textures, texture_maps[t],
                (x0, y0), background_image[y0:y1, x0:x1], widest)
            silhouettes[t, y0:y1, x0:x1] = buffer[y0:y1, x0:x1, 0] > 0
        part_depths = drawer.part_depths[t]

        u, v = np.round(markers_2d[t]).astype(np.int64).T
        seen = (marker_depths[t] > _MIN_DEPTH) & (u >= 0) & (u < width) & (v >= 0) & (v < height)
        for m in np.flatnonzero(seen):
            part = buffer[v[m], u[m], 0]
            seen[m] = part > 0 and (part in owners[m]
                                    or part_depths[part] >= marker_depths[t, m] - tolerance)
        for k in range(occluders):
            ox0, oy0, ox1, oy1 = tracks[t, k]
            cv2.rectangle(image, (int(ox0), int(oy0)), (int(ox1), int(oy1)),
                          tuple(int(c) for c in occluder_colours[k]), -1)
            cv2.rectangle(image, (int(ox0), int(oy0)), (int(ox1), int(oy1)),
                          tuple(int(c) // 2 for c in occluder_colours[k]), 2)
            silhouettes[t, max(oy0, 0):max(oy1 + 1, 0), max(ox0, 0):max(ox1 + 1, 0)] = False
            seen &= ~((u >= ox0) & (u <= ox1) & (v >= oy0) & (v <= oy1))
        visibility[t] = seen

        if blur > 0:
            image = cv2.GaussianBlur(image, (0, 0), blur)
        if lighting is not None:
            phase = 2 * np.pi * t / (motion.fps * lighting.period)
            gain = 1.0 + lighting.contrast * np.sin(phase + light_phase[0])
            offset = lighting.brightness * np.sin(0.7 * phase + light_phase[1])
            image = cv2.addWeighted(image, gain, image, 0.0, 128.0 * (1 - gain) + offset)
        if noise_std > 0:
            # a random window of a pre-drawn noise field: Gaussian per pixel, fresh-looking per
            # frame, and several times cheaper than drawing a frame's worth of normals each time
            dy, dx = rng_noise.integers(0, (height, width))
            noisy = image.astype(np.int16) + noise_field[dy:dy + height, dx:dx + width]
            image = np.clip(noisy, 0, 255, out=noisy).astype(np.uint8)
        images[t] = image

    settings = {
        "background": background_name, "noise_std": float(noise_std), "blur": float(blur),
        "lighting": None if lighting is None else asdict(lighting), "occluders": int(occluders),
        "body_scale": scale, "appearance": asdict(appearance),
    }
    return RenderedSequence(
        images=images, silhouettes=silhouettes, markers_2d=markers_2d,
        joints_3d=joints[:, [_figure.FIGURE_MARKERS.index(name) for name in markers]],
        visibility=visibility, marker_names=tuple(markers),
        camera=camera, fps=motion.fps, source=motion.source, seed=int(seed),
        settings=settings,
    )

