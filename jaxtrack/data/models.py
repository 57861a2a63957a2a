"""Trained models bundled with jaxtrack: what ``jaxtrack track`` uses when no ``--model`` is given.

Three small files ship in ``jaxtrack/data/files/models/``, each beside a JSON description of
what it was trained on (clips, subjects and their split, the data's licences, the exact
``jaxtrack train`` command, the date):

- ``latent.npz``: a GPLVM pose prior (``jaxtrack train --method latent``), used by
  ``--method latent``, ``condensation`` and ``mht`` (the baselines learn their dynamics from its
  training poses);
- ``linear_combination.npz``: Ong & Gong's model (``jaxtrack train --method
  linear-combination``), used by ``--method linear-combination``;
- ``postures.npz``: Kwatra et al.'s posture model (``jaxtrack train --method mixed-state``),
  used by ``--method mixed-state``.

Every model is trained on **training subjects** only (:mod:`jaxtrack.data.splits`) and only on
data whose licence allows it in the wheel (MIT, CMU's terms, BSD-3-Clause): never on the
non-commercial Bandai-Namco clips, the LGPL DeepMimic clips or the CC BY-SA HDM05 clips. The
posture model therefore learns lying from training subjects' standing waves laid on the floor
(``jaxtrack train --laid-down``; :meth:`jaxtrack.body.motion.Motion.laid_down`): the only real
lying clips of training subjects are DeepMimic's and HDM05's.

    >>> from jaxtrack.data.models import default_model, describe
    >>> default_model("mht").name
    'latent.npz'
    >>> describe("mixed-state")["clips"][0]
    'cmu_posture_bvh/75_19'

``python -m jaxtrack.data.models`` lists them; ``python -m jaxtrack.data.models --rebuild``
(``make models``) retrains them with the commands of :data:`RECIPES` (their clips found as
``jaxtrack.data.path`` finds any clip: all are bundled with the package) and rewrites the files
and their descriptions.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import importlib.resources
import json
import os
import shlex
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

__all__ = ["LICENCES", "METHODS", "RECIPES", "SHIPPABLE_LICENCES", "Recipe", "default_model",
           "describe", "models_folder", "rebuild", "source_licence"]


@dataclass(frozen=True)
class Recipe:
    """How one bundled model is trained.

    Attributes:
        name: the file's stem (``latent`` for ``latent.npz``).
        train_method: ``jaxtrack train --method``.
        clips: the catalogue clips it learns from (``--clips``).
        laid_down: clips also laid on their back and front as lying training data
            (``--laid-down``, the posture model only).
        options: the rest of the ``jaxtrack train`` command line.
        summary: one line on what the model is.
        also_reads: other bundled files the training reads (:data:`ALSO_READ`).
    """

    name: str
    train_method: str
    clips: tuple[str, ...]
    laid_down: tuple[str, ...] = ()
    options: tuple[str, ...] = ()
    summary: str = ""
    also_reads: tuple[str, ...] = ()

    @property
    def file_name(self) -> str:
        return f"{self.name}.npz"

    def arguments(self, out: str | os.PathLike) -> list[str]:
        """The ``jaxtrack`` command line (without ``jaxtrack``) that trains it into ``out``."""
        laid = ["--laid-down", *self.laid_down] if self.laid_down else []
        return ["train", "--method", self.train_method, "--clips", *self.clips, *laid,
                *self.options, "--out", os.fspath(out)]

    def command(self) -> str:
        """The command as a user types it (``--out`` the model's file name)."""
        return shlex.join(["jaxtrack", *self.arguments(self.file_name)])


_AD = "animateddrawings/"
_HISTORY = _AD + "history_c119d6b/"

ALSO_READ = {"pose2sim/Calib.qca.txt": "BSD-3-Clause",
             "pose2sim/background_cam01.jpg": "BSD-3-Clause"}
"""Other bundled files a training reads, with their licences: the cameras the clips are
rendered through (linear-combination) and the background photo they are rendered over."""

RECIPES: dict[str, Recipe] = {
    "latent": Recipe(
        "latent", "latent", (_AD + "fair1_wave_hello", _HISTORY + "8yr_old_wave_hello"),
        options=("--views", "5", "--active", "200", "--iterations", "3", "--seed", "0"),
        summary="GPLVM pose prior of two training subjects' waves (the demo's prior), with "
                "its SPM template and latent dynamics"),
    "linear_combination": Recipe(
        "linear_combination", "linear-combination",
        (_AD + "fair1_wave_hello", _HISTORY + "8yr_old_wave_hello",
         _HISTORY + "cmu_new_walk_point", _HISTORY + "cmu_new_walk_raise_the_roof"),
        options=("--seed", "0"),
        summary="Ong & Gong's hybrid-vector model (global PCA, clusters, transitions) of "
                "three training subjects' gestures through the four Pose2Sim cameras "
                "(jaxtrack.experiments.linear_combination.TRAIN_CLIPS)",
        also_reads=("pose2sim/Calib.qca.txt", "pose2sim/background_cam01.jpg")),
    "postures": Recipe(
        "postures", "mixed-state",
        ("cmu_posture_bvh/75_19", "cmu_posture_bvh/64_26", "cmu_amc/07_01"),
        laid_down=(_AD + "fair1_wave_hello", _HISTORY + "8yr_old_wave_hello"),
        # rendered at half the experiment's 640 x 480: the projection histograms are of the
        # silhouette's bounding box, and the 6 500 rendered frames take a quarter of the time
        options=("--size", "320x240", "--seed", "0"),
        summary="Kwatra et al.'s posture model (a Gaussian per posture over silhouette "
                "projection histograms, posture transitions): CMU 75 sits, 64 stoops, 07 "
                "walks; lying from two waves laid down",
        also_reads=("pose2sim/background_cam01.jpg",)),
}
"""The bundled models by file stem, and the ``jaxtrack train`` commands that make them."""

METHODS = {"latent": "latent", "condensation": "latent", "mht": "latent",
           "linear-combination": "linear_combination", "mixed-state": "postures"}
"""``jaxtrack track --method`` -> the bundled model it uses without ``--model`` (CONDENSATION
and MHT learn their dynamics from the latent prior's training poses)."""

LICENCES = {
    "animateddrawings": "MIT", "animateddrawings_bvh": "MIT",
    "cmu_amc": "CMU", "cmu_asfamc_walk": "CMU", "cmu_bvh": "CMU", "cmu_bvh_131": "CMU",
    "cmu_posture_bvh": "CMU",
    "pose2sim": "BSD-3-Clause", "pose2sim_demo_singleperson": "BSD-3-Clause",
    "bandai": "CC BY-NC 4.0", "bandai_namco_gestures": "CC BY-NC 4.0",
    "deepmimic_getup_bvh": "LGPL-3.0", "hdm05_cut": "CC BY-SA 3.0",
}
"""Licence of each data collection (``shared/data/README.md``): CMU is CMU's terms, free for
research and commercial use."""

SHIPPABLE_LICENCES = ("MIT", "CMU", "BSD-3-Clause")
"""Licences whose data, and models trained on it, may go into the wheel."""



def source_licence(clip: str) -> str:
    """The licence of a catalogue clip's collection (:data:`LICENCES`).

    Raises:
        KeyError: a collection of unknown licence (a user's own file).
    """
    collection = clip.replace("\\", "/").split("/", 1)[0]
    if collection not in LICENCES:
        raise KeyError(f"{clip}: no known licence for collection {collection!r}")
    return LICENCES[collection]


def models_folder() -> Path:
    """The folder of the bundled models (``jaxtrack/data/files/models``)."""
    return Path(os.fspath(importlib.resources.files("jaxtrack.data").joinpath("files",
                                                                             "models")))


def _recipe(method: str) -> Recipe:
    if method in METHODS:
        return RECIPES[METHODS[method]]
    if method in RECIPES:
        return RECIPES[method]
    raise ValueError(f"no bundled model for {method!r}; methods: {', '.join(METHODS)}")


def default_model(method: str) -> Path:
    """The bundled model ``jaxtrack track --method method`` uses without ``--model``.

    Args:
        method: a ``jaxtrack track --method`` (or a model's name, :data:`RECIPES`).

    Raises:
        ValueError: an unknown method.
        FileNotFoundError: the package was installed without its models (one line, saying
            how to make one).
    """
    recipe = _recipe(method)
    file = models_folder() / recipe.file_name
    if not file.is_file():
        raise FileNotFoundError(
            f"the bundled model {recipe.file_name} for --method {method} is not in {file.parent} "
            f"(an install without package data?); train one with {recipe.command()} and give it "
            f"as --model")
    return file


def describe(method: str) -> dict:
    """What the bundled model of ``method`` (or of a model's name) was trained on: its JSON
    description (``name``, ``file``, ``train_method``, ``used_by``, ``clips``, ``laid_down``,
    ``subjects`` with their split, ``licences`` per source, ``command``, ``date``, ``sha256``,
    ``bytes``, ``summary``, and what the training wrote into the model, ``trained``)."""
    recipe = _recipe(method)
    file = models_folder() / f"{recipe.name}.json"
    if not file.is_file():
        raise FileNotFoundError(f"no description of the bundled model {recipe.file_name} at "
                                f"{file}; rebuild it with python -m jaxtrack.data.models "
                                f"--rebuild {recipe.name}")
    return json.loads(file.read_text())


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _check_recipe(recipe: Recipe) -> dict[str, str]:
    """Subject -> split of every clip; refused unless all are training subjects with a
    shippable licence."""
    from jaxtrack.data.splits import split_of, subject_of

    subjects = {}
    for clip in (*recipe.clips, *recipe.laid_down):
        licence = source_licence(clip)
        if licence not in SHIPPABLE_LICENCES:
            raise ValueError(f"{recipe.name}: {clip} is under {licence}, which may not go into "
                             f"the wheel")
        if split_of(clip) != "training":
            raise ValueError(f"{recipe.name}: {clip} is a {split_of(clip)} subject's; bundled "
                             f"models learn from training subjects only")
        subjects[subject_of(clip)] = split_of(clip)
    return subjects


def _commit() -> str | None:
    """The source checkout's commit, when the package runs from one."""
    try:
        found = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).parent,
                               capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return found.stdout.strip() or None


def _trained_description(path: Path) -> dict:
    """The description the training saved inside the model file (its JSON metadata)."""
    import numpy as np

    with np.load(path, allow_pickle=False) as saved:
        if "metadata" not in saved.files:
            return {}
        return json.loads(str(saved["metadata"])).get("description", {})


def _compress(trained: Path, target: Path) -> Path:
    """``trained``'s arrays (metadata included, unchanged) written to ``target`` as a
    compressed ``.npz``: the same model in half the wheel (the linear-combination model's
    training vectors, 3.9 MB raw, take 1.9 MB)."""
    import numpy as np

    from jaxtrack._files import write_atomically

    with np.load(trained, allow_pickle=False) as saved:
        arrays = {key: saved[key] for key in saved.files}

    def write(temporary: Path) -> None:
        with open(temporary, "wb") as file:
            np.savez_compressed(file, **arrays)
            file.flush()
            os.fsync(file.fileno())

    write_atomically(target, write)
    return target


def rebuild(names: list[str] | None = None, folder: Path | None = None) -> list[Path]:
    """Retrain bundled models with their :data:`RECIPES` commands and write each model and its
    description into ``folder`` (default :func:`models_folder`), each file written whole.

    The command runs as a user runs it (``python -m jaxtrack train ...``), with the same
    environment, so its clips are found where ``jaxtrack.data.path`` finds them.
    """
    from jaxtrack._files import write_json_atomically

    folder = models_folder() if folder is None else Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name in names or list(RECIPES):
        if name not in RECIPES:
            raise ValueError(f"no bundled model {name!r}; models: {', '.join(RECIPES)}")
        recipe = RECIPES[name]
        subjects = _check_recipe(recipe)
        with tempfile.TemporaryDirectory() as scratch:
            trained = Path(scratch) / recipe.file_name
            arguments = recipe.arguments(trained)
            print(f"{recipe.command()}", flush=True)
            begin = time.perf_counter()
            subprocess.run([sys.executable, "-m", "jaxtrack", *arguments], check=True)
            seconds = time.perf_counter() - begin
            target = _compress(trained, folder / recipe.file_name)
        description = {
            "name": name, "file": recipe.file_name, "train_method": recipe.train_method,
            "used_by": [method for method, model in METHODS.items() if model == name],
            "summary": recipe.summary, "clips": list(recipe.clips),
            "laid_down": list(recipe.laid_down), "subjects": subjects,
            "split": "training subjects only (jaxtrack.data.splits)",
            "licences": {clip: source_licence(clip) for clip in (*recipe.clips,
                                                                 *recipe.laid_down)},
            "also_reads": {file: ALSO_READ[file] for file in recipe.also_reads},
            "command": recipe.command(),
            "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d"),
            "commit": _commit(), "training_seconds": round(seconds, 1),
            "sha256": _digest(target), "bytes": target.stat().st_size,
            "trained": _trained_description(target)}
        write_json_atomically(folder / f"{name}.json", description)
        written.append(target)
    return written


def _table() -> str:
    lines = []
    for name, recipe in RECIPES.items():
        file = models_folder() / recipe.file_name
        size = f"{file.stat().st_size / 1e3:.0f} kB" if file.is_file() else "missing"
        used = ", ".join(method for method, model in METHODS.items() if model == name)
        lines.append(f"{recipe.file_name} ({size}; jaxtrack track --method {used}):\n"
                     f"  {recipe.summary}\n  {recipe.command()}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``python -m jaxtrack.data.models [--rebuild [NAME ...]]``."""
    parser = argparse.ArgumentParser(prog="python -m jaxtrack.data.models",
                                     description="list or retrain jaxtrack's bundled models")
    parser.add_argument("--rebuild", nargs="*", metavar="NAME", default=None,
                        help=f"retrain these models (default all: {', '.join(RECIPES)})")
    parser.add_argument("--out", type=Path, default=None, metavar="DIR",
                        help="write the rebuilt models here (default: the package's folder)")
    args = parser.parse_args(argv)
    if args.rebuild is None:
        print(_table())
        return 0
    for path in rebuild(args.rebuild or None, args.out):
        print(f"wrote {path} ({path.stat().st_size / 1e3:.0f} kB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
