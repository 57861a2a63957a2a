"""The command line shared by the peer scripts (``_peer_particles.py``, ``_peer_cuthbert.py``):
``python SCRIPT IN.npz OUT.json``. Runs under a peer's own venv, so it imports only NumPy and
the standard library (the scripts import it from their own folder, never through jaxtrack)."""

from __future__ import annotations

import json
import os

import numpy as np


def main(argv, run, describe) -> int:
    """Read IN.npz into a dict of arrays, ``result = run(inputs)``, write OUT.json atomically,
    and print ``describe(entry)`` for each of ``result["runs"]``."""
    in_path, out_path = argv[1], argv[2]
    with np.load(in_path, allow_pickle=False) as data:
        inputs = {key: data[key] for key in data.files}
    result = run(inputs)
    with open(out_path + ".tmp", "w") as handle:
        json.dump(result, handle)
    os.replace(out_path + ".tmp", out_path)
    for entry in result["runs"]:
        print(describe(entry))
    return 0
