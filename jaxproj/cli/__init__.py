"""The ``jaxproj`` command line: thin subcommands over the public API (``jaxproj.cli.main``)."""

from jaxproj.cli.main import main

__all__ = ["main"]
