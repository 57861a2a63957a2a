"""Tracker options as small modules: validated once, passed through unopened, written to JSON.

* :class:`Likelihood` — which appearance likelihood scores a frame, its sharpness λ and how
  pixels are read (every tracker takes one).
* :class:`Engine` — the particle filter's settings: particles, resampler, ESS threshold (the
  particle-filter trackers take one).
* :class:`Refinement` — the full-state refinement stage (Gauss–Newton on the likelihood under a
  Gaussian prior about each start) with its optional :class:`ArmSearch`; any tracker that
  reports SPM poses takes one (``None``: report the filter's own estimate).

Each is an ``equinox.Module`` of static Python values, so two trackers built with equal options
compile to the same code, and :func:`options_record` turns any of them into the JSON a result
file records. Why each default is what it is: ``docs/trackers.md``.
"""

from __future__ import annotations

import dataclasses
import math

import equinox as eqx

from jaxtrack import smc
from jaxtrack.likelihoods import DEFAULT_LIKELIHOOD, LIKELIHOODS, default_sharpness, needs_edges

__all__ = ["DEFAULT_ARM_GRID", "DEFAULT_ARM_MARGIN", "DEFAULT_ARM_MOMENTUM", "DEFAULT_ARM_SPAN",
           "DEFAULT_REFINE_STEPS", "RESAMPLERS", "ArmSearch", "Engine", "Likelihood", "Refinement",
           "options_record"]

DEFAULT_REFINE_STEPS = 3
"""Gauss–Newton trial steps per candidate and frame of the refinement. Chosen on the validation
subject over {3, 10, 30}, which tied within their paired 95 % interval, the tie going to the
cheapest (``python -m papers.tian2005.defaults_sweep``; ``docs/trackers.md``, "Why the defaults
are what they are"). It was 10 (MHT's ``max_steps`` still is), first tuned on a test subject's
clip."""

DEFAULT_ARM_GRID = 7
"""Offsets per arm angle of the arm search (7 × 7 upper-arm × forearm angles per arm and
candidate, 0.2 rad apart with :data:`DEFAULT_ARM_SPAN`); chosen on the Bandai validation splits
(``docs/trackers.md``, "Arm search")."""

DEFAULT_ARM_SPAN = 0.6
"""Largest angle offset (radians) of the arm search; chosen on a Bandai validation split
(``docs/trackers.md``, "Arm search")."""

DEFAULT_ARM_MARGIN = 2.0
"""Nats by which the arm search's best offset must beat the arm as it was; chosen on the Bandai
validation splits (``docs/trackers.md``, "Arm search")."""

DEFAULT_ARM_MOMENTUM = 1.0
"""Factor on the arm angles' change over the last frame that gives the arm search's second
centre (1: constant velocity; 0: none); chosen on the Bandai validation splits
(``docs/trackers.md``, "Arm search")."""


def _number(value, name: str, low: float, high: float = math.inf, *, closed_low: bool = True
            ) -> None:
    """Raise unless ``low ≤ value ≤ high`` (``low < value`` when ``closed_low`` is False)."""
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(
        value) and (value >= low if closed_low else value > low) and value <= high
    if not ok:
        bound = f"{'>=' if closed_low else '>'} {low}" + (f" and <= {high}" if high < math.inf
                                                          else "")
        raise ValueError(f"{name} must be a finite number {bound}, got {value!r}")


_EDGE_BOUNDS = {"edge_weight": math.inf, "edge_tolerance": 90.0, "foreground_weight": math.inf,
                "coverage_weight": math.inf, "keypoint_weight": math.inf,
                "keypoint_scale": math.inf}
"""The ``"limbs+edges"`` settings a :class:`Likelihood` may give, and their upper bounds."""


class Likelihood(eqx.Module):
    """How a tracker scores a frame.

    Attributes:
        kind: ``"limbs+edges"`` (limb strips, their oriented edges and, given a background,
            the arms' foreground), ``"limbs"`` (the strips alone) or ``"markers"`` (Tian et
            al.'s eq. 7 patches at the markers); :mod:`jaxtrack.likelihoods.appearance`.
        sharpness: λ; None for the kind's default.
        nearest: particles read pixels at the nearest sample point (fast) instead of
            bilinearly (refinements and mode scores always read bilinearly).
        edge_weight, edge_tolerance, foreground_weight: ``"limbs+edges"``'s κ, angular
            tolerance (degrees) and μ (``jaxtrack.likelihoods.edges``); None for the library's
            defaults, whose docstrings say where they were chosen.
        coverage_weight: ``"limbs+edges"``'s ν, the weight of its coverage term, which charges
            the person's mask for what the body leaves unexplained (needs masks:
            ``jaxtrack.trackers.track(..., masks=...)``); None or 0: off, the default.
        keypoint_weight, keypoint_scale: ``"limbs+edges"``'s η and τ, the weight and scale of
            its keypoint term, which scores a per-frame detector's keypoints (needs them:
            ``jaxtrack.trackers.track(..., keypoints=...)``); η None or 0: off, the default.
    """

    kind: str = eqx.field(static=True, default=DEFAULT_LIKELIHOOD)
    sharpness: float | None = eqx.field(static=True, default=None)
    nearest: bool = eqx.field(static=True, default=True)
    edge_weight: float | None = eqx.field(static=True, default=None)
    edge_tolerance: float | None = eqx.field(static=True, default=None)
    foreground_weight: float | None = eqx.field(static=True, default=None)
    coverage_weight: float | None = eqx.field(static=True, default=None)
    keypoint_weight: float | None = eqx.field(static=True, default=None)
    keypoint_scale: float | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        if self.kind not in LIKELIHOODS:
            raise ValueError(f"likelihood must be one of {LIKELIHOODS}, got {self.kind!r}")
        if self.sharpness is not None:
            _number(self.sharpness, "sharpness", 0, closed_low=False)
        if not isinstance(self.nearest, bool):
            raise ValueError(f"nearest must be True or False, got {self.nearest!r}")
        for name, high in _EDGE_BOUNDS.items():
            value = getattr(self, name)
            if value is None:
                continue
            if self.kind != "limbs+edges":
                raise ValueError(f"{name} is a setting of the 'limbs+edges' likelihood, not of "
                                 f"{self.kind!r}")
            _number(value, name, 0, high,
                    closed_low=name not in ("edge_tolerance", "keypoint_scale"))

    @property
    def edge_options(self) -> dict:
        """The edge settings given (not None), as ``make_edge_limb_templates`` keywords."""
        return {name: float(getattr(self, name)) for name in _EDGE_BOUNDS
                if getattr(self, name) is not None}

    @property
    def has_coverage(self) -> bool:
        """Whether the coverage term is on (it needs the person's masks)."""
        return bool(self.coverage_weight)

    @property
    def has_keypoints(self) -> bool:
        """Whether the keypoint term is on (it needs a detector's keypoints per frame)."""
        return bool(self.keypoint_weight)

    @property
    def lam(self) -> float:
        """λ: ``sharpness``, or the kind's default."""
        return default_sharpness(self.kind) if self.sharpness is None else float(self.sharpness)

    @property
    def needs_edges(self) -> bool:
        """Whether frames are observed with their edge maps, ``(3, height, width)``."""
        return needs_edges(self.kind)


RESAMPLERS = {"systematic": smc.Systematic, "stratified": smc.Stratified,
              "multinomial": smc.Multinomial, "residual": smc.Residual}
"""The engine's resamplers by name (``jaxtrack.smc``)."""


class Engine(eqx.Module):
    """The particle filter's settings (``jaxtrack.smc.step``).

    Attributes:
        num_particles: N.
        resampler: one of :data:`RESAMPLERS` (default systematic).
        ess_threshold: resample when ESS < ess_threshold × N (1: every frame, as CONDENSATION).
        iterations_per_frame: select/predict/measure cycles on each frame (1: CONDENSATION's;
            Ong & Gong ran 5), each with the model's full dynamics noise; the frame's log
            evidence is the first cycle's (``jaxtrack.smc.step``).
    """

    num_particles: int = eqx.field(static=True)
    resampler: str = eqx.field(static=True, default="systematic")
    ess_threshold: float = eqx.field(static=True, default=1.0)
    iterations_per_frame: int = eqx.field(static=True, default=1)

    def __check_init__(self):
        for name in ("num_particles", "iterations_per_frame"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        if self.resampler not in RESAMPLERS:
            raise ValueError(f"resampler must be one of {tuple(RESAMPLERS)}, got "
                             f"{self.resampler!r}")
        _number(self.ess_threshold, "ess_threshold", 0, 1)

    def step(self, key, state: smc.FilterState, observation, model: smc.StateSpaceModel):
        """``jaxtrack.smc.step`` with these settings."""
        return smc.step(key, state, observation, model, resampler=RESAMPLERS[self.resampler](),
                        ess_threshold=self.ess_threshold,
                        iterations_per_frame=self.iterations_per_frame)


class ArmSearch(eqx.Module):
    """The global search over each arm's two image angles that starts each refinement.

    For each arm, every combination of ``grid`` offsets of the upper-arm and forearm angles in
    ``[−span, span]`` is scored by the likelihood (the arm's strips alone), about the arm as it
    was and, with ``momentum`` > 0, about the arm moved on by ``momentum`` × its change over
    the last frame; the best is kept if it beats the arm as it was by ``margin`` nats.

    Attributes:
        grid: offsets per angle, odd (offset 0 in the middle).
        span: largest offset in radians.
        margin: nats the best offset must win by.
        momentum: in [0, 1]; 0 searches about the carried arm alone.
    """

    grid: int = eqx.field(static=True, default=DEFAULT_ARM_GRID)
    span: float = eqx.field(static=True, default=DEFAULT_ARM_SPAN)
    margin: float = eqx.field(static=True, default=DEFAULT_ARM_MARGIN)
    momentum: float = eqx.field(static=True, default=DEFAULT_ARM_MOMENTUM)

    def __check_init__(self):
        if not isinstance(self.grid, int) or self.grid < 1 or self.grid % 2 == 0:
            raise ValueError(f"arm_grid must be an odd positive integer (offset 0 on the grid), "
                             f"got {self.grid!r}")
        _number(self.span, "arm_span", 0, closed_low=False)
        _number(self.margin, "arm_margin", 0)
        _number(self.momentum, "arm_momentum", 0, 1)


class Refinement(eqx.Module):
    """The full-state refinement of a tracker's reported pose (``jaxtrack.trackers``' stage).

    Every frame two candidates, the pose reported at the last frame and the tracker's own
    estimate, are arm-searched (``arm_search``), refined by ``steps`` damped Gauss–Newton trial
    steps on the likelihood under a Gaussian prior about each start, and the better-scoring one
    is reported and carried.

    Attributes:
        steps: Gauss–Newton trial steps per candidate and frame (≥ 1).
        prior_std: σ of the Gaussian prior about each start, relative to the SPM state's noise
            floor: ``prior_std × default_noise_floor(torso)`` (log scale, angles and log
            lengths in units of 0.002, the neck position in 0.2 % of the torso).
        arm_search: the arm search before each refinement; None: none.
    """

    steps: int = eqx.field(static=True, default=DEFAULT_REFINE_STEPS)
    prior_std: float = eqx.field(static=True, default=40.0)
    arm_search: ArmSearch | None = ArmSearch()

    def __check_init__(self):
        if not isinstance(self.steps, int) or self.steps < 1:
            raise ValueError(f"refine_steps must be a positive integer, got {self.steps!r}")
        _number(self.prior_std, "refine prior_std", 0, closed_low=False)


def options_record(options) -> dict | None:
    """A JSON-able dict of an options module (nested modules become dicts; None stays None)."""
    if options is None:
        return None
    if hasattr(options, "record"):  # a module that says how it is recorded (a likelihood)
        return options.record()
    record = {}
    for field in dataclasses.fields(options):
        value = getattr(options, field.name)
        record[field.name] = (options_record(value) if isinstance(value, eqx.Module)
                              else value)
    return record
