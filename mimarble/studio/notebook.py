"""The studio inline in a Jupyter notebook: ``mimarble.studio(scene)`` — the same server and
page as ``mimarble studio`` (mimarble/studio/server.py), run in a background thread of the
kernel and shown in an ``<iframe>``."""

from __future__ import annotations

import atexit
import html

#: The iframe's height in pixels unless told otherwise (the render and its controls).
HEIGHT = 760


class StudioView:
    """A running studio: shown inline by Jupyter (``_repr_html_``: an iframe of its page),
    stopped by :meth:`close` (or when the kernel exits).

    ========== ===============================================================
    Attribute  Meaning
    ========== ===============================================================
    session    the :class:`~mimarble.studio.StudioSession` (edit it from code too)
    server     the :class:`~mimarble.studio.server.StudioServer`
    url        the page's address with its token (open it in a browser tab as well)
    height     the iframe's height in pixels
    ========== ===============================================================
    """

    def __init__(self, session, server, height: int = HEIGHT):
        self.session = session
        self.server = server
        self.height = int(height)
        self._closed = False
        atexit.register(self.close)

    @property
    def url(self) -> str:
        return self.server.url

    def _repr_html_(self) -> str:
        if self._closed:
            return "<p>mimarble studio: closed</p>"
        return (f'<iframe src="{html.escape(self.url, quote=True)}" width="100%" '
                f'height="{self.height}" style="border:1px solid #8884" '
                f'title="mimarble studio: {html.escape(str(self.session.path))}"></iframe>')

    def __repr__(self) -> str:
        return f"<mimarble studio {'closed' if self._closed else self.url}>"

    def close(self) -> None:
        """Stop the server and the session's threads; idempotent."""
        if not self._closed:
            self._closed = True
            self.server.stop()
            self.session.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def studio(scene, mode: str | None = None, *, port: int = 0, height: int = HEIGHT) -> StudioView:
    """Start the studio for ``scene`` (a scene file or a packaged scene's name) on
    127.0.0.1 and return its view, which a notebook shows inline.

    ========== ===============================================================
    Parameter  Meaning
    ========== ===============================================================
    scene      a scene file's path, or a packaged scene's name (``"fig11a"``)
    mode       ``"whitted"`` or ``"path"`` (default: the scene's)
    port       the port (0: a free one)
    height     the iframe's height in pixels
    ========== ===============================================================

    Needs the ``studio`` extra (one sentence naming it when missing). The kernel's browser
    must reach 127.0.0.1 of the kernel's machine: a local Jupyter does.
    """
    from mimarble.runtime.extras import require_extra
    require_extra("studio")
    from mimarble.studio.server import StudioServer
    from mimarble.studio.session import StudioSession
    # The name as given: the session resolves a packaged scene's name and then refuses
    # to save over it (resolved here first, it was an ordinary path, saved over).
    session = StudioSession(scene, mode=mode)
    try:
        server = StudioServer(session, port=port).start()
    except BaseException:
        session.close()
        raise
    return StudioView(session, server, height=height)
