"""``mocapviz serve DB --auth FILE`` (issue 40 item 5): a real server process over the sample database with a users
file and a cookie secret file; raw HTTP requests without and with the sign-in cookie, then headless Chromium through
the login page.

What a visitor not signed in gets, for every kind of request (the page, Bokeh's and Panel's static files, the
WebSocket handshake, a POST): a redirect to /login or a 403, never a page with a session token. A cookie is accepted
only when signed with the server's secret and naming a user the file still holds, and while the file can be read.
~11 s of tests after the server's start (15-21 s on the loaded 2 cores: the sample ingested, if no other test did,
then warmed up).
"""
from __future__ import annotations

import base64
import http.client
import os
import re
from urllib.parse import urlencode, urlsplit

import pytest
from tornado.web import create_signed_value

from mocapviz import users

USERS = {"alice": ("alice's passphrase", "annotate"), "bob": ("bob's passphrase", "read"),
         "carol": ("carol's passphrase", "admin")}  # fmt: skip
SECRET = "a test cookie secret of this server, 52 characters.."
STATIC = ["/static/js/bokeh.min.js", "/static/extensions/panel/panel.min.js"]


@pytest.fixture(scope="module")
def server(tmp_path_factory, sample_db, serve_dashboard):
    """(port, users file, log file) of the sample dashboard served with --auth and --cookie-secret-file."""
    folder = tmp_path_factory.mktemp("auth")
    path = folder / "users.json"
    for name, (password, role) in USERS.items():
        users.add_user(path, name, password, role)
    (folder / "secret").write_text(SECRET + "\n")
    url = serve_dashboard(sample_db.path, "--auth", str(path), "--cookie-secret-file", str(folder / "secret"))
    return urlsplit(url).port, path, serve_dashboard.log_of(url)


def _request(port: int, method: str, path: str, cookie: str | None = None, body: dict | None = None,
             headers: dict | None = None) -> tuple[int, http.client.HTTPMessage, str]:
    """One request to 127.0.0.1:port (its Host header one of the server's); the status, headers and body."""
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    sent = dict(headers or {})
    if cookie is not None:
        sent["Cookie"] = cookie
    if body is not None:
        sent["Content-Type"] = "application/x-www-form-urlencoded"
    conn.request(method, path, body=None if body is None else urlencode(body), headers=sent)
    answer = conn.getresponse()
    text = "" if answer.status == 101 else answer.read().decode("utf-8", "replace")
    conn.close()
    return answer.status, answer.headers, text


def _handshake(port: int, cookie: str | None, token: str = "no-token") -> int:
    """The status of a WebSocket handshake at /ws as bokehjs opens it (101: opened)."""
    key = base64.b64encode(os.urandom(16)).decode()
    return _request(port, "GET", "/ws", cookie, headers={
        "Upgrade": "websocket", "Connection": "Upgrade", "Sec-WebSocket-Key": key, "Sec-WebSocket-Version": "13",
        "Sec-WebSocket-Protocol": f"bokeh, {token}", "Origin": f"http://127.0.0.1:{port}"})[0]  # fmt: skip


def _sign_in(port: int, name: str, password: str) -> tuple[int, str, str | None]:
    """POST the login form: the status, the redirect and the ``user`` cookie set (``user=VALUE``), if any."""
    status, headers, _ = _request(port, "POST", "/login", body={"username": name, "password": password})
    cookies = [c.split(";")[0] for c in headers.get_all("Set-Cookie") or [] if c.startswith("user=")]
    return status, headers.get("Location", ""), cookies[0] if cookies else None


def _refused(answer) -> None:
    status, headers, body = answer
    assert status in (302, 403), (status, body[:200])
    if status == 302:
        assert headers["Location"].startswith("/login")
    assert "token" not in body and "bokeh" not in body.lower()


def test_signed_out_requests_get_no_session(server):
    port, _, log = server
    status, headers, _ = _request(port, "GET", "/")
    assert status == 302 and headers["Location"] == "/login?next=%2F"
    for path in STATIC:
        _refused(_request(port, "GET", path))
    _refused(_request(port, "POST", "/", body={"x": "1"}))
    assert _handshake(port, None) == 403
    forged = create_signed_value("another server's secret, long enough....", "user", "alice").decode()
    unknown = create_signed_value(SECRET, "user", "mallory").decode()  # the right secret, no such user
    for cookie in (f'user="{forged}"', f'user="{unknown}"', "user=alice"):
        _refused(_request(port, "GET", "/", cookie))
        _refused(_request(port, "GET", STATIC[0], cookie))
        assert _handshake(port, cookie) == 403
    status, _, page = _request(port, "GET", "/login")
    assert status == 200 and 'name="password"' in page and 'type="password"' in page
    assert SECRET not in log.read_text()


def test_sign_in_then_removed(server):
    port, path, log = server
    status, location, cookie = _sign_in(port, "carol", "bob's passphrase")  # another user's password
    assert (status, location, cookie) == (302, "/login?error=1", None)
    status, location, cookie = _sign_in(port, "carol", USERS["carol"][0])
    assert (status, location) == (302, "/") and cookie is not None
    status, _, page = _request(port, "GET", "/", cookie)
    assert status == 200
    token = re.search(r'"token":"([^"]+)"', page)[1]
    for static in STATIC:
        assert _request(port, "GET", static, cookie)[0] == 200
    assert _handshake(port, cookie, token) == 101
    content = path.read_bytes()
    path.write_text("{damaged")  # a users file that cannot be read signs everybody out, until it is put back
    _refused(_request(port, "GET", "/", cookie))
    path.write_bytes(content)
    assert _request(port, "GET", "/", cookie)[0] == 200
    users.remove_user(path, "carol")  # her cookie is signed and unexpired, but she is no user any more
    _refused(_request(port, "GET", "/", cookie))
    assert _handshake(port, cookie, token) == 403
    text = log.read_text()
    assert "sign-in refused: user 'carol'" in text and "signed in: carol (admin)" in text
    assert f"users file unusable, nobody is signed in: {path}: not a users file (not JSON" in text
    assert USERS["carol"][0] not in text and "bob's passphrase" not in text


def test_serve_refuses_bad_auth_options_before_serving(sample_db, tmp_path, capsys):
    from mocapviz.cli import main

    assert main(["serve", str(sample_db.path), "--auth", str(tmp_path / "missing.json")]) == 1
    assert "missing.json: no such users file" in capsys.readouterr().err
    assert main(["serve", str(sample_db.path), "--cookie-secret-file", str(tmp_path / "secret")]) == 1
    assert "give --auth FILE too" in capsys.readouterr().err
    one, empty = tmp_path / "one.json", tmp_path / "empty.json"
    for path in (one, empty):
        users.add_user(path, "alice", USERS["alice"][0], "read")
    users.remove_user(empty, "alice")
    (tmp_path / "short").write_text("too short\n")
    for options, says in ((["--auth", str(empty)], "holds no users"),
                          (["--auth", str(one), "--cookie-secret-file", str(tmp_path / "short")],
                           "a cookie secret needs at least 32 characters, this one has 9")):
        assert main(["serve", str(sample_db.path), *options]) == 1
        assert says in capsys.readouterr().err


def test_without_auth_a_session_may_do_everything():
    from mocapviz.app.auth import SessionUser, can, session_user

    assert session_user() == SessionUser(None, "admin")
    assert all(can(None, action) for action in ("search", "download", "annotate", "add takes"))
    assert [can(SessionUser("bob", "read"), a) for a in ("search", "annotate")] == [True, False]
    assert not can(SessionUser("gone", None), "search")  # a user removed from the file since


def test_browser_login_and_logout(server, page):
    from playwright.sync_api import expect

    port = server[0]
    page.goto(f"http://127.0.0.1:{port}/")
    assert urlsplit(page.url).path == "/login"
    page.fill("#username", "alice")
    page.fill("#password", "not alice's passphrase")
    page.click("#sign-in")
    expect(page.locator("#error")).to_have_text("Wrong user name or password.")
    page.fill("#username", "alice")
    page.fill("#password", USERS["alice"][0])
    page.click("#sign-in")
    header = page.locator(".mv-header")
    expect(header).to_contain_text("signed in as alice (annotate)")
    expect(page.locator(".mv-tabs")).to_be_visible()
    header.get_by_text("sign out").click()
    expect(page.locator("h1")).to_have_text("Signed out")
    page.goto(f"http://127.0.0.1:{port}/")
    assert urlsplit(page.url).path == "/login"
