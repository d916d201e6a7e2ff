"""jaxproj.eval."""
