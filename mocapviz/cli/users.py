"""``mocapviz users FILE add|list|remove|role|password``: the users of ``mocapviz serve --auth FILE``
(:mod:`mocapviz.users`). A password is read twice, from the terminal without echo (:func:`getpass.getpass`) or, when
standard input is not a terminal, as its first two lines; never from the command line, never stored in clear."""
from __future__ import annotations

import getpass
import sys

from .. import users
from ..errors import ParameterError
from ..validation import plural


def run_users(args) -> None:
    _ACTIONS[args.action](args)


def read_password(name: str) -> str:
    """The new password of user ``name``, typed twice (ParameterError when the two differ or input ends)."""
    if sys.stdin.isatty():
        first = getpass.getpass(f"password for {name}: ")
        second = getpass.getpass(f"password for {name} again: ")
    else:
        first, second = (sys.stdin.readline().rstrip("\r\n") for _ in range(2))
    if first != second:
        raise ParameterError(f"the two passwords typed for {name} differ; nothing changed")
    return first


def _add(args) -> None:
    users.add_user(args.file, args.name, read_password(args.name), args.role)
    print(f"user {args.name} added to {args.file} with role {args.role}")


def _list(args) -> None:
    roles = users.roles(args.file)
    print(f"{plural(len(roles), 'user')} in {args.file}")
    for name, role in roles.items():
        print(f"{name}\t{role}")


def _remove(args) -> None:
    users.remove_user(args.file, args.name)
    print(f"user {args.name} removed from {args.file}")


def _role(args) -> None:
    users.set_role(args.file, args.name, args.role)
    print(f"user {args.name} of {args.file} now has role {args.role} (from their next session)")


def _password(args) -> None:
    users.set_password(args.file, args.name, read_password(args.name))
    print(f"user {args.name} of {args.file} has a new password")


_ACTIONS = {"add": _add, "list": _list, "remove": _remove, "role": _role, "password": _password}
