"""The linear-combination tracker's preprocessing, OpenCV against kornia, per frame.

Foreground mask (background difference, opening and closing), skin mask (YCrCb chroma box
inside the foreground) and gradient-magnitude map (Gaussian, Sobel, scaled) of real-photo frames
with a rendered person (the Pose2Sim scene behind a textured silhouette): the OpenCV path of
``jaxtrack.vision`` frame by frame on NumPy arrays, and the kornia path
(``jaxtrack.vision._kornia``) on a batch of torch tensors with its result handed to JAX through
DLPack. Both run side by side in one process, alternating, medians of ``--repeats``; the first
kornia call (its kernels' warm-up) apart.

    python -m benchmarks.vision_backends [--size 640 480] [--frames 8] [--repeats 5]

Prints ms per frame and writes ``benchmarks/results/vision_backends.json``. Needs torch and
kornia (``pip install torch==2.13.0`` then ``pip install -e '.[kornia]'``).
"""

from __future__ import annotations

import argparse
import statistics
import time

import jax
import numpy as np

from benchmarks._common import device_description, print_table, write_json


def scene(size: tuple[int, int], frames: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A real photo as background and ``frames`` frames with a textured box and a skin patch."""
    from jaxtrack.body import _backgrounds

    width, height = size
    rng = np.random.default_rng(seed)
    background = _backgrounds.make_background("photo", (width, height), rng)[0]
    images = np.repeat(background[None], frames, axis=0)
    top, left = height // 5, width // 3
    for t in range(frames):
        shift = t * width // (8 * frames)
        images[t, top:top + height // 2, left + shift:left + shift + width // 6] = rng.integers(
            0, 255, (height // 2, width // 6, 3))
        images[t, top:top + height // 12, left + shift:left + shift + width // 16] = (220, 170,
                                                                                     140)
    return images, background


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, nargs=2, default=(640, 480), metavar=("W", "H"))
    parser.add_argument("--frames", type=int, default=8, help="frames per batch (8)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--json", default="benchmarks/results/vision_backends.json")
    args = parser.parse_args(argv)
    if args.frames < 1 or args.repeats < 1 or min(args.size) < 16:
        parser.error("--frames and --repeats must be at least 1, --size at least 16 x 16")
    import torch

    from jaxtrack.vision import _kornia
    from jaxtrack.vision.foreground import foreground_mask
    from jaxtrack.vision.normals import gradient_magnitude
    from jaxtrack.vision.skin import skin_mask

    images, background = scene(tuple(args.size), args.frames)
    tensors, background_tensor = torch.from_numpy(images), torch.from_numpy(background)
    foreground = np.stack([foreground_mask(frame, background) for frame in images])
    stages = {
        "foreground": (lambda: [foreground_mask(f, background) for f in images],
                       lambda: _kornia.foreground_masks(tensors, background_tensor)),
        "skin": (lambda: [skin_mask(f, m) for f, m in zip(images, foreground, strict=True)],
                 lambda: _kornia.skin_masks(tensors, foreground)),
        "gradient": (lambda: [gradient_magnitude(f) for f in images],
                     lambda: _kornia.gradient_magnitudes(tensors)),
    }
    times = {(stage, backend): [] for stage in stages for backend in ("opencv", "kornia")}
    warm_up = {}
    for stage, (_, kornia_call) in stages.items():
        start = time.perf_counter()
        jax.block_until_ready(kornia_call())
        warm_up[stage] = time.perf_counter() - start
    for _ in range(args.repeats):
        for stage, calls in stages.items():
            for backend, call in zip(("opencv", "kornia"), calls, strict=True):
                start = time.perf_counter()
                jax.block_until_ready(call())
                times[stage, backend].append(time.perf_counter() - start)
    rows = []
    for stage in stages:
        opencv = statistics.median(times[stage, "opencv"]) / args.frames
        kornia = statistics.median(times[stage, "kornia"]) / args.frames
        rows.append({"stage": stage, "opencv_ms": 1e3 * opencv, "kornia_ms": 1e3 * kornia,
                     "ratio": kornia / opencv, "kornia_first_s": warm_up[stage],
                     "opencv_times": times[stage, "opencv"],
                     "kornia_times": times[stage, "kornia"]})
    print(f"device: {device_description()}, torch {torch.__version__} "
          f"({torch.get_num_threads()} threads)")
    print(f"{args.size[0]} x {args.size[1]} frames, batches of {args.frames}; ms per frame, "
          f"medians of {args.repeats}")
    print_table(rows, [("stage", "stage", "s"), ("opencv_ms", "OpenCV ms", ".2f"),
                       ("kornia_ms", "kornia ms", ".2f"), ("ratio", "kornia / OpenCV", ".1f"),
                       ("kornia_first_s", "kornia first call s", ".2f")])
    write_json(args.json, {"benchmark": "vision_backends", "device": device_description(),
                           "torch": torch.__version__, "arguments": vars(args), "rows": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
