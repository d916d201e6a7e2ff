"""jaxproj.robots.unitree_g1: the Unitree G1 (29-DoF body, revision 1.0).

``unitree_g1.xml`` (the project's MJCF, from ``shared/reference/unitree_g1_kinematics.md``),
``robot`` (joints in Unitree's SDK order, limits, speeds, the loader) and ``spec`` (the
``Robot``, registered as ``"unitree_g1"``: its correspondence table, chains and generic IK).
"""
