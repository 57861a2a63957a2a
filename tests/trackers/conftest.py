"""A small GPLVM prior and rendered held-out clips, shared by the tracker tests."""

import pytest

from jaxtrack.experiments.protocol import render_test_sequences
from jaxtrack.priors.train import train_prior

HISTORY = "animateddrawings/history_c119d6b/"
TRAIN = ("animateddrawings/fair1_wave_hello", HISTORY + "cmu_1006_wave_hello_1")
HELD_OUT = HISTORY + "cmu_1006_wave_hello_2"


@pytest.fixture(scope="session")
def prior():
    """Two adult wave takes, a low pose rate and a small active set."""
    return train_prior(TRAIN, views=2, fps=10.0, active_size=60, iterations=1, progress=False)


@pytest.fixture(scope="session")
def wave_prior():
    """The demo's three training takes (``jaxtrack._demo``, one of them a child's), same small
    settings: the ablation over the whole take needs the third take's waving."""
    return train_prior(TRAIN + (HISTORY + "8yr_old_wave_hello",), views=2, fps=10.0,
                       active_size=60, iterations=1, progress=False)


@pytest.fixture(scope="session")
def sequence():
    """The first 16 frames of the held-out take (the arms coming down from a T pose)."""
    return render_test_sequences(HELD_OUT, views=1, backgrounds=("photo",), fps=15.0,
                                 image_size=(320, 240), max_frames=16)[0]


@pytest.fixture(scope="session")
def whole_take():
    """The whole held-out take (69 frames at 15 fps): the arms come down, then wave."""
    return render_test_sequences(HELD_OUT, views=1, backgrounds=("photo",), fps=15.0,
                                 image_size=(320, 240))[0]
