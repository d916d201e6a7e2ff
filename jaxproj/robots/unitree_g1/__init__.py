"""jaxproj.robots.unitree_g1: the Unitree G1 (29-DoF body, revision 1.0) MJCF, ``unitree_g1.xml``.

Not registered as a robot yet: only the model file lives here for now.
"""
