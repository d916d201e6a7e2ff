"""The ``jaxproj`` command line: thin subcommands over the public API (``jaxproj.cli.main``)."""

from jaxproj.cli.main import build_parser, main

__all__ = ["build_parser", "main"]
