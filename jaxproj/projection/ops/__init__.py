"""jaxproj.projection.objectives.ops."""
