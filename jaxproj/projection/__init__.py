"""jaxproj.projection.objectives."""
