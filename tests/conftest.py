"""Test-wide settings: float64 so numerics can be checked against closed forms.

Library code respects input dtypes; float32 behaviour is tested with explicit float32 inputs.

Every compiled XLA program maps a few pages of executable memory, and the process may hold at
most ``vm.max_map_count`` (65 530 by default) mappings: a suite that keeps every program it
ever compiled reaches that limit and the compiler crashes (a segmentation fault inside
``backend_compile_and_load``). The compiled programs are therefore released after each module.
"""

import gc

import jax
import pytest

jax.config.update("jax_enable_x64", True)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop JAX's compilation caches (and the linear-combination tracker's ahead-of-time
    executables) once a test module is done, so their memory mappings are unmapped."""
    yield
    from jaxtrack.trackers import linear_combination

    linear_combination.release_compiled()
    jax.clear_caches()
    gc.collect()
