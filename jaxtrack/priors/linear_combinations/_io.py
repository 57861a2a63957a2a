"""Saving and loading linear-combination models: ``.npz`` arrays plus JSON metadata, written
atomically (the conventions of ``jaxtrack.priors.gplvm``)."""

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
from jaxtrack.body.hybrid import HybridLayout
from jaxtrack.priors.linear_combinations._model import LinearCombinationModel

__all__ = ["LinearCombinationFormatError", "SavedLinearCombinations", "load_linear_combinations",
           "save_linear_combinations"]

FORMAT_NAME = "jaxtrack.linear_combinations"
FORMAT_VERSION = 1
_FIELDS = ("part_weights", "mean", "basis", "eigenvalues", "cluster_means", "local_bases",
           "local_extents", "transition", "cluster_prior", "training_coefficients",
           "training_clusters")


class LinearCombinationFormatError(ValueError):
    """A file is not a readable linear-combination model (wrong kind, damaged, newer version)."""


@dataclass(frozen=True)
class SavedLinearCombinations:
    """A loaded model with what was saved beside it.

    Attributes:
        model: the :class:`LinearCombinationModel` (float64 arrays).
        description: the training-data description given to :func:`save_linear_combinations`.
        arrays: extra named arrays given to :func:`save_linear_combinations`.
    """

    model: LinearCombinationModel
    description: dict = field(default_factory=dict)
    arrays: dict = field(default_factory=dict)


def save_linear_combinations(path: str | os.PathLike, model: LinearCombinationModel, *,
                             description: dict | None = None, arrays: dict | None = None
                             ) -> Path:
    """Write ``model`` to ``path`` (``.npz``), atomically. Returns the path.

    Args:
        description: JSON-serialisable description of the training data (clips, views,
            settings), stored in the metadata.
        arrays: extra arrays to keep with the model, stored as ``extra/<name>``.
    """
    path = Path(path)
    metadata = {
        "format": FORMAT_NAME, "format_version": FORMAT_VERSION,
        "num_contour": model.layout.num_contour, "num_skeleton": model.layout.num_skeleton,
        "components": model.num_components, "clusters": model.num_clusters,
        "description": description or {}, "extra_arrays": sorted(arrays or {}),
    }
    contents = {name: np.asarray(getattr(model, name)) for name in _FIELDS}
    contents |= {f"extra/{name}": np.asarray(value) for name, value in (arrays or {}).items()}
    return write_npz_atomically(path, contents, metadata)


def _fail(path: Path, reason: str) -> LinearCombinationFormatError:
    return LinearCombinationFormatError(f"{path}: {reason}")


def load_linear_combinations(path: str | os.PathLike) -> SavedLinearCombinations:
    """Read a file written by :func:`save_linear_combinations`.

    Raises:
        FileNotFoundError: no such file.
        LinearCombinationFormatError: the file is damaged or truncated, is another kind of file
            (e.g. a GPLVM or a rendered sequence), is a newer format version, or its arrays
            disagree in shape or hold non-finite values.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such linear-combination model file")
    if not zipfile.is_zipfile(path):
        with open(path, "rb") as file:
            if file.read(4) == b"PK\x03\x04":
                raise _fail(path, "damaged or truncated linear-combination model (a .npz "
                                  "archive without its end; copy or train it again)")
        raise _fail(path, "not a jaxtrack linear-combination model (not a .npz archive)")
    try:
        with np.load(path, allow_pickle=False) as archive:
            if "metadata" not in archive.files:
                raise _fail(path, "not a jaxtrack linear-combination model (no metadata)")
            metadata = json.loads(str(archive["metadata"]))
            if metadata.get("format") != FORMAT_NAME:
                raise _fail(path, f"not a jaxtrack linear-combination model (format "
                                  f"{metadata.get('format')!r}, expected {FORMAT_NAME!r})")
            if metadata.get("format_version", 0) > FORMAT_VERSION:
                raise _fail(path, f"format version {metadata['format_version']} is newer than "
                                  f"this jaxtrack reads ({FORMAT_VERSION}); upgrade jaxtrack")
            missing = [name for name in _FIELDS if name not in archive.files]
            if missing:
                raise _fail(path, f"missing arrays {missing}")
            values = {name: np.array(archive[name]) for name in _FIELDS}
            extra = {name: np.array(archive[f"extra/{name}"])
                     for name in metadata.get("extra_arrays", [])}
    except LinearCombinationFormatError:
        raise
    except (zipfile.BadZipFile, EOFError, OSError, ValueError, KeyError) as error:
        raise _fail(path, f"damaged or truncated linear-combination model "
                          f"({type(error).__name__}: {error})") from None
    layout = HybridLayout(num_contour=int(metadata.get("num_contour", -1)),
                          num_skeleton=int(metadata.get("num_skeleton", -1)))
    _check_shapes(path, values, layout)
    with jax.enable_x64(True):
        arrays = {name: jnp.asarray(values[name]) for name in _FIELDS}
        arrays["training_clusters"] = arrays["training_clusters"].astype(jnp.int32)
        model = LinearCombinationModel(layout=layout, **arrays)
    return SavedLinearCombinations(model=model, description=metadata.get("description", {}),
                                   arrays=extra)


def _check_shapes(path: Path, values: dict, layout: HybridLayout) -> None:
    if layout.num_contour < 3 or layout.num_skeleton < 1:
        raise _fail(path, "metadata lacks the hybrid layout (num_contour, num_skeleton)")
    basis = values["basis"]
    components = basis.shape[1] if basis.ndim == 2 else -1
    clusters = values["cluster_means"].shape[0] if values["cluster_means"].ndim == 2 else -1
    local = values["local_bases"].shape[2] if values["local_bases"].ndim == 3 else -1
    examples = values["training_clusters"].shape[0] if values["training_clusters"].ndim else -1
    expected = {
        "part_weights": (3,), "mean": (layout.size,), "basis": (layout.size, components),
        "eigenvalues": (components,), "cluster_means": (clusters, components),
        "local_bases": (clusters, components, local), "local_extents": (clusters, local),
        "transition": (clusters, clusters), "cluster_prior": (clusters,),
        "training_coefficients": (examples, components), "training_clusters": (examples,),
    }
    for name, shape in expected.items():
        if min(shape, default=0) < 0 or values[name].shape != shape:
            raise _fail(path, f"array {name!r} has shape {values[name].shape}, expected {shape}")
    for name in _FIELDS:
        if not np.all(np.isfinite(values[name])):
            raise _fail(path, f"array {name!r} holds non-finite values")
    if np.any(values["eigenvalues"] <= 0):
        raise _fail(path, "array 'eigenvalues' holds values <= 0")
    labels = values["training_clusters"]
    if labels.size and (labels.min() < 0 or labels.max() >= clusters):
        raise _fail(path, f"training clusters out of range for {clusters} clusters")
    if not np.allclose(values["transition"].sum(axis=1), 1.0, atol=1e-6):
        raise _fail(path, "the transition matrix's rows do not sum to 1")
