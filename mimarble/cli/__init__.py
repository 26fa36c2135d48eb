"""The ``mimarble`` command line: ``main`` parses the arguments and runs one command."""

from mimarble.cli.main import main

__all__ = ["main"]
