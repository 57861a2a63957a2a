"""jaxtrack: JAX-accelerated, differentiable particle filters for tracking human body pose.

Subpackages (data flows down the list; lower layers never import higher ones):

- ``jaxtrack.smc``          generic SMC engine: ``run``, ``step``, resamplers, smoothers, Kalman
- ``jaxtrack.body``         motion capture, skeletons, marker sets, cameras, pose models, renderer
- ``jaxtrack.priors``       learned pose spaces (GPLVM, linear combinations) and dynamics
- ``jaxtrack.vision``       OpenCV preprocessing, overlays and video writing (with the renderer,
                            the only place cv2/kornia are imported)
- ``jaxtrack.likelihoods``  per-particle image likelihoods
- ``jaxtrack.trackers``     the assembled trackers and baselines
- ``jaxtrack.evaluation``   metrics and their plots
- ``jaxtrack.experiments``  the protocol that renders, tracks and scores; the demo
- ``jaxtrack.cli``          one module per ``jaxtrack`` command

See docs/layers.md.

``import jaxtrack`` imports only JAX-side code; OpenCV and PyTorch are imported lazily where used.
"""

from jaxtrack import smc

__version__ = "0.1.0"

__all__ = ["smc", "__version__"]
