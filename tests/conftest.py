"""Test-wide settings: float64 so numerics can be checked against closed forms.

Library code respects input dtypes; float32 behaviour is tested with explicit float32 inputs.

Every compiled XLA program maps a few pages of executable memory, and the process may hold at
most ``vm.max_map_count`` (65 530 by default) mappings: a suite that keeps every program it
ever compiled reaches that limit and the compiler crashes (a segmentation fault inside
``backend_compile_and_load``). The compiled programs are therefore released after each module.

Many modules compile the same programs (the same tracker on the same tiny shapes), so one
pytest run shares a persistent compilation cache in a temporary folder: the first module to
compile a program writes it, later modules (in any xdist worker) load it instead of compiling
again. The folder is made once by the process that imports this file first (pytest's main
process, before it starts the workers, which inherit its path) and removed when that process
exits. Setting ``JAXTRACK_TEST_XLA_CACHE`` to a folder keeps the cache there across runs.
"""

import atexit
import functools
import gc
import os
import shutil
import tempfile
from pathlib import Path

import jax
import pytest

jax.config.update("jax_enable_x64", True)

if "JAXTRACK_TEST_XLA_CACHE" not in os.environ:
    os.environ["JAXTRACK_TEST_XLA_CACHE"] = tempfile.mkdtemp(prefix="jaxtrack-tests-xla-")
    atexit.register(shutil.rmtree, os.environ["JAXTRACK_TEST_XLA_CACHE"], ignore_errors=True)
jax.config.update("jax_compilation_cache_dir", os.environ["JAXTRACK_TEST_XLA_CACHE"])
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.2)
jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop JAX's compilation caches (and the linear-combination tracker's ahead-of-time
    executables) once a test module is done, so their memory mappings are unmapped."""
    yield
    from jaxtrack.trackers import linear_combination

    linear_combination.release_compiled()
    jax.clear_caches()
    gc.collect()


# the files that take longest (``pytest --durations``, 2026-11-26/27 and 11-29), started first: with
# ``--dist loadfile`` each file runs whole in one worker, and the collection order (alphabetical,
# so ``tests/trackers/`` last) otherwise left one worker alone with the heaviest files at the end
HEAVY_FIRST = ("tests/trackers/test_five_trackers.py", "tests/trackers/test_tracker_contract.py",
               "tests/trackers/test_latent.py",
               "tests/trackers/test_held_out_subject.py", "tests/test_notebooks.py",
               "tests/papers/test_tian2005_tracking.py", "tests/smc/test_transformations.py",
               "tests/priors/test_gplvm.py", "tests/likelihoods/test_edges.py",
               "tests/cli/test_paths.py", "tests/trackers/test_baselines.py")


SLOW_LIST = Path(__file__).with_name("slow.txt")
"""Node ids of the tests measured slowest (``tests/slow.txt`` says how), marked ``slow`` here so
that ``make test`` keeps within 10 minutes on 2 cores; ``pytest -m slow`` runs them."""


@pytest.hookimpl(tryfirst=True)  # before ``-m 'not slow'`` deselects by the marks
def pytest_itemcollected(item):
    """Mark the tests of :data:`SLOW_LIST` ``slow``."""
    if item.nodeid in _slow_ids():
        item.add_marker(pytest.mark.slow)


@functools.cache
def _slow_ids() -> frozenset[str]:
    lines = SLOW_LIST.read_text().splitlines()
    return frozenset(line.strip() for line in lines if line.strip() and not line.startswith("#"))


def pytest_collection_modifyitems(config, items):
    """Run the :data:`HEAVY_FIRST` files first (a stable sort: order within a file is kept)."""
    rank = {name: index for index, name in enumerate(HEAVY_FIRST)}
    root = config.rootpath
    items.sort(key=lambda item: rank.get(item.path.relative_to(root).as_posix(), len(rank)))
