"""The ``mimarble`` command line: ``main`` parses the arguments, runs one command, and
says a user's mistake in one line.

Exit status: 0 success, 1 the environment cannot render (``doctor``), 2 a user
error (bad scene, bad argument, unusable variant). User errors print one
message and no traceback: ``mimarble: …`` (``mimarble: FILE: …`` for a scene file that
cannot be read), or ``FILE:LINE:COL: …`` for an error at a place in a scene file, as
compilers write it.

The options are mimarble/cli/arguments.py's; each command is a function in a module of
its own (:data:`HANDLERS`), imported when that command runs, so that a mistake in
another command's options or in a scene costs no more than what it needs.
"""

from __future__ import annotations

import importlib
import os
import sys

from mimarble.cli.arguments import build_parser, command_named
# What tests and scripts call as ``cli.X`` (mimarble/cli/shared.py).
from mimarble.cli.shared import UsageError, load_scene, scene_list, start_mitsuba

__all__ = ["main", "build_parser", "HANDLERS", "UsageError", "load_scene", "scene_list",
           "start_mitsuba"]

#: Each command's handler: (module under mimarble/cli, function). The function takes the
#: parsed arguments and returns the exit status (or raises UsageError, SceneError, …).
HANDLERS = {
    "render": ("render", "_render"),
    "reference": ("render", "_reference"),
    "compare": ("compare", "_compare"),
    "bench": ("bench", "_bench"),
    "stress": ("bench", "_stress"),
    "sweep": ("sweep", "_sweep"),
    "gallery": ("scenes", "_gallery"),
    "scenes": ("scenes", "_scenes"),
    "presets": ("presets", "_presets"),
    "export": ("export_bake", "_export"),
    "bake": ("export_bake", "_bake"),
    "doctor": ("doctor", "_doctor"),
    "studio": ("studio", "_studio"),
}


def _handler(command: str):
    """The function that runs ``command``, its module imported now."""
    module, function = HANDLERS[command]
    return getattr(importlib.import_module(f"mimarble.cli.{module}"), function)


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """Warnings are sentences for the user, not source locations of ours (the user's
    strings in them made printable: scene/errors.py)."""
    from mimarble.scene.errors import printable
    print(f"mimarble: warning: {printable(message)}", file=sys.stderr if file is None else file)


def main(argv=None) -> int:
    import warnings
    warnings.showwarning = _show_warning
    typed = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(command_named(typed))        # only the command run gets its options
    args = parser.parse_args(typed)
    args.argv = typed                                  # as typed, for provenance
    from mimarble.runtime.environment import EnvironmentProblem
    from mimarble.scene.errors import SceneError, printable
    try:
        return _handler(args.command)(args)
    except (EnvironmentProblem, UsageError) as e:
        # One line: a newline or an escape code in a name it quotes is shown, not sent.
        print(f"mimarble: {printable(e)}", file=sys.stderr)
        return 2
    except SceneError as e:
        # FILE:LINE:COL: message, as compilers write it (editors jump to it); an error with
        # no position (a scene file that cannot be read) is the program's: "mimarble: FILE: …".
        print(e if e.line is not None else f"mimarble: {e}", file=sys.stderr)
        return e.exit_status
    except KeyboardInterrupt:
        print("mimarble: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (`mimarble compare … | head`): not an error of ours.
        sys.stdout = open(os.devnull, "w")
        return 0


if __name__ == "__main__":
    sys.exit(main())
