"""jaxtrack.likelihoods."""
