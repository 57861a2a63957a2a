"""Test-wide settings: float64 so numerics can be checked against closed forms.

Library code respects input dtypes; float32 behaviour is tested with explicit float32 inputs.
"""

import jax

jax.config.update("jax_enable_x64", True)
