"""The users file of ``mocapviz serve --auth`` (issue 40 item 5): ``mocapviz.users`` and ``mocapviz users FILE ...``.

Passwords are checked against a brute-force reference (``hashlib.scrypt`` over the stored salt with the stored
cost); the file is read back as bytes and searched for every password. Tests of anything but the cost itself hash
at a test's cost (:func:`cheap`).
"""
from __future__ import annotations

import hashlib
import json
import os
import stat
import subprocess
import sys

import pytest

from mocapviz import users
from mocapviz.errors import ParameterError, UnknownKeyError, UsersFileError

PASSWORDS = {"alice": "correct horse battery", "bob": "tr0ub4dor&3"}


@pytest.fixture
def cheap(monkeypatch):
    """scrypt at a test's cost (n = 16, r = 8, p = 1: microseconds) for new hashes; the stored cost is what a check
    uses, so everything else runs as with the real one (test_stored_hash_is_salted_scrypt_never_the_password)."""
    monkeypatch.setattr(users, "SCRYPT", {"n": 16, "r": 8, "p": 1})


@pytest.fixture
def users_file(tmp_path, cheap):
    path = tmp_path / "users.json"
    users.add_user(path, "alice", PASSWORDS["alice"], "annotate")
    users.add_user(path, "bob", PASSWORDS["bob"], "read")
    return path


def _mocapviz(*args, stdin: str = "") -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mocapviz.cli", *map(str, args)], input=stdin, text=True, check=False,
                          capture_output=True, timeout=120)  # fmt: skip


def test_round_trip_and_passwords(users_file):
    assert users.roles(users_file) == {"alice": "annotate", "bob": "read"}
    assert users.check_password(users_file, "alice", PASSWORDS["alice"]) == "annotate"
    assert users.check_password(users_file, "bob", PASSWORDS["bob"]) == "read"
    assert users.check_password(users_file, "alice", PASSWORDS["bob"]) is None  # another user's password
    assert users.check_password(users_file, "alice", PASSWORDS["alice"] + " ") is None
    assert users.check_password(users_file, "carol", PASSWORDS["alice"]) is None  # no such user
    users.set_role(users_file, "bob", "admin")
    users.set_password(users_file, "alice", "a new passphrase")
    assert users.check_password(users_file, "alice", PASSWORDS["alice"]) is None
    assert users.check_password(users_file, "alice", "a new passphrase") == "annotate"
    users.remove_user(users_file, "alice")
    assert users.roles(users_file) == {"bob": "admin"}
    assert users.check_password(users_file, "alice", "a new passphrase") is None


def test_stored_hash_is_salted_scrypt_never_the_password(tmp_path):
    users_file = tmp_path / "users.json"
    for name, role in (("alice", "annotate"), ("bob", "read")):
        users.add_user(users_file, name, PASSWORDS[name], role)
    raw = users_file.read_bytes()
    for password in PASSWORDS.values():
        assert password.encode() not in raw
    stored = json.loads(raw)
    assert stored["format"] == "mocapviz.users" and stored["version"] == 1
    records = stored["users"]
    assert records["alice"]["salt"] != records["bob"]["salt"]
    for name, password in PASSWORDS.items():
        r = records[name]
        reference = hashlib.scrypt(password.encode(), salt=bytes.fromhex(r["salt"]), n=r["n"], r=r["r"], p=r["p"],
                                   maxmem=2**26, dklen=32)  # fmt: skip
        assert (r["kdf"], r["n"], r["r"], r["p"]) == ("scrypt", 2**14, 8, 5)
        assert bytes.fromhex(r["hash"]) == reference
    # the same password twice gets two salts, two hashes
    users.set_password(users_file, "bob", PASSWORDS["bob"])
    assert json.loads(users_file.read_text())["users"]["bob"]["hash"] != records["bob"]["hash"]


def test_file_is_owner_only_whatever_the_umask(tmp_path, cheap):
    path = tmp_path / "users.json"
    old = os.umask(0)
    try:
        users.add_user(path, "alice", PASSWORDS["alice"], "admin")
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    path.chmod(0o644)
    users.set_role(path, "alice", "read")  # a rewrite makes it 0600 again
    assert stat.S_IMODE(path.stat().st_mode) == 0o600


@pytest.mark.parametrize("content, says", [
    ("not json {", "not JSON"),
    ('{"format": "mocapviz.MotionDB", "version": 1}', "not a mocapviz.users version 1 file"),
    ('{"format": "mocapviz.users", "version": 2, "users": {}}', "version 2 found"),
    ('{"format": "mocapviz.users", "version": 1, "users": {"eve": {"role": "root"}}}', "damaged users file"),
    ('{"format": "mocapviz.users", "version": 1, "users": []}', "damaged users file"),
])  # fmt: skip
def test_damaged_or_foreign_file_is_named(tmp_path, content, says, cheap):
    path = tmp_path / "users.json"
    path.write_text(content)
    with pytest.raises(UsersFileError, match=says) as err:
        users.roles(path)
    assert str(path) in str(err.value)
    with pytest.raises(UsersFileError):  # and nothing is written over it
        users.add_user(path, "alice", PASSWORDS["alice"], "read")
    assert path.read_text() == content


def test_refusals(users_file, tmp_path):
    with pytest.raises(UsersFileError, match="no such users file"):
        users.roles(tmp_path / "missing.json")
    with pytest.raises(ParameterError, match="exists already"):
        users.add_user(users_file, "alice", "another password", "read")
    with pytest.raises(ParameterError, match="8 to 1024 characters"):
        users.add_user(users_file, "carol", "short", "read")
    with pytest.raises(ParameterError, match="user name"):
        users.add_user(users_file, "../carol", "long enough", "read")
    with pytest.raises(ParameterError, match="unknown role 'root'"):
        users.set_role(users_file, "bob", "root")
    with pytest.raises(UnknownKeyError, match="no user 'carol'"):
        users.remove_user(users_file, "carol")
    assert users.roles(users_file) == {"alice": "annotate", "bob": "read"}


def test_roles_include_the_ones_before():
    table = {role: [action for action in ("search", "download", "annotate", "add takes") if users.allows(role, action)]
             for role in users.ROLES}  # fmt: skip
    assert table == {"read": ["search", "download"], "annotate": ["search", "download", "annotate"],
                     "admin": ["search", "download", "annotate", "add takes"]}
    assert not users.allows(None, "search")
    with pytest.raises(ParameterError, match="unknown action"):
        users.allows("admin", "delete everything")


def test_cookie_secret(tmp_path, monkeypatch):
    monkeypatch.delenv(users.COOKIE_SECRET_ENV, raising=False)
    a, b = users.cookie_secret(), users.cookie_secret()
    assert a != b and len(a) >= users.COOKIE_SECRET_LENGTH
    secret = "s" * 40
    (tmp_path / "secret").write_text(secret + "\n")
    assert users.cookie_secret(tmp_path / "secret") == secret
    monkeypatch.setenv(users.COOKIE_SECRET_ENV, "e" * 32)
    assert users.cookie_secret() == "e" * 32
    monkeypatch.setenv(users.COOKIE_SECRET_ENV, "short-secret")
    with pytest.raises(ParameterError, match=f"{users.COOKIE_SECRET_ENV}: a cookie secret needs at least 32") as err:
        users.cookie_secret()
    assert "short-secret" not in str(err.value)


def test_cli(tmp_path):
    path = tmp_path / "users.json"
    done = _mocapviz("users", path, "add", "alice", "--role", "admin", stdin="a long password\na long password\n")
    assert done.returncode == 0, done.stderr
    assert users.check_password(path, "alice", "a long password") == "admin"
    differ = _mocapviz("users", path, "add", "bob", "--role", "read", stdin="first password\nsecond password\n")
    assert differ.returncode == 1 and "differ" in differ.stderr
    assert list(users.roles(path)) == ["alice"]
    assert _mocapviz("users", path, "role", "alice", "annotate").returncode == 0
    listed = _mocapviz("users", path, "list")
    assert listed.stdout.splitlines() == ["1 user in " + str(path), "alice\tannotate"]
    assert json.loads(path.read_text())["users"]["alice"]["hash"] not in listed.stdout
    argv = _mocapviz("users", path, "add", "bob", "--role", "read", "--password", "on the command line")
    assert argv.returncode == 2  # no way to give a password as an argument
    assert _mocapviz("users", path, "remove", "alice").returncode == 0
    assert users.roles(path) == {}


def test_concurrent_adds_all_land(tmp_path):
    path = tmp_path / "users.json"
    names = [f"user{i}" for i in range(4)]
    procs = [subprocess.Popen([sys.executable, "-m", "mocapviz.cli", "users", str(path), "add", name, "--role", "read"],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for name in names]  # fmt: skip
    for name, proc in zip(names, procs):
        _, err = proc.communicate(f"password of {name}\n" * 2, timeout=120)
        assert proc.returncode == 0, err
    assert users.roles(path) == dict.fromkeys(names, "read")
    for name in names:
        assert users.check_password(path, name, f"password of {name}") == "read"
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
