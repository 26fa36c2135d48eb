"""The ``mimarble`` command line: ``mimarble.cli.main.main`` parses the arguments and runs one command."""
