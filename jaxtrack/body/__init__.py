"""jaxtrack.body."""
