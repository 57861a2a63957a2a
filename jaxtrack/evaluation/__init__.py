"""jaxtrack.evaluation."""
