"""jaxproj._internal."""
