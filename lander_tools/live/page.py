"""The student page's HTTP server: the static files of ``lander_tools/live/web/`` on localhost.

Only those files are served (no directory listing, nothing outside the folder), plus
``/config.json`` telling the page how to get its data (``{"mode": "live", "ws_port": P}``: the
Foxglove WebSocket port; ``{"mode": "replay"}``: a recorded flight) and the JSON routes its owner
gives (``/history.json``: the flight's graph fields from t = 0; ``/replay.json``: a bag's states).
The page fetches nothing from the internet: its JavaScript speaks the ``foxglove.sdk.v1``
protocol itself (``web/foxglove.js``) and its 3-D view is three.js, shipped in ``web/``
(``three.module.min.js``, ``OrbitControls.js``; MIT licence in ``web/three.LICENSE``).
"""
from __future__ import annotations

import json
import threading
from collections.abc import Callable, Mapping
from functools import partial
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

WEB_DIR = Path(__file__).resolve().parent / "web"
_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
          ".css": "text/css; charset=utf-8", ".json": "application/json", ".png": "image/png"}


class _Handler(BaseHTTPRequestHandler):
    def __init__(self, *args: object, config: dict[str, Any], routes: Mapping[str, Callable[[], bytes]],
                 **kwargs: object) -> None:
        self.config = config
        self.routes = routes
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]  # passed through as the server gave them

    def do_GET(self) -> None:
        path = self.path.split("?", 1)[0]
        if path == "/config.json":
            return self._send(200, json.dumps(self.config).encode(), _TYPES[".json"])
        if path in self.routes:
            return self._send(200, self.routes[path](), _TYPES[".json"])
        name = "index.html" if path in ("", "/") else path.lstrip("/")
        files = {p.name: p for p in WEB_DIR.iterdir() if p.is_file()}
        if name not in files:  # flat folder: no path ever leaves it
            return self._send(404, f"not found: {path}\n".encode(), "text/plain")
        f = files[name]
        self._send(200, f.read_bytes(), _TYPES.get(f.suffix, "application/octet-stream"))

    def _send(self, code: int, body: bytes, ctype: str) -> None:
        self.send_response(code)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, format: str, *args: object) -> None:
        pass  # quiet: the flight's output is the console's


class PageServer:
    """Serves the page on ``host:port`` (0: a free port, see :attr:`port`) in a daemon thread.

    ``ws_port``: the Foxglove server of a live flight; None: a replay (``routes`` has
    ``/replay.json``). ``routes``: path -> a function giving that path's JSON body.
    """

    def __init__(self, host: str, port: int, ws_port: int | None,
                 routes: Mapping[str, Callable[[], bytes]] | None = None) -> None:
        config: dict[str, Any] = {"mode": "replay"} if ws_port is None else {"mode": "live", "ws_port": ws_port}
        self.httpd = ThreadingHTTPServer((host, port), partial(_Handler, config=config, routes=dict(routes or {})))
        self.httpd.daemon_threads = True
        self.port = int(self.httpd.server_address[1])
        self._thread = threading.Thread(target=self.httpd.serve_forever, kwargs={"poll_interval": 0.05}, name="live-page", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
