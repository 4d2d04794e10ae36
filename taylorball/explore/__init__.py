"""``taylorball explore``: Poincaré sections in the browser (a local Bokeh server).

Choose one of the paper's systems and balls (Figs. 1-5), set Omega and the level, click
on the section chart: the orbit from that point is integrated in a worker thread and its
crossings appear as they come, coloured by its MEGNO class (:mod:`taylorball.palette`).
A section of your own (``gamma3 = 0``, ...) is drawn next to the paper's. Needs the
optional extra ``explore`` (``pip install "taylorball[explore]"``: Bokeh). See
docs/explore.md.
"""

from __future__ import annotations

import logging
import threading
from typing import Any, Optional

from ..errors import UsageError

__all__ = ["serve", "make_document"]

_log = logging.getLogger("taylorball.explore")


def make_document(doc: Any) -> None:
    """Build the explorer in a Bokeh document (for ``bokeh serve`` or a notebook's
    ``bokeh.io.show(make_document)``)."""
    from .app import make_document as build

    build(doc)


def _bokeh():
    try:
        import bokeh  # noqa: F401
    except ImportError:
        raise UsageError("taylorball explore needs Bokeh: pip install \"taylorball[explore]\" "
                         "(or pip install \"bokeh>=3.4\")") from None


def serve(port: int = 5006, *, open_browser: bool = True, warm: bool = True, ready: Optional[Any] = None) -> None:
    """Serve the explorer at ``http://127.0.0.1:port/`` until interrupted (Ctrl-C).

    Parameters
    ----------
    port : int
        TCP port on 127.0.0.1 (0: a free one, printed).
    open_browser : bool
        Open the page in the default browser.
    warm : bool
        Compile the first preset's integrators in the background at start (so the first
        click answers at once).
    ready : callable, optional
        Called with the port once the server listens.
    """
    _bokeh()
    from bokeh.application import Application
    from bokeh.application.handlers.function import FunctionHandler
    from bokeh.server.server import Server

    if not (isinstance(port, int) and not isinstance(port, bool) and 0 <= port <= 65535):
        raise UsageError(f"port must be an integer in [0, 65535], got {port!r}")
    if port == 0:
        import socket

        with socket.socket() as sock:
            sock.bind(("127.0.0.1", 0))
            port = int(sock.getsockname()[1])
    server = Server({"/": Application(FunctionHandler(make_document))}, port=port, address="127.0.0.1",
                    allow_websocket_origin=[f"127.0.0.1:{port}", f"localhost:{port}"], num_procs=1)
    server.start()
    url = f"http://127.0.0.1:{port}/"
    print(f"taylorball explore: serving {url} (Ctrl-C to stop)", flush=True)
    if warm:
        from .engine import View, warm_megno, warm_up

        # the page's first view: the Fig. 4a preset with the section gamma3 = 0 beside the paper's
        first = View(event="gamma3", chart=("R1", "R2"))
        threading.Thread(target=warm_up, args=(first,), daemon=True, name="taylorball-warm-up").start()
        # M||gamma (Fig. 1) as the page shows it, in a child process: its MEGNO in default mode
        # takes tens of seconds to compile on an empty cache
        warm_megno(View(preset="fig1", event="gamma3", chart=("K1", "K2")))
    if ready is not None:
        ready(port)
    if open_browser:
        server.io_loop.add_callback(server.show, "/")
    try:
        server.io_loop.start()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
