"""jaxtrack.vision."""
