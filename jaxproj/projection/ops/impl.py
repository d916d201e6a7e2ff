"""The one backend switch of the projection: ``Impl`` (the Pallas kernels or their XLA twins).

Two steps of the batched relaxed projection have a fused Pallas (Triton) kernel and an XLA twin
that computes the same thing: the exact k-NN search (``knn_pallas`` / ``search.nearest``) and
the back-projection's least deviations (``backproj_pallas`` / ``relaxed._least_deviations``).
Which one runs is a value, not a hidden switch (as MJX's ``Impl``): ``"auto"`` is resolved
ONCE, from the platform of the target device (``resolve_impl``), to ``"pallas"`` on CUDA GPUs
(where the kernels are measured faster, ``benchmarks/RESULTS.md``) and ``"xla"`` everywhere
else; the resolved value travels down as a static argument. A caller (an A/B script, a test)
passes ``impl="xla"`` or ``impl="pallas"`` to override it.

``"pallas"`` compiles the kernels with Triton when the default backend is a CUDA GPU and runs
them in Pallas' interpreter on any other platform (``pallas_interpret``: slow, for tests).

Not behind this switch: ``search.smallest``'s choice between XLA ``TopK`` (CPU) and repeated
minima (other platforms). Both are XLA programs selecting the same exact neighbours; it is a
per-platform tuning of the XLA search, not a backend, and stays with the search.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence

import jax

from jaxproj.errors import ConfigError


class Impl(enum.StrEnum):
    """Backend of the projection's fused steps (see the module doc)."""

    AUTO = "auto"
    XLA = "xla"
    PALLAS = "pallas"


ImplLike = Impl | str
"""An ``Impl`` or its value (``"auto"``, ``"xla"``, ``"pallas"``)."""


def platform_of(devices: Sequence[jax.Device] | None = None) -> str:
    """The platform programs for ``devices`` are lowered for (``None``: the default backend):
    ``"cpu"``, ``"cuda"``, ``"rocm"``, ``"tpu"``, ... (``lax.platform_dependent``'s names: a
    GPU is ``"cuda"`` or ``"rocm"``, not ``"gpu"``)."""
    device = list(devices)[0] if devices else jax.devices()[0]
    platform = device.platform
    if platform == "gpu":
        version = str(getattr(device.client, "platform_version", "")).lower()
        platform = "rocm" if "rocm" in version else "cuda"
    return platform


def resolve_impl(impl: ImplLike = Impl.AUTO, devices: Sequence[jax.Device] | None = None) -> Impl:
    """``impl`` as an ``Impl``, ``"auto"`` resolved for the platform of ``devices`` (``None``: the
    default backend): ``Impl.PALLAS`` on CUDA GPUs, ``Impl.XLA`` elsewhere.

    Raises:
      ConfigError: ``impl`` is not one of ``"auto"``, ``"xla"``, ``"pallas"``.
    """
    try:
        impl = Impl(impl)
    except ValueError:
        choices = ", ".join(repr(i.value) for i in Impl)
        raise ConfigError(f"impl must be one of {choices}, got {impl!r}") from None
    if impl is Impl.AUTO:
        return Impl.PALLAS if platform_of(devices) == "cuda" else Impl.XLA
    return impl


def pallas_interpret() -> bool:
    """Whether ``Impl.PALLAS`` runs the kernels in Pallas' interpreter (the default backend is
    not a CUDA GPU) rather than compiled with Triton."""
    return platform_of() != "cuda"
