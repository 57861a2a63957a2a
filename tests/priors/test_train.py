"""The trained prior: the optimiser and the back-constraint it was trained with are part of its
cache key."""

from jaxtrack.priors.train import train_prior

CLIP = ("animateddrawings/fair1_wave_hello",)


def test_train_prior_keeps_the_optimiser_and_back_constraint_in_its_cache_key(tmp_path):
    options = dict(views=1, fps=5.0, active_size=20, iterations=1, active_steps=5,
                   progress=False, cache=tmp_path / "prior.npz")
    lbfgs = train_prior(CLIP, optimiser="lbfgs", **options)
    assert lbfgs.description["settings"]["optimiser"] == "lbfgs" and lbfgs.seconds > 0
    again = train_prior(CLIP, optimiser="lbfgs", **options)  # loaded from the cache
    assert again.seconds == 0.0
    assert again.description["settings_key"] == lbfgs.description["settings_key"]
    # BFGS (the default) is not served the cached L-BFGS prior, and its settings have no
    # optimiser entry, so caches written before the option existed stay valid
    bfgs = train_prior(CLIP, **options)
    assert bfgs.seconds > 0 and "optimiser" not in bfgs.description["settings"]
    assert bfgs.description["settings_key"] != lbfgs.description["settings_key"]
    # nor the back-constrained one, whose width is in its settings
    constrained = train_prior(CLIP, back_constraint=0.5, **options)
    assert constrained.seconds > 0
    assert constrained.description["settings"]["back_constraint"] == 0.5
    assert "back_constraint" not in bfgs.description["settings"]
    assert constrained.description["settings_key"] != bfgs.description["settings_key"]
