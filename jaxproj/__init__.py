"""jaxproj: human-to-humanoid motion projection from sparsely sampled correspondence, in JAX.

Pipeline (one module per stage): ``readers`` / ``datasets`` / ``skeleton`` (data and the body-frame
bone descriptor) -> ``robot`` / ``ik`` (NAO H25 model and the analytic IK ground truth) ->
``retarget`` (whole motions) -> ``smoothing``.

Jit policy: public entry points are jitted; helpers and loops inside them are not.
"""

__version__ = "0.1.0"
