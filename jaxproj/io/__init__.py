"""jaxproj.io."""
