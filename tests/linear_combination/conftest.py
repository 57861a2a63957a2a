"""A short real clip rendered through one Pose2Sim camera, and a tiny model trained on it."""

import pytest

from jaxtrack.experiments.linear_combination import render_hybrid_sequences

CLIP = "animateddrawings/history_c119d6b/cmu_1006_wave_hello_1"


@pytest.fixture(scope="session")
def rendered():
    """12 frames at 6 fps (the arms move between frames) through camera 1, with the tracker's
    observations; 40 contour points."""
    return render_hybrid_sequences(CLIP, views=(0,), num_contour=40, fps=6.0, max_frames=12,
                                   keep_observations=True)[0]
