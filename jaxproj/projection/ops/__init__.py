"""GPU kernels of the projection (Pallas) and the one switch between them and XLA (``Impl``)."""

from jaxproj.projection.ops.impl import Impl, ImplLike, pallas_interpret, platform_of, resolve_impl

__all__ = ["Impl", "ImplLike", "pallas_interpret", "platform_of", "resolve_impl"]
