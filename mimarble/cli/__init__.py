"""The ``mimarble`` command line: ``mimarble.cli.main.main`` parses the arguments and runs one
command (the console script ``mimarble.cli.main:main``).

Nothing is imported here: ``from mimarble.cli import main`` is the module
mimarble/cli/main.py (``main.main`` the function, ``main.build_parser`` the parser).
"""
