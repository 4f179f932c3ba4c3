"""The access token: what every request and WebSocket must carry when the server listens
beyond this machine.

Bound to the loopback interface (the default), only this machine's users reach the
server, and no token is asked. Bound to any other address, every route but the page's
shell needs the token: ``Authorization: Bearer <token>``, or ``?token=<token>`` (the page
and the WebSocket, which cannot set a header). The token is made once, stored in the
server's folder with owner-only permissions, and printed once, when it is made.
"""

from __future__ import annotations

import ipaddress
import os
import secrets
import stat
from pathlib import Path

from tattotronix.errors import TattotronixError

__all__ = ["TOKEN_FILE", "is_loopback", "load_or_make_token", "token_matches"]

#: the token's file in the server's folder
TOKEN_FILE = "token"


def is_loopback(host: str) -> bool:
    """Whether ``host`` is this machine only (``localhost``, ``127.0.0.0/8``, ``::1``)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def load_or_make_token(folder: Path) -> tuple[str, bool]:
    """The server's token and whether it was made now (a new one is printed once).

    Raises:
        TattotronixError: the token file is readable by others (its permissions are
            refused, never repaired: someone may have read it), or unreadable.
    """
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / TOKEN_FILE
    if path.exists():
        mode = stat.S_IMODE(path.stat().st_mode)
        if mode & 0o077:
            raise TattotronixError(
                f"{path} can be read by others (mode {mode:o}): delete it, and a new token "
                "is made at the next start (every browser then needs the new one)")
        try:
            token = path.read_text(encoding="utf-8").strip()
        except OSError as exc:
            raise TattotronixError(f"cannot read the token file {path}: {exc}") from None
        if len(token) >= 16:
            return token, False
    token = secrets.token_urlsafe(24)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(token + "\n")
    os.chmod(path, 0o600)
    return token, True


def token_matches(given: str | None, token: str) -> bool:
    """Whether ``given`` is the token (in constant time)."""
    return given is not None and secrets.compare_digest(given.encode(), token.encode())
