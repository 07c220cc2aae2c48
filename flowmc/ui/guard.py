"""Who may use an editor server: only the editor's own page, in a browser holding this launch's token.

Binding to 127.0.0.1 keeps other machines out but not other web pages: any site open in the user's
browser can open a websocket to ``ws://127.0.0.1:8080`` (browsers do not apply the same-origin rule
to websockets), and a DNS-rebinding site can even load the page under its own name. So every HTTP
request and websocket handshake must pass three checks, as Jupyter does:

- ``Host`` names this server (a loopback name, or a host given with ``--host``) on its own port:
  a rebinding site's requests carry its own name;
- ``Origin``, when the browser sends one, is this server itself (``http://<Host>``): a page from
  anywhere else is refused;
- the request carries the per-launch secret: ``?token=`` in the address ``flowmc serve`` prints, then
  a cookie (``HttpOnly``, ``SameSite=Strict``, named per port) that the page's websocket sends.

``Guard.check`` decides; ``flowmc.ui.viser_internals`` puts it in front of viser's server.
"""

from __future__ import annotations

import hmac
import secrets
import socket
from dataclasses import dataclass
from http.cookies import CookieError, SimpleCookie
from typing import Iterable, Mapping
from urllib.parse import parse_qs, urlsplit

__all__ = ["Guard", "Verdict", "LOOPBACK", "is_loopback"]

LOOPBACK = ("127.0.0.1", "localhost", "::1")
REFUSED_PAGE = ("flowmc editor: refused ({reason}).\n\nOpen the address `flowmc serve` printed: it carries the "
                "secret ?token=... of this launch. Pages from other sites may not use the editor.\n")


def is_loopback(host: str) -> bool:
    return host.strip("[]").lower() in LOOPBACK


@dataclass(frozen=True)
class Verdict:
    """``ok``; else ``status`` (403) and ``reason``. ``set_cookie``: the token came in the address."""

    ok: bool
    status: int = 200
    reason: str = ""
    set_cookie: bool = False


def _host_names(bind: str, extra: Iterable[str]) -> frozenset[str]:
    """Names a browser may use for a server bound to ``bind``: loopback names always, the bind address,
    and for all interfaces this machine's names and addresses."""
    names = {*LOOPBACK, bind.strip("[]").lower(), *(h.strip("[]").lower() for h in extra)}
    if bind in ("0.0.0.0", "::", ""):
        host = socket.gethostname()
        names |= {host.lower(), socket.getfqdn().lower()}
        try:
            names |= {info[4][0].lower() for info in socket.getaddrinfo(host, None)}
        except OSError:
            pass
    names.discard("")
    return frozenset(names)


class Guard:
    """The policy for one launch: the secret ``token`` and the host names the page may be loaded under."""

    def __init__(self, bind: str = "127.0.0.1", *, token: str | None = None, hosts: Iterable[str] = ()):
        self.token = token or secrets.token_urlsafe(24)
        self.hosts = _host_names(bind, hosts)

    @staticmethod
    def cookie_name(port: int) -> str:
        return f"flowmc-token-{port}"  # cookies ignore ports: one name per server

    def set_cookie(self, port: int) -> str:
        return f"{self.cookie_name(port)}={self.token}; Path=/; HttpOnly; SameSite=Strict"

    def _host_ok(self, value: str | None, port: int) -> bool:
        if not value:
            return False
        try:
            parts = urlsplit(f"//{value}")
            name, given = (parts.hostname or "").lower(), parts.port
        except ValueError:
            return False
        return name in self.hosts and (given or 80) == port

    def _token_in(self, path: str, cookie_header: str | None, port: int) -> tuple[bool, bool]:
        """(the token matched, it came in the address)."""
        query = parse_qs(urlsplit(path).query).get("token", [])
        if any(hmac.compare_digest(t.encode(), self.token.encode()) for t in query[:4]):
            return True, True
        if cookie_header:
            jar: SimpleCookie = SimpleCookie()
            try:
                jar.load(cookie_header)
            except CookieError:
                return False, False
            morsel = jar.get(self.cookie_name(port))
            if morsel is not None and hmac.compare_digest(morsel.value.encode(), self.token.encode()):
                return True, False
        return False, False

    def check(self, headers: Mapping[str, str], path: str, port: int) -> Verdict:
        """The verdict on one request (HTTP or websocket handshake) to the server listening on ``port``."""
        host = headers.get("Host")
        if not self._host_ok(host, port):
            return Verdict(False, 403, "this server does not answer to that host name")
        origin = headers.get("Origin")
        if origin is not None and origin.lower() != f"http://{host}".lower():
            return Verdict(False, 403, "requests from other sites are not allowed")
        matched, in_address = self._token_in(path, headers.get("Cookie"), port)
        if not matched:
            return Verdict(False, 403, "missing or wrong token")
        return Verdict(True, set_cookie=in_address)

    def url(self, host: str, port: int) -> str:
        """The address to open: this launch's token in the query."""
        shown = f"[{host}]" if ":" in host else host
        return f"http://{shown}:{port}/?token={self.token}"
