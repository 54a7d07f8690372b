"""The interactive explorer: the parameter space in a browser (``cosserat-channel explore``).

A local web app: inputs for ``eps`` (or the channel's half-width ``W`` with ``d_p``), ``L``,
``K``, ``A`` and ``N`` (or the wall friction angle ``delta_w`` with ``phi``), the material and the
tolerance, typed or on sliders; the point's status, profiles, outputs and their sensitivities
(:func:`cosserat_channel.solve_point`); the solvability map of the ``(A, N)`` plane at its
``eps L`` from the shipped atlas (:func:`cosserat_channel.atlas.classify`), clickable; one
output against one parameter (:func:`cosserat_channel.solve`); and a button that writes the
view as a sweep file and figures. In a notebook, :func:`explore` shows the same page.

Modules: :mod:`.answers` (the page's questions answered by the library's public functions, as
JSON-ready dicts), :mod:`.server` (the HTTP server, its background jobs), ``static/`` (the page:
HTML, CSS and a script that draws the plots in the browser) and :mod:`.chromium` (headless
Chromium for the browser test and the benchmark). Standard library only beyond the
package's own dependencies; the ``explore`` extra installs nothing more (README says why).

Layer: the top, beside the command line: calls the public API, the atlas's reading functions
and the figures; nothing below imports it.
"""

from __future__ import annotations

import os
import sys
import threading

__all__ = ["explore", "serve"]


def explore(port: int = 0, directory: str = ".", height: int = 980):
    """Start the explorer on a background thread and return it; in a notebook it shows the page.

    Parameters
    ----------
    port : int
        Port on 127.0.0.1 (0: a free one).
    directory : str
        Where the page's export button writes its files (none is ever replaced).
    height : int
        Height in pixels of the page in a notebook cell.

    Returns
    -------
    server.Running
        ``.url`` is the address, ``.stop()`` ends it; a notebook displays it as the page.
    """
    from .server import Running

    return Running(port, directory, height)


def serve(port: int = 0, directory: str = ".", open_browser: bool = True, stream=None) -> None:
    """Serve the explorer until interrupted (Ctrl-C): prints the address, opens a browser tab.

    Raises KeyboardInterrupt when stopped, after the port is freed.
    """
    from .server import make_server, url_of

    stream = stream or sys.stdout
    httpd, explorer = make_server(port, directory)
    url = url_of(httpd)
    print(f"cosserat-channel explorer: {url}  (Ctrl-C stops it)", file=stream, flush=True)
    if open_browser and sys.platform.startswith("linux") and not (
            os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        print("no display here: open the address in a browser (through an SSH tunnel, e.g. "
              f"ssh -L {httpd.server_address[1]}:127.0.0.1:{httpd.server_address[1]} HOST)",
              file=stream, flush=True)
    elif open_browser:
        import webbrowser

        threading.Thread(target=webbrowser.open, args=(url,), daemon=True).start()
    try:
        httpd.serve_forever()
    finally:
        httpd.server_close()
        explorer.close()
