"""``tattotronix serve [--host H] [--port N] [--folder DIR] [--max-upload-mb M]``.

Binds to ``127.0.0.1`` by default: only this machine reaches the server, and no token is
asked. Any other address (``--host 0.0.0.0`` on the Pi, for the phones and laptops on its
network) needs the access token on every request: it is made on the first such start,
stored in the server's folder with owner-only permissions, and printed once.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from tattotronix.errors import TattotronixError

__all__ = ["default_folder", "main"]


def default_folder() -> Path:
    """The server's own folder: ``$XDG_STATE_HOME/tattotronix`` (``~/.local/state``)."""
    base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(base) / "tattotronix"


def main(argv: Sequence[str] | None = None) -> int:
    """The command line (see the module docstring)."""
    ap = argparse.ArgumentParser(prog="tattotronix", description="TATTOTRONIX")
    sub = ap.add_subparsers(dest="command", required=True)
    serve = sub.add_parser("serve", help="the job server and its page")
    serve.add_argument("--host", default="127.0.0.1",
                       help="address to bind (default 127.0.0.1: this machine only)")
    serve.add_argument("--port", type=int, default=8420)
    serve.add_argument("--folder", type=Path, default=None,
                       help="the server's folder (plans, jobs, arm state, token; default "
                       f"{default_folder()})")
    serve.add_argument("--max-upload-mb", type=float, default=8.0)
    args = ap.parse_args(argv)

    import uvicorn

    from tattotronix.server.auth import is_loopback, load_or_make_token
    from tattotronix.server.web import create_app

    folder = (args.folder or default_folder()).expanduser().resolve()
    token = None
    try:
        if not is_loopback(args.host):
            token, made = load_or_make_token(folder)
            if made:
                print(f"access token (shown once; stored in {folder / 'token'}): {token}",
                      flush=True)
        hosts = (["localhost", "127.0.0.1", "::1", "[::1]"] if is_loopback(args.host)
                 else None)
        app = create_app(folder, token=token, hosts=hosts,
                         max_upload_bytes=int(args.max_upload_mb * 1024 * 1024))
    except TattotronixError as exc:
        print(f"tattotronix serve: {exc}", file=sys.stderr)
        return 2
    where = f"http://{args.host}:{args.port}/"
    print(f"serving {where} (folder {folder})" + ("" if token is None else
          "; open it with ?token=<token>"), flush=True)
    # no access log: the page's address and the WebSocket's carry the token (?token=)
    uvicorn.run(app, host=args.host, port=args.port, log_level="info", access_log=False)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
