"""jaxproj.human."""
