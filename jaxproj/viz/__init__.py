"""jaxproj.viz."""
