"""The editor's HTTP API on 127.0.0.1 (convsss.editor.server), without a browser."""

import http.client
import json

import pytest

from convsss.editor.server import EditorServer, check_loopback
from convsss.errors import ConvsssError


def _request(server, method, path, body=None, host=None):
    port = server.server_address[1]
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
    headers = {"Content-Type": "application/json"}
    if host:
        connection.putrequest(method, path, skip_host=True)
        connection.putheader("Host", host)
        data = json.dumps(body).encode() if body is not None else b""
        connection.putheader("Content-Length", str(len(data)))
        connection.endheaders(data)
    else:
        connection.request(method, path, None if body is None else json.dumps(body), headers)
    response = connection.getresponse()
    return response.status, response.getheader("Content-Type"), response.read()


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


def test_bad_requests(editor_server):
    status, _, body = _request(editor_server, "POST", "/api/update", {"color": [2.0, 0.5, 0.5]})
    assert status == 400 and "not reachable" in json.loads(body)["error"]
    assert _request(editor_server, "POST", "/api/update", [1, 2])[0] == 400
    assert _request(editor_server, "GET", "/nothing")[0] == 404
    # DNS rebinding: a request that names another host is refused.
    assert _request(editor_server, "GET", "/api/state", host="evil.example:80")[0] == 403
    assert _request(editor_server, "GET", "/api/state", host="localhost:1")[0] == 200


@pytest.mark.parametrize("host", ["0.0.0.0", "", "192.168.1.2", "::"])
def test_only_loopback_addresses_may_be_bound(host):
    with pytest.raises(ConvsssError, match="loopback"):
        EditorServer(None, host, 0)
    assert check_loopback("127.0.0.1") == "127.0.0.1"
