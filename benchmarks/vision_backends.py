"""The linear-combination tracker's preprocessing, OpenCV against kornia, per frame.

Foreground mask (background difference, opening and closing), skin mask (YCrCb chroma box
inside the foreground) and gradient-magnitude map (Gaussian, Sobel, scaled) of real-photo frames
with a rendered person (the Pose2Sim scene behind a textured silhouette): the OpenCV path of
``jaxtrack.vision`` frame by frame on NumPy arrays, and the kornia path
(``jaxtrack.vision._kornia``) on a batch of torch tensors with its result handed to JAX through
DLPack. Both run side by side in one process, alternating, medians of ``--repeats``; the first
kornia call (its kernels' warm-up) apart.

    python -m benchmarks.vision_backends [--size 640 480] [--frames 8] [--repeats 5]
    python -m benchmarks.vision_backends --device cuda    # frames that live on a GPU

With ``--device cuda`` the frames start as torch tensors on the GPU and both paths must end
with a ``jax.Array`` on the GPU: kornia there, handed to JAX through DLPack; OpenCV after a copy
to host memory, and its result copied back (``jax.device_put``), which is what a user of the
OpenCV path pays for frames decoded on a GPU. The run also checks, and records, that the kornia
result JAX receives is the torch tensor's own GPU memory (the same address: no copy) and how
many pixels differ from the OpenCV path.

Prints ms per frame and writes ``benchmarks/results/vision_backends.json``. Needs torch and
kornia (``pip install torch==2.13.0`` then ``pip install -e '.[kornia]'``; for ``cuda``, a CUDA
build of torch and of jaxlib).
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


def zero_copy(device: str) -> dict:
    """Whether a torch tensor on ``device`` reaches JAX through ``_kornia.to_jax`` without a
    copy: the JAX array's device and whether its buffer is the tensor's own memory."""
    import torch

    from jaxtrack.vision import _kornia

    tensor = torch.arange(4 * 6, dtype=torch.float32, device=device).reshape(4, 6)
    array = _kornia.to_jax(tensor)
    (jax_device,) = array.devices()
    return {"jax_device": str(jax_device),
            "same_memory": bool(array.unsafe_buffer_pointer() == tensor.data_ptr()),
            "equal": bool(np.array_equal(np.asarray(array), tensor.cpu().numpy()))}


def differing_pixels(opencv, kornia) -> float:
    """The share of pixels where two ``(time, height, width)`` results differ (masks) or
    differ by more than 5 × 10⁻³ (gradient maps)."""
    opencv, kornia = np.asarray(opencv), np.asarray(kornia)
    if opencv.dtype == bool:
        return float(np.mean(opencv != kornia))
    return float(np.mean(np.abs(opencv.astype(np.float64) - kornia) > 5e-3))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, nargs=2, default=(640, 480), metavar=("W", "H"))
    parser.add_argument("--frames", type=int, default=8, help="frames per batch (8)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--device", choices=("cpu", "cuda"), default="cpu",
                        help="where the frames live as torch tensors (cpu)")
    parser.add_argument("--json", default="benchmarks/results/vision_backends.json")
    args = parser.parse_args(argv)
    if args.frames < 1 or args.repeats < 1 or min(args.size) < 16:
        parser.error("--frames and --repeats must be at least 1, --size at least 16 x 16")
    import torch

    if args.device == "cuda" and not torch.cuda.is_available():
        parser.error("--device cuda: this torch sees no CUDA device")
    if args.device == "cuda" and jax.default_backend() != "gpu":
        parser.error(f"--device cuda: JAX runs on {jax.default_backend()}, not a GPU")

    from jaxtrack.vision import _kornia
    from jaxtrack.vision.foreground import foreground_mask
    from jaxtrack.vision.normals import gradient_magnitude
    from jaxtrack.vision.skin import skin_mask

    images, background = scene(tuple(args.size), args.frames)
    tensors = torch.from_numpy(images).to(args.device)
    background_tensor = torch.from_numpy(background).to(args.device)
    foreground = np.stack([foreground_mask(frame, background) for frame in images])
    foreground_tensor = torch.from_numpy(foreground).to(args.device)

    opencv_stages = {
        "foreground": lambda frames, masks: [foreground_mask(f, background) for f in frames],
        "skin": lambda frames, masks: [skin_mask(f, m) for f, m in zip(frames, masks,
                                                                        strict=True)],
        "gradient": lambda frames, masks: [gradient_magnitude(f) for f in frames],
    }
    kornia_stages = {
        "foreground": lambda: _kornia.foreground_masks(tensors, background_tensor),
        "skin": lambda: _kornia.skin_masks(tensors, foreground_tensor),
        "gradient": lambda: _kornia.gradient_magnitudes(tensors),
    }

    def opencv_path(function):
        if args.device == "cpu":  # NumPy frames in, NumPy results out, as the tracker uses
            return lambda: function(images, foreground)
        # GPU frames in, a JAX array on the GPU out: OpenCV needs the round trip
        return lambda: jax.device_put(np.stack(function(tensors.cpu().numpy(),
                                                        foreground_tensor.cpu().numpy())))

    stages = {stage: (opencv_path(opencv_stages[stage]), kornia_stages[stage])
              for stage in opencv_stages}

    def synchronised(call):
        output = jax.block_until_ready(call())
        if args.device == "cuda":
            torch.cuda.synchronize()
        return output

    times = {(stage, backend): [] for stage in stages for backend in ("opencv", "kornia")}
    warm_up, differing = {}, {}
    for stage, (opencv_call, kornia_call) in stages.items():
        start = time.perf_counter()
        kornia_output = synchronised(kornia_call)
        warm_up[stage] = time.perf_counter() - start
        differing[stage] = differing_pixels(np.stack(synchronised(opencv_call)), kornia_output)
    for _ in range(args.repeats):
        for stage, calls in stages.items():
            for backend, call in zip(("opencv", "kornia"), calls, strict=True):
                start = time.perf_counter()
                synchronised(call)
                times[stage, backend].append(time.perf_counter() - start)
    rows = []
    for stage in stages:
        opencv = statistics.median(times[stage, "opencv"]) / args.frames
        kornia = statistics.median(times[stage, "kornia"]) / args.frames
        rows.append({"stage": stage, "opencv_ms": 1e3 * opencv, "kornia_ms": 1e3 * kornia,
                     "ratio": kornia / opencv, "kornia_first_s": warm_up[stage],
                     "differing_pixels": differing[stage],
                     "opencv_times": times[stage, "opencv"],
                     "kornia_times": times[stage, "kornia"]})
    handoff = zero_copy(args.device)
    gpu = f", {torch.cuda.get_device_name()}" if args.device == "cuda" else ""
    print(f"device: {device_description()}, torch {torch.__version__} "
          f"({torch.get_num_threads()} threads){gpu}")
    opencv_path = ("OpenCV on the host" if args.device == "cpu"
                   else "OpenCV with the round trip through host memory")
    print(f"{args.size[0]} x {args.size[1]} frames on {args.device}, batches of {args.frames}; "
          f"ms per frame, medians of {args.repeats}; {opencv_path}")
    print_table(rows, [("stage", "stage", "s"), ("opencv_ms", "OpenCV ms", ".2f"),
                       ("kornia_ms", "kornia ms", ".2f"), ("ratio", "kornia / OpenCV", ".2f"),
                       ("kornia_first_s", "kornia first call s", ".2f"),
                       ("differing_pixels", "pixels differing", ".2e")])
    print(f"DLPack hand-off to JAX: on {handoff['jax_device']}, "
          f"{'the same memory (no copy)' if handoff['same_memory'] else 'a copy'}")
    write_json(args.json, {"benchmark": "vision_backends", "device": device_description(),
                           "torch": torch.__version__, "frames_on": args.device,
                           "gpu": torch.cuda.get_device_name() if args.device == "cuda"
                           else None, "handoff": handoff, "arguments": vars(args),
                           "rows": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
