"""``mimarble studio``: a scene's marbles tuned live in the browser — the studio's server
started on this machine, its URL (with the token) printed, the browser opened."""

from __future__ import annotations

import os
import sys
import threading
import warnings

from mimarble.cli.shared import UsageError, say, scene_path, start_mitsuba


def _studio(args) -> int:
    """Serve the studio until Ctrl-C: then one line, exit status 0, nothing left running."""
    from mimarble.runtime.extras import require_extra
    require_extra("studio")                    # one sentence naming the extra, exit 2
    path = scene_path(args.scene)
    from mimarble import scene as scene_language
    scene_language.load(path)                  # a bad scene answers before Dr.Jit loads
    from mimarble.studio.server import is_loopback
    if not is_loopback(args.host):
        warnings.warn(f"--host {args.host}: the studio is reachable from other machines; "
                      f"whoever has its URL (token) can edit the scene and write files")
    start_mitsuba(args)
    from mimarble.studio import StudioSession
    from mimarble.studio.server import StudioServer
    try:
        # The argument as given, not ``path``: the session resolves a packaged scene's
        # name itself, and only then knows it is packaged (Save refuses to overwrite it).
        session = StudioSession(args.scene, mode=args.mode)
    except ValueError as e:                    # a mode the studio does not render
        raise UsageError(f"--mode {args.mode}: {e}") from None
    try:
        try:
            server = StudioServer(session, host=args.host, port=args.port).start()
        except OSError as e:
            raise UsageError(f"cannot listen on {args.host}:{args.port}: "
                             f"{e.strerror or e}") from None
        try:
            say(f"mimarble studio: {path}")
            say(f"    {server.url}")
            say("open that URL (it holds the page's token); Ctrl-C stops the studio", flush=True)
            if not args.no_browser:
                _open_browser(server.url)
            stop = threading.Event()
            while not stop.wait(0.5):          # wakes for Ctrl-C (the main thread's signal)
                pass
        except KeyboardInterrupt:
            print("mimarble: studio stopped", file=sys.stderr)
            return 0
        finally:
            server.stop()
    finally:
        session.close()
    return 0


def _open_browser(url: str) -> None:
    """Open ``url`` in the user's browser — a graphical one only: with no display, Python's
    ``webbrowser`` would start a text browser in this terminal, over the server's output."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        say("(no display: open the URL in a browser yourself)", flush=True)
        return
    import webbrowser
    threading.Thread(target=webbrowser.open, args=(url,), daemon=True,
                     name="mimarble-studio-browser").start()
