"""Saving and loading trained GPLVMs: ``.npz`` arrays plus JSON metadata, written atomically."""

from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack._files import write_npz_atomically
from jaxtrack.priors.gplvm._kernel import KernelParameters
from jaxtrack.priors.gplvm._model import GPLVM
from jaxtrack.priors.gplvm._parts import PartsGPLVM

__all__ = ["GPLVMFormatError", "SavedGPLVM", "load_gplvm", "save_gplvm"]

FORMAT_NAME = "jaxtrack.gplvm"
FORMAT_VERSION = 1
_KERNEL_FIELDS = ("log_alpha", "log_beta", "log_gamma")
_MODEL_FIELDS = ("pose_mean", "latents", "poses", "active_indices", "active_latents",
                 "active_poses", "weights", "inverse_gram", "dynamics_std", "dynamics_fps")


class GPLVMFormatError(ValueError):
    """A file is not a readable jaxtrack GPLVM (wrong kind, damaged, or a newer version)."""


@dataclass(frozen=True)
class SavedGPLVM:
    """A loaded model with what was saved beside it.

    Attributes:
        model: the :class:`GPLVM` or :class:`PartsGPLVM` (float64 arrays).
        description: the training-data description given to :func:`save_gplvm`.
        arrays: extra named arrays given to :func:`save_gplvm` (e.g. an SPM template).
        trace: the training trace, if saved.
    """

    model: GPLVM
    description: dict = field(default_factory=dict)
    arrays: dict = field(default_factory=dict)
    trace: list = field(default_factory=list)


def _model_metadata(model: GPLVM) -> dict:
    return {"latent_dim": model.latent_dim, "pose_dim": model.pose_dim,
            "active_size": model.active_size,
            "kernel": {"alpha": float(model.kernel.alpha), "beta": float(model.kernel.beta),
                       "gamma": float(model.kernel.gamma)},
            "active_indices": np.asarray(model.active_indices).tolist()}


def _model_arrays(model: GPLVM, prefix: str = "") -> dict:
    contents = {prefix + name: np.asarray(getattr(model.kernel, name)) for name in _KERNEL_FIELDS}
    return contents | {prefix + name: np.asarray(getattr(model, name)) for name in _MODEL_FIELDS}


def save_gplvm(path: str | os.PathLike, model: GPLVM | PartsGPLVM, *,
               description: dict | None = None, arrays: dict | None = None,
               trace: list | None = None) -> Path:
    """Write ``model`` to ``path`` (``.npz``), atomically. Returns the path.

    A :class:`PartsGPLVM` is saved part by part (arrays ``part<i>/<name>``, the parts' names
    and links in the metadata).

    Args:
        description: JSON-serialisable description of the training data (clips, views, fps,
            pose representation), stored in the metadata.
        arrays: extra arrays to keep with the model, stored as ``extra/<name>``.
        trace: the training trace (:attr:`GPLVMFit.trace`).
    """
    path = Path(path)
    metadata = {"format": FORMAT_NAME, "format_version": FORMAT_VERSION,
                "description": description or {}, "trace": trace or [],
                "extra_arrays": sorted(arrays or {})}
    if isinstance(model, PartsGPLVM):
        metadata |= {"latent_dim": model.latent_dim, "pose_dim": model.pose_dim,
                     "active_size": model.active_size, "parts": [
                         {"name": name, "links": list(links), **_model_metadata(part)}
                         for part, links, name in zip(model.parts, model.links, model.names,
                                                      strict=True)]}
        contents = {}
        for index, part in enumerate(model.parts):
            contents |= _model_arrays(part, f"part{index}/")
    else:
        metadata |= _model_metadata(model)
        contents = _model_arrays(model)
    contents |= {f"extra/{name}": np.asarray(value) for name, value in (arrays or {}).items()}
    return write_npz_atomically(path, contents, metadata, what="description and trace")


def _fail(path: Path, reason: str) -> GPLVMFormatError:
    return GPLVMFormatError(f"{path}: {reason}")


def load_gplvm(path: str | os.PathLike) -> SavedGPLVM:
    """Read a file written by :func:`save_gplvm`.

    Raises:
        FileNotFoundError: no such file.
        GPLVMFormatError: the file is damaged or truncated, is not a jaxtrack GPLVM (e.g. a
            rendered sequence), is a newer format version, or its arrays disagree in shape.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such GPLVM file")
    if not zipfile.is_zipfile(path):  # np.load would read it as text and advise allow_pickle
        with open(path, "rb") as file:
            if file.read(4) == b"PK\x03\x04":  # a zip archive's start: cut short, or damaged
                raise _fail(path, "damaged or truncated GPLVM file (a .npz archive without its "
                                  "end; copy or train it again)")
        raise _fail(path, "not a jaxtrack GPLVM file (not a .npz archive; a GPLVM is the .npz "
                          "that jaxtrack train writes)")
    try:
        with np.load(path, allow_pickle=False) as archive:
            if "metadata" not in archive.files:
                raise _fail(path, "not a jaxtrack GPLVM file (no metadata)")
            metadata = json.loads(str(archive["metadata"]))
            if metadata.get("format") != FORMAT_NAME:
                raise _fail(path, f"not a jaxtrack GPLVM file (format "
                                  f"{metadata.get('format')!r}, expected {FORMAT_NAME!r})")
            if metadata.get("format_version", 0) > FORMAT_VERSION:
                raise _fail(path, f"format version {metadata['format_version']} is newer than "
                                  f"this jaxtrack reads ({FORMAT_VERSION}); upgrade jaxtrack")
            parts = metadata.get("parts")
            layout = ([("", metadata)] if parts is None else
                      [(f"part{index}/", part) for index, part in enumerate(parts)])
            names = _KERNEL_FIELDS + _MODEL_FIELDS
            missing = [prefix + n for prefix, _ in layout for n in names
                       if prefix + n not in archive.files]
            if missing:
                raise _fail(path, f"missing arrays {missing}")
            values = [{name: np.array(archive[prefix + name]) for name in names}
                      for prefix, _ in layout]
            extra = {name: np.array(archive[f"extra/{name}"])
                     for name in metadata.get("extra_arrays", [])}
    except GPLVMFormatError:
        raise
    except (zipfile.BadZipFile, EOFError, OSError, ValueError, KeyError) as error:
        raise _fail(path, f"damaged or truncated GPLVM file ({type(error).__name__}: "
                          f"{error})") from None
    for part_values, (_, part_metadata) in zip(values, layout, strict=True):
        _check_shapes(path, part_values, part_metadata)
    with jax.enable_x64(True):
        models = [GPLVM(kernel=KernelParameters(*(jnp.asarray(v[name]) for name in _KERNEL_FIELDS)),
                        **{name: jnp.asarray(v[name]) for name in _MODEL_FIELDS}) for v in values]
        if parts is None:
            model = models[0]
        else:
            try:
                model = PartsGPLVM(tuple(models), tuple(tuple(p["links"]) for p in parts),
                                   tuple(str(p["name"]) for p in parts))
            except (ValueError, KeyError, TypeError) as error:
                raise _fail(path, f"inconsistent parts ({error})") from None
    return SavedGPLVM(model=model, description=metadata.get("description", {}), arrays=extra,
                      trace=metadata.get("trace", []))


def _check_shapes(path: Path, values: dict, metadata: dict) -> None:
    n, latent = values["latents"].shape if values["latents"].ndim == 2 else (-1, -1)
    active = values["active_indices"].shape[0] if values["active_indices"].ndim == 1 else -1
    dims = values["pose_mean"].shape[0] if values["pose_mean"].ndim == 1 else -1
    expected = {
        "latents": (n, latent), "poses": (n, dims), "active_latents": (active, latent),
        "active_poses": (active, dims), "weights": (active, dims),
        "inverse_gram": (active, active), "dynamics_std": (latent,), "dynamics_fps": (),
    }
    for name, shape in expected.items():
        if min(shape, default=0) < 0 or values[name].shape != shape:
            raise _fail(path, f"array {name!r} has shape {values[name].shape}, expected {shape}")
    if (latent, dims, active) != (metadata.get("latent_dim"), metadata.get("pose_dim"),
                                   metadata.get("active_size")):
        raise _fail(path, "arrays disagree with the metadata's latent_dim/pose_dim/active_size")
    indices = values["active_indices"]
    if indices.size and (indices.min() < 0 or indices.max() >= n):
        raise _fail(path, f"active indices out of range for {n} training points")
    for name in ("latents", "poses", "active_latents", "active_poses", "weights", "inverse_gram",
                 "pose_mean", *_KERNEL_FIELDS):
        if not np.all(np.isfinite(values[name])):
            raise _fail(path, f"array {name!r} holds non-finite values")
