"""jaxtrack.priors."""
