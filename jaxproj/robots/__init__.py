"""jaxproj.robots."""
