"""Named users of a served dashboard (``mocapviz serve DB --auth FILE``): a users file of names, roles and salted
password hashes, kept by ``mocapviz users FILE add|list|remove|role|password`` (docs/dashboard.md, "Users and
login").

The file is JSON with the header of every stored format (:func:`mocapviz.store.stamp`: ``format`` =
``mocapviz.users``, ``version`` = 1) and ``users``: ``{name: {"role", "kdf", "n", "r", "p", "salt", "hash"}}``.
A password is never stored: its scrypt hash (:func:`hashlib.scrypt`, the cost :data:`SCRYPT` kept with each user
so that a later cost can be told apart) over a random 16-byte salt of its own. Every change re-reads the file and
replaces it atomically (:func:`mocapviz.store.atomic_file`) under the file's own lock (``.<name>.lock`` beside it,
:func:`mocapviz.store.locked`), so that concurrent ``users add`` commands all land; the file is made mode 0600
(owner only) before anything is written to it.

A **role** says what a user may do: ``read`` (search, download), ``annotate`` (also label segments), ``admin``
(also add takes). Each includes the ones before it (:func:`allows`).
"""
from __future__ import annotations

import hashlib
import hmac
import json
import os
import re
import secrets
from pathlib import Path

from . import store
from .errors import MotionDBError, ParameterError, UnknownKeyError, UsersFileError
from .validation import one_of

FORMAT, VERSION = "mocapviz.users", 1
ROLES = ("read", "annotate", "admin")
"""The roles, each allowed what the ones before it are."""
ACTIONS = {"search": "read", "download": "read", "annotate": "annotate", "add takes": "admin"}
"""What a page may ask :func:`allows` besides a role's name, and the least role that may do it."""
SCRYPT = {"n": 2**14, "r": 8, "p": 5}
"""scrypt's cost: 16 MiB of memory and 0.19 s per hash on one core (measured with ``hashlib.scrypt``), one of
OWASP's equivalent settings for password storage (N = 2^14, r = 8, p = 5)."""
SALT_BYTES, HASH_BYTES = 16, 32
PASSWORD_LENGTH = (8, 1024)
"""A password's least and most characters."""
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._@-]{0,63}")
"""A user name: a letter or digit, then up to 63 letters, digits or ``. _ @ -`` (it is a label's author too)."""
COOKIE_SECRET_ENV = "MOCAPVIZ_COOKIE_SECRET"
"""The environment variable that may hold the secret the server signs its login cookies with."""
COOKIE_SECRET_LENGTH = 32
"""A cookie secret's least characters."""


def read_users(path: str | os.PathLike) -> dict[str, dict]:
    """The users of the users file ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        The users file.

    Returns
    -------
    dict
        User name -> ``{"role", "kdf", "n", "r", "p", "salt", "hash"}``, by name.

    Raises
    ------
    UsersFileError
        The file is missing or unreadable, not JSON, not a mocapviz users file of this version, or a record is not a
        user's (an unknown role, no hash); the message names the file.
    """
    path = Path(path)
    try:
        header = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UsersFileError(f"{path}: no such users file (`mocapviz users {path} add NAME --role ROLE` creates "
                             f"it)") from None  # fmt: skip
    except OSError as exc:
        raise UsersFileError(f"{path}: cannot read the users file ({exc.strerror})") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise UsersFileError(f"{path}: not a users file (not JSON: {exc})") from None
    try:
        store.check_format(header, FORMAT, VERSION, path)
    except MotionDBError as exc:
        raise UsersFileError(str(exc)) from None
    users = header.get("users")
    if not isinstance(users, dict) or not all(_is_user(name, record) for name, record in users.items()):
        raise UsersFileError(f"{path}: a damaged users file (its 'users' must map user names to a role and a scrypt "
                             f"hash)")  # fmt: skip
    return dict(sorted(users.items()))


def _is_user(name, record) -> bool:
    return (isinstance(name, str) and NAME.fullmatch(name) is not None and isinstance(record, dict)
            and record.get("role") in ROLES and record.get("kdf") == "scrypt"
            and all(isinstance(record.get(k), int) and record[k] > 0 for k in SCRYPT)
            and all(isinstance(record.get(k), str) and re.fullmatch(r"[0-9a-f]+", record[k]) for k in ("salt", "hash")))


def roles(path: str | os.PathLike) -> dict[str, str]:
    """User name -> role of the users file ``path``, by name (never a hash; :func:`read_users` raises)."""
    return {name: record["role"] for name, record in read_users(path).items()}


def add_user(path: str | os.PathLike, name: str, password: str, role: str) -> None:
    """Add a user to the users file ``path`` (created, mode 0600, when missing).

    Parameters
    ----------
    path : str or os.PathLike
        The users file; its folder must exist.
    name : str
        The new user's name (:data:`NAME`).
    password : str
        Its password (:data:`PASSWORD_LENGTH`); only its salted hash is stored.
    role : str
        One of :data:`ROLES`.

    Raises
    ------
    ParameterError
        A malformed name or role, a password too short or too long, or a name the file holds already.
    UsersFileError
        The file exists but is not a users file.
    """
    _check_name(name)
    role = one_of(role, "role", ROLES)
    record = {"role": role, **hashed(password)}

    def change(users: dict) -> None:
        if name in users:
            raise ParameterError(f"{path}: user {name!r} exists already (`mocapviz users {path} password {name}` "
                                 f"sets a new password, `role` a new role)")  # fmt: skip
        users[name] = record

    _update(path, change, create=True)


def remove_user(path: str | os.PathLike, name: str) -> None:
    """Remove the user ``name`` from the users file ``path`` (UnknownKeyError when it holds none)."""
    _update(path, lambda users: users.pop(_existing(users, name, path)))


def set_role(path: str | os.PathLike, name: str, role: str) -> None:
    """Give the user ``name`` of the users file ``path`` the role ``role`` (one of :data:`ROLES`)."""
    role = one_of(role, "role", ROLES)
    _update(path, lambda users: users[_existing(users, name, path)].update(role=role))


def set_password(path: str | os.PathLike, name: str, password: str) -> None:
    """Give the user ``name`` of the users file ``path`` a new password (a new salt and hash)."""
    record = hashed(password)
    _update(path, lambda users: users[_existing(users, name, path)].update(record))


def check_password(path: str | os.PathLike, name: str, password: str) -> str | None:
    """The role of the user ``name`` when ``password`` is its password, else None (also for a name the file does
    not hold: a hash is computed all the same, so that the time taken does not tell names apart).

    Parameters
    ----------
    path : str or os.PathLike
        The users file (read now: a user removed or given a new password since is judged by the file as it is).
    name, password : str
        What the user typed.

    Returns
    -------
    str or None
        One of :data:`ROLES`, or None.
    """
    record = read_users(path).get(name)
    stored = record if record is not None else {**SCRYPT, "salt": "00" * SALT_BYTES, "hash": "00" * HASH_BYTES}
    typed = _scrypt(password, bytes.fromhex(stored["salt"]), stored)
    same = hmac.compare_digest(typed, bytes.fromhex(stored["hash"]))
    return record["role"] if same and record is not None else None


def allows(role: str | None, action: str) -> bool:
    """Whether a user of ``role`` may do ``action``: a role's name (each includes the ones before it in
    :data:`ROLES`) or one of :data:`ACTIONS`.

    Examples
    --------
    >>> allows("annotate", "search"), allows("annotate", "annotate"), allows("annotate", "add takes")
    (True, True, False)
    >>> allows(None, "search")
    False
    """
    needed = ACTIONS.get(action, action)
    one_of(needed, "action", (*ROLES, *ACTIONS))
    return role in ROLES and ROLES.index(role) >= ROLES.index(needed)


def hashed(password: str) -> dict:
    """``{"kdf": "scrypt", "n", "r", "p", "salt", "hash"}`` of ``password`` with a new random salt (hex digits).

    Raises
    ------
    ParameterError
        ``password`` is not a string of :data:`PASSWORD_LENGTH` characters.
    """
    least, most = PASSWORD_LENGTH
    if not isinstance(password, str) or not least <= len(password) <= most:
        raise ParameterError(f"a password must have {least} to {most} characters"
                             + (f"; this one has {len(password)}" if isinstance(password, str) else ""))
    salt = secrets.token_bytes(SALT_BYTES)
    return {"kdf": "scrypt", **SCRYPT, "salt": salt.hex(), "hash": _scrypt(password, salt, SCRYPT).hex()}


def cookie_secret(path: str | os.PathLike | None = None) -> str:
    """The secret a server signs its login cookies with: the content of the file ``path`` (white space around it
    left out), else the environment variable :data:`COOKIE_SECRET_ENV`, else a new random one (43 characters, 256
    bits: every cookie of an earlier start is then void). Never printed, never logged.

    Raises
    ------
    ParameterError
        The secret given is shorter than :data:`COOKIE_SECRET_LENGTH` characters, or the file cannot be read (the
        message names the file or variable, never the secret).
    """
    if path is not None:
        try:
            given, where = Path(path).read_text(encoding="utf-8").strip(), str(path)
        except (OSError, UnicodeDecodeError) as exc:
            raise ParameterError(f"--cookie-secret-file {path}: cannot read it ({exc})") from None
    else:
        given, where = os.environ.get(COOKIE_SECRET_ENV, ""), COOKIE_SECRET_ENV
        if not given:
            return secrets.token_urlsafe(32)
    if len(given) < COOKIE_SECRET_LENGTH:
        raise ParameterError(f"{where}: a cookie secret needs at least {COOKIE_SECRET_LENGTH} characters, this one "
                             f"has {len(given)} (e.g. python -c 'import secrets; print(secrets.token_urlsafe(32))')")
    return given


def _scrypt(password: str, salt: bytes, cost: dict) -> bytes:
    n, r, p = cost["n"], cost["r"], cost["p"]
    return hashlib.scrypt(password.encode("utf-8"), salt=salt, n=n, r=r, p=p, dklen=HASH_BYTES,
                          maxmem=256 * n * r + 2**20)  # 128·n·r bytes of memory, and room


def _check_name(name) -> None:
    if not isinstance(name, str) or NAME.fullmatch(name) is None:
        raise ParameterError(f"user name {name!r}: give 1 to 64 letters, digits or . _ @ -, starting with a letter or "
                             f"a digit")  # fmt: skip


def _existing(users: dict, name: str, path) -> str:
    if name not in users:
        raise UnknownKeyError(f"{path}: no user {name!r}" + (f" (users: {', '.join(users)})" if users else
                                                             " (the file holds no users)"))  # fmt: skip
    return name


def _update(path: str | os.PathLike, change, create: bool = False) -> None:
    """Read the users file, ``change(users)`` in place, write it back: under the file's lock, atomically, mode
    0600 before its content is written. ``create``: a missing file counts as one without users."""
    path = Path(path)
    with store.locked(path.parent, what=str(path), name=f".{path.name}.lock"):
        users = {} if create and not path.exists() else read_users(path)
        change(users)
        content = {**store.stamp(FORMAT, VERSION), "users": dict(sorted(users.items()))}
        with store.atomic_file(path) as tmp:
            os.chmod(tmp, 0o600)
            tmp.write_text(json.dumps(content, indent=1) + "\n", encoding="utf-8")
