"""jaxtrack.trackers."""
