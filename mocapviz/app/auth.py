"""Named users on the served dashboard (``mocapviz serve DB --auth FILE``; docs/dashboard.md, "Users and login").

:class:`Login` is one server's sign-in: the users file (:mod:`mocapviz.users`) and the secret its cookies are signed
with. Its :meth:`Login.options` give ``pn.serve`` Panel's authentication hooks (a Panel ``BasicAuthProvider`` whose
login page checks the name and password against the users file's scrypt hashes, off the event loop, and whose
``get_user`` accepts a signed cookie only for a user the file still holds); its :meth:`Login.rule` is a rule for the
front of the tornado router (after the host check) that answers every request without such a cookie, whatever its
path (pages, Bokeh's and Panel's static files, the WebSocket), with a redirect to the login page (``/``) or a 403,
except the login and logout pages themselves, which need nothing from the server's static files.

A session knows its user: :func:`session_user` (name and role, read from the users file when asked, so a new role
holds from the next question on), :func:`can` (whether it may ``"search"``, ``"download"``, ``"annotate"``,
``"add takes"``). Without ``--auth`` every session may do everything, as before users existed.
"""
from __future__ import annotations

import asyncio
import logging
import os
from pathlib import Path
from typing import NamedTuple
from urllib.parse import quote

import jinja2
import panel as pn
from panel.auth import BasicAuthProvider, BasicLoginHandler, LogoutHandler
from panel.config import config
from tornado.routing import Matcher, Rule
from tornado.web import RequestHandler, decode_signed_value

from .. import users
from ..errors import UsersFileError

LOG = logging.getLogger("mocapviz.app")
LOGIN, LOGOUT = "/login", "/logout"
COOKIE = "user"  # Panel's signed cookie of the user's name (pn.state.user reads it)
_SERVING: dict = {}  # "login": the Login of this process's server, when it has one


class SessionUser(NamedTuple):
    """Who a browser session is: ``name`` (None without ``--auth``) and ``role`` (one of
    :data:`mocapviz.users.ROLES`; ``"admin"`` without ``--auth``; None for a user removed since signing in)."""

    name: str | None
    role: str | None


def session_user() -> SessionUser:
    """The user of the current browser session (``pn.state.user``) and their role in the users file now."""
    login = _SERVING.get("login")
    if login is None:
        return SessionUser(None, "admin")
    name = pn.state.user
    return SessionUser(name, login.role_of(name))


def can(user: SessionUser | None, action: str) -> bool:
    """Whether ``user`` (None: the current session's, :func:`session_user`) may do ``action``: a role's name or one
    of :data:`mocapviz.users.ACTIONS` (``"search"``, ``"download"``, ``"annotate"``, ``"add takes"``)."""
    return users.allows((user or session_user()).role, action)


def signed_in_line() -> str:
    """The header's line naming the session's user, role and the way out (Markdown); empty without ``--auth``."""
    user = session_user()
    if user.name is None:
        return ""
    return f"\n\nsigned in as `{user.name}` ({user.role}) · [sign out]({LOGOUT})"


class Login:
    """The sign-in of one server: its users file and cookie secret.

    Parameters
    ----------
    path : str or os.PathLike
        The users file (``mocapviz users FILE add ...``).
    secret_file : str or os.PathLike, optional
        A file holding the cookie secret (:func:`mocapviz.users.cookie_secret`: else the environment's, else a new
        one for this start).

    Raises
    ------
    UsersFileError
        ``path`` is not a users file, or holds no users.
    ParameterError
        The cookie secret given is too short or cannot be read.
    """

    def __init__(self, path: str | os.PathLike, secret_file: str | os.PathLike | None = None):
        self.path = Path(path)
        self._stat, self._roles = None, {}
        if not self.roles():
            raise UsersFileError(f"{self.path}: holds no users (`mocapviz users {self.path} add NAME --role admin` "
                                 f"adds one)")  # fmt: skip
        self.secret = users.cookie_secret(secret_file)

    def roles(self) -> dict[str, str]:
        """User name -> role, as the users file holds them now (read again when it changed; raises when it is damaged
        or gone)."""
        st = os.stat(self.path)
        key = (st.st_ino, st.st_mtime_ns, st.st_size)
        if key != self._stat:
            self._roles, self._stat = users.roles(self.path), key
        return self._roles

    def role_of(self, name: str | None) -> str | None:
        """The role of the user ``name`` in the users file now; None for a name it does not hold, and when the file
        cannot be read (logged: nobody is signed in then)."""
        try:
            return None if name is None else self.roles().get(name)
        except (OSError, UsersFileError) as exc:
            LOG.error("users file unusable, nobody is signed in: %s", exc)
            return None

    def known(self, name: str | None) -> bool:
        """Whether ``name`` is a user of the users file now (:meth:`role_of`)."""
        return self.role_of(name) is not None

    def signed_in(self, cookie: str | None) -> str | None:
        """The user whose name ``cookie`` (the ``user`` cookie's value) carries, signed with this server's secret
        and not expired, when the users file still holds them; else None."""
        if not cookie:
            return None
        name = decode_signed_value(self.secret, COOKIE, cookie, max_age_days=config.oauth_expiry)
        name = None if name is None else name.decode("utf-8", "replace")
        return name if self.known(name) else None

    def options(self) -> dict:
        """``pn.serve``'s keyword arguments for this sign-in (``auth_provider``, ``cookie_secret``); makes it the one
        :func:`session_user` consults."""
        _SERVING["login"] = self
        return {"auth_provider": _Provider(self), "cookie_secret": self.secret}

    def rule(self) -> Rule:
        """The router rule that answers every request of a visitor not signed in (:class:`_SignIn`)."""
        return Rule(_SignedOut(self), _SignIn)


class _SignedOut(Matcher):
    """Matches a request without a valid sign-in cookie, other than for the login and logout pages and the icon."""

    def __init__(self, login: Login):
        self.login = login

    def match(self, request):
        if request.path in (LOGIN, LOGOUT, "/favicon.ico"):  # (Bokeh's icon: a browser asks for it on any page)
            return None
        morsel = request.cookies.get(COOKIE)
        return None if self.login.signed_in(morsel and morsel.value) else {}


class _SignIn(RequestHandler):
    """The dashboard's page: a redirect to the login page; anything else (a static file, the WebSocket, a POST): 403
    and one line of text."""

    def prepare(self) -> None:
        page = self.request.path == "/" and self.request.method in ("GET", "HEAD")
        if page and self.request.headers.get("Upgrade", "").lower() != "websocket":
            self.redirect(f"{LOGIN}?next={quote('/', safe='')}")
            return
        LOG.info("refused %s %s: not signed in", self.request.method, self.request.path)
        self.set_status(403)
        self.set_header("Content-Type", "text/plain; charset=utf-8")
        self.finish(f"not signed in: sign in at {LOGIN}\n")


class _LoginHandler(BasicLoginHandler):
    """Panel's login page and form, the password checked against the users file (in a thread: a scrypt hash takes
    0.2 s, and the server answers other sessions meanwhile)."""

    login: Login  # set on the subclass each server makes

    async def post(self) -> None:
        name, password = self.get_argument("username", ""), self.get_argument("password", "")
        role = await asyncio.get_running_loop().run_in_executor(None, self._role, name, password)
        if role is None:
            LOG.warning("sign-in refused: user %r from %s", name[:64], self.request.remote_ip)
            self.redirect(f"{LOGIN}?error=1")
            return
        LOG.info("signed in: %s (%s) from %s", name, role, self.request.remote_ip)
        self.set_current_user(name)
        self.redirect("/")

    def _role(self, name: str, password: str) -> str | None:
        try:
            return users.check_password(self.login.path, name, password)
        except (OSError, UsersFileError) as exc:
            LOG.error("sign-in of %r refused, the users file is unusable: %s", name[:64], exc)
            return None


class _Provider(BasicAuthProvider):
    """Panel's basic authentication with :class:`_LoginHandler`, pages of their own (no static file needed) and a
    user the users file no longer holds signed out."""

    def __init__(self, login: Login):
        self.sign_in = login  # before Bokeh's checks of the handlers, which __init__ runs
        super().__init__(login_endpoint=LOGIN, logout_endpoint=LOGOUT)
        self._login_template = _TEMPLATES.from_string(LOGIN_PAGE)
        self._logout_template = _TEMPLATES.from_string(LOGOUT_PAGE)

    @property
    def get_user(self):
        panel_user = super().get_user

        def get_user(handler: RequestHandler) -> str | None:
            name = panel_user(handler)
            return name if self.sign_in.known(name) else None

        return get_user

    @property
    def login_handler(self):
        return type("LoginHandler", (_LoginHandler,), {"login": self.sign_in, "_login_endpoint": LOGIN,
                                                        "_login_template": self._login_template})  # fmt: skip

    @property
    def logout_handler(self):
        return type("LogoutHandler", (LogoutHandler,), {"_login_endpoint": LOGIN,
                                                         "_logout_template": self._logout_template})  # fmt: skip


_TEMPLATES = jinja2.Environment(autoescape=True)
_STYLE = """<style>
body{font-family:system-ui,sans-serif;background:#fafafa;display:flex;align-items:center;justify-content:center;
height:100vh;margin:0}
form,div.box{background:#fff;border:1px solid #ddd;padding:2em;width:320px}
h1{font-size:1.3em;margin:0 0 1em}label{display:block;margin:.8em 0 .2em}
input{width:100%;box-sizing:border-box;padding:.5em}button{margin-top:1.2em;width:100%;padding:.6em}
p.error{color:#b00020}
</style>"""
LOGIN_PAGE = """<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>mocapviz · sign in</title>
""" + _STYLE + """</head><body>
<form action="{{ login_endpoint }}" method="post">
<h1>mocapviz · sign in</h1>
{% if errormessage %}<p class="error" id="error">Wrong user name or password.</p>{% endif %}
<label for="username">User name</label><input id="username" name="username" autocomplete="username" required autofocus>
<label for="password">Password</label>
<input id="password" name="password" type="password" autocomplete="current-password" required>
<button type="submit" id="sign-in">Sign in</button>
</form></body></html>
"""
LOGOUT_PAGE = """<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>mocapviz · signed out</title>
""" + _STYLE + """</head><body><div class="box"><h1>Signed out</h1>
<p><a href="{{ LOGIN_ENDPOINT }}">Sign in again</a></p></div></body></html>
"""
