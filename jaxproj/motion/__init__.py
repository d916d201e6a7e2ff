"""jaxproj.motion."""
