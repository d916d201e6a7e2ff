"""jaxproj.paper."""
