"""jaxproj.robots.nao_h25."""
