"""The editor's web server: one static page and a small JSON API over an :class:`~convsss.editor.EditSession` that a
:class:`~convsss.editor.loop.RenderLoop` renders, on the loopback interface only (the standard library's
``http.server``; no dependency).

    GET  /                the page (``static/index.html``, package data)
    GET  /api/state       the session's :meth:`~convsss.editor.EditSession.state` and the loop's ``max_spp`` (JSON)
    POST /api/update      a JSON object of changes (:data:`~convsss.editor.session.FIELDS`) -> the new state once the
                          edit's first pass is shown; a bad value -> 400 ``{"error": "..."}``, nothing changed
    GET  /image.png       the image (the mean of the passes so far), tone-mapped; ``?denoised=1``: denoised
    GET  /profile.png     ``r R_d(r)`` of the edited object's profile

Each connection has a thread of its own and :data:`TIMEOUT` seconds to send its request (an idle or short-bodied
client blocks nobody); those threads never render: edits are queued to the render loop's thread, reads return what
it last published. Only ``127.0.0.1``, ``::1`` and ``localhost`` may be bound,
and requests must name one of them in their ``Host`` header (a page elsewhere cannot reach the API through DNS
rebinding). An update must be ``application/json`` of at most :data:`MAX_BODY` bytes, and a browser's ``Origin``,
when sent, must be the editor's own page: a page elsewhere cannot drive it with a cross-origin "simple" POST.
"""

import http.server
import json
import re
import socketserver
from importlib import resources

from ..errors import ConvsssError

#: Hosts the server may bind and that requests may name.
LOOPBACK = ("127.0.0.1", "::1", "localhost")
#: A ``Host`` header: a name or IPv4 address, or an IPv6 address in brackets, then an optional port; nothing else.
HOST = re.compile(r"\[([0-9A-Fa-f:.]+)\](?::\d{1,5})?|([A-Za-z0-9.-]+)(?::\d{1,5})?")


def host_name(header):
    """The host a ``Host`` header names (an IPv6 address without its brackets), or None when the header is not one
    host and port (``127.0.0.1:80@evil.example`` is not).

    >>> host_name("[::1]:8123"), host_name("[::1]"), host_name("localhost"), host_name("127.0.0.1:80@evil.example")
    ('::1', '::1', 'localhost', None)
    """
    found = HOST.fullmatch(header.strip())
    return None if found is None else found.group(1) or found.group(2)


#: Seconds a connection may take to send its request.
TIMEOUT = 10.0
#: The largest update body, in bytes (an edit is a few hundred).
MAX_BODY = 1 << 16


def check_loopback(host):
    """``host`` if it is a loopback address, else a one-line error."""
    if host not in LOOPBACK:
        raise ConvsssError(f"the editor serves on the loopback interface only ({', '.join(LOOPBACK)}), not {host!r}: "
                           "it renders with this machine's files and has no authentication")
    return host


def page():
    """The editor's HTML page (bytes)."""
    return resources.files("convsss").joinpath("editor", "static", "index.html").read_bytes()


class EditorHandler(http.server.BaseHTTPRequestHandler):
    """Serves :attr:`server.loop` (a :class:`~convsss.editor.loop.RenderLoop` and its session)."""

    server_version = "convsss-edit"
    timeout = TIMEOUT

    def log_message(self, format, *args):  # quiet: the command prints the URL and errors only
        pass

    def _send(self, status, body, kind):
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def _json(self, status, value):
        self._send(status, json.dumps(value).encode(), "application/json")

    def _local(self):
        host = host_name(self.headers.get("Host") or "")
        if host not in LOOPBACK:
            self._json(403, {"error": f"requests must name a loopback host, not {host!r}"})
            return False
        return True

    def do_GET(self):
        if not self._local():
            return
        path = self.path.split("?", 1)[0]
        session = self.server.loop.session
        if path in ("/", "/index.html"):
            self._send(200, page(), "text/html; charset=utf-8")
        elif path == "/api/state":
            self._json(200, self.server.loop.state())
        elif path == "/image.png":
            denoised = "denoised=1" in self.path.split("?", 1)[-1].split("&")
            self._send(200, session.denoised_png() if denoised else session.image_png(), "image/png")
        elif path == "/profile.png":
            self._send(200, session.profile_png(), "image/png")
        else:
            self._json(404, {"error": f"no {path}"})

    def _same_origin(self):
        """A browser's ``Origin`` (sent with every cross-origin POST) must be this page's own: ``http://`` and the
        ``Host`` the request names. ``null`` (a sandboxed or file page) is another origin."""
        origin = self.headers.get("Origin")
        if origin is not None and origin != f"http://{self.headers.get('Host')}":
            self._json(403, {"error": f"updates come from the editor's own page, not from {origin!r}"})
            return False
        return True

    def _body(self):
        """The update's bytes, or None after a 4xx reply: ``application/json``, a valid length of at most
        :data:`MAX_BODY`."""
        kind = (self.headers.get("Content-Type") or "").split(";", 1)[0].strip().lower()
        if kind != "application/json":
            self._json(415, {"error": "an update is sent as Content-Type: application/json"})
            return None
        length = self.headers.get("Content-Length") or ""
        if not length.isdigit():
            self.close_connection = True
            self._json(411, {"error": "an update needs a Content-Length of its bytes"})
            return None
        if int(length) > MAX_BODY:
            self.close_connection = True
            self._json(413, {"error": f"an update is at most {MAX_BODY} bytes"})
            return None
        return self.rfile.read(int(length))

    def do_POST(self):
        if not (self._local() and self._same_origin()):
            return
        if self.path.split("?", 1)[0] != "/api/update":
            self._json(404, {"error": f"no {self.path}"})
            return
        try:
            body = self._body()
            if body is None:
                return
            try:
                changes = json.loads(body or b"{}")
            except RecursionError:  # nested deeper than Python's parser goes: no edit is
                raise ConvsssError("an update is a JSON object of changes, not nested thousands deep") from None
            if not isinstance(changes, dict):
                raise ConvsssError("an update is a JSON object of changes")
            self._json(200, self.server.loop.submit(changes))
        except TimeoutError:  # a body shorter than its Content-Length: drop the connection
            self.close_connection = True
        except (ConvsssError, ValueError, TypeError) as error:
            self._json(400, {"error": str(error)})
        except Exception as error:  # the session kept its state (an edit is applied whole or not at all)
            self._json(500, {"error": f"the edit failed and was undone: {type(error).__name__}: {error}"})


class EditorServer(socketserver.ThreadingMixIn, socketserver.TCPServer):
    """An HTTP server on a loopback address, a thread per connection, holding the render loop its handler serves
    (settable after the port is taken)."""

    allow_reuse_address = True
    daemon_threads = True

    def __init__(self, loop, host="127.0.0.1", port=0):
        import socket

        self.address_family = socket.AF_INET6 if ":" in check_loopback(host) else socket.AF_INET
        self.loop = loop
        try:
            super().__init__((host, int(port)), EditorHandler)
        except OSError as error:
            raise ConvsssError(f"cannot serve the editor on {host} port {port}: {error.strerror or error} (--port 0 "
                               "picks a free one)") from None

    @property
    def url(self):
        host, port = self.server_address[:2]
        return f"http://{'[' + host + ']' if ':' in host else host}:{port}/"
