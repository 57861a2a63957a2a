"""Backgrounds, clothing textures and moving occluders for the renderer (private).

Everything here is drawn once per render (backgrounds, textures) or is a cheap per-frame
rectangle (occluders), so the per-frame cost stays in drawing the figure.
"""

from __future__ import annotations

import importlib.resources

import numpy as np

from jaxtrack.body._figure import HAIR, MATERIALS, SHIRT, SHOES, SKIN, STRIPE, TROUSERS

BACKGROUNDS = ("plain", "photo", "clutter")
PHOTO = "pose2sim_demo_singleperson/background_cam01.jpg"
"""The bundled real photo (one frame of Pose2Sim's cam01, BSD-3-Clause), under `data/files/`."""


def photo_background() -> np.ndarray:
    """The bundled photo as `(480, 640, 3)` uint8 RGB."""
    import cv2

    resource = importlib.resources.files("jaxtrack.data").joinpath("files", *PHOTO.split("/"))
    try:
        data = resource.read_bytes()
    except FileNotFoundError:  # e.g. a source tree without the file: try the data catalogue
        from jaxtrack.data import path

        data = path(f"pose2sim/{PHOTO.split('/')[1]}").read_bytes()
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    if image is None:
        raise ValueError(f"the bundled background photo {PHOTO} cannot be decoded")
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def _fit(image: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """Crop to the target aspect (centred), then resize: no stretching, no borders."""
    import cv2

    width, height = image_size
    rows, columns = image.shape[:2]
    if columns * height > rows * width:  # too wide
        keep = max(1, round(rows * width / height))
        image = image[:, (columns - keep) // 2:(columns - keep) // 2 + keep]
    else:
        keep = max(1, round(columns * height / width))
        image = image[(rows - keep) // 2:(rows - keep) // 2 + keep]
    if image.shape[:2] != (height, width):
        image = cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)
    return np.ascontiguousarray(image)


def _clutter(image_size: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """Random shapes in many colours: edges, stripes, checker patches and skin-coloured blobs, the
    things that fool edge, colour and template likelihoods."""
    import cv2

    width, height = image_size
    top, bottom = rng.integers(40, 220, size=(2, 3))
    ramp = np.linspace(0.0, 1.0, height)[:, None, None]
    image = np.ascontiguousarray(
        np.broadcast_to((1 - ramp) * top + ramp * bottom, (height, width, 3)).astype(np.uint8))
    size = float(min(width, height))

    def colour():
        return tuple(int(c) for c in rng.integers(0, 256, size=3))

    def point():
        return int(rng.integers(0, width)), int(rng.integers(0, height))

    for _ in range(int(rng.integers(25, 40))):
        kind = rng.integers(6)
        if kind == 0:
            cv2.rectangle(image, point(), point(), colour(), -1)
        elif kind == 1:
            axes = tuple(int(a) for a in rng.uniform(0.02, 0.15, 2) * size)
            cv2.ellipse(image, point(), axes, float(rng.uniform(0, 180)), 0, 360, colour(), -1,
                        cv2.LINE_AA)
        elif kind == 2:
            cv2.line(image, point(), point(), colour(), int(rng.integers(1, 8)), cv2.LINE_AA)
        elif kind == 3:  # stripes patch: many parallel edges
            x, y = point()
            w, h = (int(v) for v in rng.uniform(0.05, 0.25, 2) * size)
            step = int(rng.integers(3, 12))
            first, second = colour(), colour()
            for offset in range(0, w, step):
                cv2.rectangle(image, (x + offset, y), (x + offset + step // 2, y + h),
                              first if (offset // step) % 2 else second, -1)
        elif kind == 4:  # checkerboard patch
            x, y = point()
            cell = int(rng.integers(4, 16))
            first, second = colour(), colour()
            for i in range(int(rng.integers(3, 10))):
                for j in range(int(rng.integers(3, 10))):
                    cv2.rectangle(image, (x + i * cell, y + j * cell),
                                  (x + (i + 1) * cell, y + (j + 1) * cell),
                                  first if (i + j) % 2 else second, -1)
        else:  # skin-coloured blob, face or hand sized
            skin = (int(rng.integers(150, 245)), int(rng.integers(95, 190)),
                    int(rng.integers(60, 160)))
            axes = tuple(int(a) for a in rng.uniform(0.015, 0.06, 2) * size)
            cv2.ellipse(image, point(), axes, float(rng.uniform(0, 180)), 0, 360, skin, -1,
                        cv2.LINE_AA)
    noise = rng.normal(0.0, 6.0, size=image.shape)
    return np.clip(image + noise, 0, 255).astype(np.uint8)


def make_background(background, image_size: tuple[int, int],
                    rng: np.random.Generator) -> tuple[np.ndarray, str]:
    """The background image `(height, width, 3)` uint8 RGB, and its name for the metadata.

    Args:
        background: "plain", "photo", "clutter", or an image `(height, width, 3)` / `(h, w)` uint8
            (RGB; resized to fit after a centred crop to the aspect ratio).
    """
    width, height = image_size
    if isinstance(background, str):
        if background == "plain":
            colour = rng.integers(60, 200, size=3).astype(np.uint8)
            return np.ascontiguousarray(np.broadcast_to(colour, (height, width, 3))), "plain"
        if background == "photo":
            return _fit(photo_background(), image_size), "photo"
        if background == "clutter":
            return _clutter(image_size, rng), "clutter"
        raise ValueError(f"background must be one of {BACKGROUNDS} or an image array, "
                         f"got {background!r}")
    image = np.asarray(background)
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=2)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"a background image must be (height, width, 3) uint8 RGB, got "
                         f"{image.shape} {image.dtype}")
    return _fit(image, image_size), "image"


def texture_tile(image_size: tuple[int, int]) -> int:
    """Side of the square texture tiles for a render of `image_size`: a power of two (so wrapping
    is a bit mask) of at least half the image's longer side, larger than any one body part."""
    return max(64, 1 << (max(image_size) - 1).bit_length() - 1)


def material_textures(colours: np.ndarray, tile: int, rng: np.random.Generator) -> np.ndarray:
    """Per-material colour tiles `(materials, tile, tile, 3)` uint8: base colour times fabric noise
    (a fine weave for cloth, faint mottling for skin), periodic so they wrap without seams.

    The renderer looks them up in each body part's own frame (see `FigureDrawer.texture_maps`),
    one texel per pixel at the subject's usual depth, so the fabric moves with the body.
    """
    import cv2

    textures = np.zeros((len(MATERIALS), tile, tile, 3), np.uint8)
    amplitude = {SKIN: 0.04, SHIRT: 0.12, STRIPE: 0.1, TROUSERS: 0.15, SHOES: 0.1, HAIR: 0.2}
    rows, columns = np.mgrid[0:tile, 0:tile]
    # diagonal twill of denim, about 7 texels a cycle, a whole number of cycles per tile
    weave = np.sin(2 * np.pi * round(0.9 * tile / (2 * np.pi)) / tile * (rows + columns))
    weave = weave.astype(np.float32)
    pad = 8  # beyond the blur kernel's reach: blurring the wrapped noise keeps it periodic
    for material, strength in amplitude.items():
        noise = np.pad(rng.standard_normal((tile, tile)).astype(np.float32), pad, mode="wrap")
        noise = cv2.GaussianBlur(noise, (0, 0), 1.0 if material != HAIR else 0.7)
        noise = noise[pad:-pad, pad:-pad] * 2.0
        if material == TROUSERS:
            noise = 0.6 * noise + 0.6 * weave
        factor = 1.0 + strength * noise
        textures[material] = np.clip(colours[material] * factor[..., None], 0, 255)
    return textures


def occluder_tracks(num_occluders: int, figure_boxes: np.ndarray,
                    rng: np.random.Generator) -> np.ndarray:
    """Rectangles that sweep across the figure: `(time, occluders, 4)` int `(x0, y0, x1, y1)`.

    Args:
        figure_boxes: `(time, 4)` the figure's bounding box per frame `(x0, y0, x1, y1)`.
    """
    num_frames = figure_boxes.shape[0]
    tracks = np.zeros((num_frames, num_occluders, 4), dtype=np.int64)
    centre = 0.5 * (figure_boxes[:, :2] + figure_boxes[:, 2:])
    extent = np.maximum(np.median(figure_boxes[:, 2:] - figure_boxes[:, :2], axis=0), 8.0)
    time = np.linspace(0.0, 1.0, num_frames)[:, None]
    for k in range(num_occluders):
        size = extent * rng.uniform([0.25, 0.15], [0.6, 0.4])
        # start off to one side of the figure and end on the other, at a random height
        start = rng.uniform(-1.0, 1.0, 2) * 0.5 * extent
        start[0] = rng.choice([-1.0, 1.0]) * 0.8 * extent[0]
        end = -start + rng.uniform(-0.2, 0.2, 2) * extent
        middle = centre + (1 - time) * start + time * end
        tracks[:, k, :2] = np.round(middle - 0.5 * size)
        tracks[:, k, 2:] = np.round(middle + 0.5 * size)
    return tracks
