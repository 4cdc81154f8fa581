"""The editor's HTTP API on 127.0.0.1 (convsss.editor.server), without a browser."""

import http.client
import json

import pytest

from convsss.editor.server import EditorServer, check_loopback
from convsss.errors import ConvsssError


def _request(server, method, path, body=None, host=None, raw=None):
    port = server.server_address[1]
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
    headers = {"Content-Type": "application/json"}
    if raw is not None:
        connection.request(method, path, raw, headers)
    elif host:
        connection.putrequest(method, path, skip_host=True)
        connection.putheader("Host", host)
        data = json.dumps(body).encode() if body is not None else b""
        connection.putheader("Content-Length", str(len(data)))
        connection.endheaders(data)
    else:
        connection.request(method, path, None if body is None else json.dumps(body), headers)
    response = connection.getresponse()
    return response.status, response.getheader("Content-Type"), response.read()


@pytest.mark.slow
def test_page_state_update_and_images(editor_server):
    assert editor_server.url.startswith("http://127.0.0.1:")
    status, kind, page = _request(editor_server, "GET", "/")
    assert status == 200 and kind.startswith("text/html") and b"/api/update" in page
    status, _, body = _request(editor_server, "GET", "/api/state")
    state = json.loads(body)
    assert status == 200 and state["eta_editable"] and len(state["presets"]) == 47
    status, kind, image = _request(editor_server, "GET", "/image.png")
    assert status == 200 and kind == "image/png" and image[:4] == b"\x89PNG"
    status, _, body = _request(editor_server, "POST", "/api/update", {"sigma_a": [0.2, 0.2, 0.2]})
    new = json.loads(body)
    assert status == 200 and new["version"] == state["version"] + 1 and new["last"]["rebuilt"] == "prepare"
    assert _request(editor_server, "GET", "/image.png")[2] != image
    assert _request(editor_server, "GET", "/profile.png")[2][:4] == b"\x89PNG"
    status, kind, denoised = _request(editor_server, "GET", f"/image.png?v={new['version']}&denoised=1")
    assert status == 200 and kind == "image/png" and denoised[:4] == b"\x89PNG"
    assert denoised != _request(editor_server, "GET", "/image.png")[2] or new["max_spp"] == 0


def test_bad_requests(editor_server):
    status, _, body = _request(editor_server, "POST", "/api/update", {"color": [2.0, 0.5, 0.5]})
    assert status == 400 and "not reachable" in json.loads(body)["error"]
    assert _request(editor_server, "POST", "/api/update", [1, 2])[0] == 400
    assert _request(editor_server, "GET", "/nothing")[0] == 404
    # DNS rebinding: a request that names another host is refused.
    assert _request(editor_server, "GET", "/api/state", host="evil.example:80")[0] == 403
    assert _request(editor_server, "GET", "/api/state", host="localhost:1")[0] == 200
    # A Host that is not one host and port (issue 51: accepted), and a bare IPv6 loopback (refused).
    assert _request(editor_server, "GET", "/api/state", host="127.0.0.1:80@evil.example")[0] == 403
    assert _request(editor_server, "GET", "/api/state", host="[::1]")[0] == 200
    # JSON nested deeper than the parser goes (issue 51: a 500 with Python's RecursionError): a 400 of one line.
    status, _, body = _request(editor_server, "POST", "/api/update", raw=b"[" * 5000 + b"]" * 5000)
    assert status == 400 and "nested" in json.loads(body)["error"]


@pytest.mark.parametrize("host", ["0.0.0.0", "", "192.168.1.2", "::"])
def test_only_loopback_addresses_may_be_bound(host):
    with pytest.raises(ConvsssError, match="loopback"):
        EditorServer(None, host, 0)
    assert check_loopback("127.0.0.1") == "127.0.0.1"


def _raw(server, method, path, headers, body=b""):
    """A request with exactly ``headers`` (no Content-Type added): (status, JSON body)."""
    connection = http.client.HTTPConnection("127.0.0.1", server.server_address[1], timeout=120)
    connection.putrequest(method, path)
    for name, value in headers.items():
        connection.putheader(name, value)
    connection.endheaders(body)
    response = connection.getresponse()
    return response.status, json.loads(response.read() or b"{}")


@pytest.mark.slow
def test_no_other_page_can_drive_the_editor(editor_server):
    """Issue 30, defect 4: a cross-origin "simple" POST (text/plain, no preflight) and an ``Origin`` other than the
    page's own (``null`` included) are refused, and the material is unchanged; the page's own origin works."""
    before = editor_server.loop.state()["material"]
    body = json.dumps({"sigma_a": [0.3, 0.3, 0.3]}).encode()
    length = {"Content-Length": str(len(body))}
    assert _raw(editor_server, "POST", "/api/update", {"Content-Type": "text/plain", **length}, body)[0] == 415
    for origin in ("http://evil.example", "null", "http://127.0.0.1:1"):
        status, reply = _raw(editor_server, "POST", "/api/update", {"Content-Type": "application/json",
                                                                     "Origin": origin, **length}, body)
        assert status == 403 and "own page" in reply["error"]
    assert editor_server.loop.state()["material"] == before
    own = f"http://127.0.0.1:{editor_server.server_address[1]}"
    status, reply = _raw(editor_server, "POST", "/api/update", {"Content-Type": "application/json", "Origin": own,
                                                                 **length}, body)
    assert status == 200 and reply["material"]["sigma_a"] == [0.3, 0.3, 0.3]


@pytest.mark.slow
def test_bad_lengths_and_idle_clients_block_nobody(editor_server):
    """Issue 30, defect 12: ``Content-Length: -1`` and a body over the limit are refused without reading it; an idle
    connection and a POST whose body never comes do not stop another client from being served (each connection
    has its own thread; the others time out)."""
    import socket

    from convsss.editor.server import MAX_BODY

    json_type = {"Content-Type": "application/json"}
    assert _raw(editor_server, "POST", "/api/update", {**json_type, "Content-Length": "-1"})[0] == 411
    assert _raw(editor_server, "POST", "/api/update", {**json_type, "Content-Length": str(MAX_BODY + 1)})[0] == 413
    address = ("127.0.0.1", editor_server.server_address[1])
    idle = socket.create_connection(address)
    short = socket.create_connection(address)
    short.sendall(b"POST /api/update HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                  b"Content-Length: 100\r\n\r\n{}")
    try:
        connection = http.client.HTTPConnection(*address, timeout=5)  # under the server's TIMEOUT of 10 s
        connection.request("GET", "/api/state")
        assert connection.getresponse().status == 200
    finally:
        idle.close()
        short.close()
