"""The dashboard's server answers only its own addresses (issue 28, scope 5): raw HTTP requests and WebSocket
handshakes to a real ``mocapviz serve`` process on 127.0.0.1, with the Host and Origin headers a browser would send.

A name that is not the dashboard's, reaching its port, is what DNS rebinding produces: a page of
``attacker.example:PORT`` whose name then resolves to 127.0.0.1 sends ``Host: attacker.example:PORT`` (and, for its
WebSocket, the same ``Origin``). Sending those headers to 127.0.0.1 directly is the same request.
"""

from __future__ import annotations

import base64
import hashlib
import os
import re
import socket
from urllib.parse import urlsplit

import pytest

WS_GUID = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11"  # RFC 6455: the key's accept value is sha1(key + this), base64
PATHS = ["/", "/static/js/bokeh.min.js"]  # a page (with its session token) and a static file


def _exchange(port: int, lines: list[str]) -> tuple[int, dict, str]:
    """Send one request (its request line and header lines) to 127.0.0.1:port; return the status, the headers (lower
    case names) and the body of the answer."""
    with socket.create_connection(("127.0.0.1", port), timeout=60) as s:
        s.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
        data = b""
        while b"\r\n\r\n" not in data and (chunk := s.recv(65536)):
            data += chunk
        head, _, body = data.partition(b"\r\n\r\n")
        status_line, *header_lines = head.decode("latin-1").split("\r\n")
        headers = {name.strip().lower(): value.strip() for name, value in (h.split(":", 1) for h in header_lines)}
        length = int(headers.get("content-length", 0))  # none after a 101: what follows is WebSocket frames
        while len(body) < length and (chunk := s.recv(65536)):
            body += chunk
    return int(status_line.split()[1]), headers, body[:length].decode()


def _get(port: int, path: str, host: str | None) -> tuple[int, dict, str]:
    """GET ``path`` with this Host header (None: none, as HTTP/1.0 allows)."""
    if host is None:
        return _exchange(port, [f"GET {path} HTTP/1.0"])
    return _exchange(port, [f"GET {path} HTTP/1.1", f"Host: {host}", "Connection: close"])


def _token(port: int) -> str:
    """The session token of a page just served to http://localhost:port/ (what its bokehjs sends with the
    WebSocket handshake)."""
    status, _, body = _get(port, "/", f"localhost:{port}")
    assert status == 200
    return re.search(r'"token":"([^"]+)"', body)[1]


def _handshake(port: int, host: str, origin: str | None) -> tuple[int, dict, str]:
    """The WebSocket handshake of a fresh session's page, as bokehjs opens it, with this Host and Origin (None:
    none). The answer: 101 and the key's accept value when the server opens the WebSocket."""
    key = base64.b64encode(os.urandom(16)).decode()
    lines = ["GET /ws HTTP/1.1", f"Host: {host}", "Upgrade: websocket", "Connection: Upgrade",
             f"Sec-WebSocket-Key: {key}", "Sec-WebSocket-Version: 13",
             f"Sec-WebSocket-Protocol: bokeh, {_token(port)}"]  # fmt: skip
    if origin is not None:
        lines.append(f"Origin: {origin}")
    status, headers, body = _exchange(port, lines)
    if status == 101:
        accept = base64.b64encode(hashlib.sha1((key + WS_GUID).encode()).digest()).decode()
        assert headers["sec-websocket-accept"] == accept
    return status, headers, body


def _refused(answer: tuple[int, dict, str], header: str) -> None:
    status, headers, body = answer
    assert status == 403, (status, body[:200])
    assert headers["content-type"].startswith("text/plain")
    assert header in body and "is not an address of this dashboard" in body and "token" not in body


@pytest.fixture(scope="module")
def port(sample_dashboard) -> int:
    """The port of ``mocapviz serve`` over the sample on 127.0.0.1 (no --allow-origin)."""
    return urlsplit(sample_dashboard).port


@pytest.mark.parametrize("name", ["127.0.0.1", "localhost", "LocalHost", "[::1]"])
@pytest.mark.parametrize("path", PATHS)
def test_the_loopback_names_at_the_port_get_pages_and_files(port, name, path):
    status, _, body = _get(port, path, f"{name}:{port}")
    assert status == 200
    assert ('"token":"' in body) == (path == "/")


@pytest.mark.parametrize("name", ["evil.example.com:{port}", "attacker.example:{port}", "localhost:{other}",
                                  "localhost", "127.0.0.2:{port}", "myhost:{port}"])  # fmt: skip
@pytest.mark.parametrize("path", [*PATHS, "/ws"])
def test_any_other_host_gets_a_403_on_every_path(port, name, path):
    host = name.format(port=port, other=port + 1)
    _refused(_get(port, path, host), f"Host {host!r}")


def test_a_request_without_host_gets_a_403(port):
    _refused(_get(port, "/", None), "Host ''")


@pytest.mark.parametrize("host, origin", [("localhost:{port}", "http://localhost:{port}"),
                                          ("127.0.0.1:{port}", "http://127.0.0.1:{port}"),
                                          ("127.0.0.1:{port}", "http://localhost:{port}")])  # fmt: skip
def test_a_page_of_a_loopback_name_opens_the_websocket(port, host, origin):
    status, headers, _ = _handshake(port, host.format(port=port), origin.format(port=port))
    assert status == 101 and headers["upgrade"].lower() == "websocket"


@pytest.mark.parametrize("name", ["evil.example.com:{port}", "attacker.example:{port}"])
def test_a_websocket_whose_origin_equals_a_foreign_host_is_refused(port, name):
    """Tornado opens a WebSocket whose Origin equals its Host before Bokeh's list is consulted: DNS rebinding."""
    host = name.format(port=port)
    _refused(_handshake(port, host, f"http://{host}"), f"Host {host!r}")


@pytest.mark.parametrize("origin", ["http://evil.example.com:{port}", "http://localhost:{other}", "null"])
def test_a_websocket_from_a_page_of_another_origin_is_refused(port, origin):
    origin = origin.format(port=port, other=port + 1)
    _refused(_handshake(port, f"localhost:{port}", origin), f"WebSocket Origin {origin!r}")


def test_a_websocket_without_origin_is_refused(port):
    """Browsers send Origin with every WebSocket; a handshake without one is refused rather than trusted (tornado
    would open it)."""
    status, headers, body = _handshake(port, f"localhost:{port}", None)
    assert status == 403 and headers["content-type"].startswith("text/plain")
    assert "without an Origin header" in body and "token" not in body


def test_allow_origin_adds_an_address_and_only_it(sample_db, serve_dashboard):
    url = serve_dashboard(sample_db.path, "--allow-origin", "myhost:{port}")
    port = urlsplit(url).port
    status, _, body = _get(port, "/", f"myhost:{port}")
    assert status == 200 and '"token":"' in body
    assert _handshake(port, f"myhost:{port}", f"http://myhost:{port}")[0] == 101
    assert _handshake(port, f"localhost:{port}", f"http://myhost:{port}")[0] == 101  # a page of myhost, by name
    _refused(_get(port, "/", f"myhost:{port + 1}"), f"Host 'myhost:{port + 1}'")
    _refused(_handshake(port, f"evil.example.com:{port}", f"http://evil.example.com:{port}"), "Host")
    _refused(_handshake(port, f"myhost:{port}", f"http://evil.example.com:{port}"), "WebSocket Origin")
