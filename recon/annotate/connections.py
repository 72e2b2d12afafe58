"""How the annotation server holds its connections: none idle for long, a few per client.

uvicorn answers 503 to every request once ``limit_concurrency`` connections are open, and
keeps a connection that never sends a request open for ever: 32 idle connections, no token
needed, locked the page out. :class:`GuardedH11Protocol` (uvicorn's HTTP/1.1 protocol with
two rules added) replaces that limit:

- a connection must deliver a whole request (headers and body) within ``idle_timeout``
  seconds of opening, or of its last answer, else it is closed; the time the app then
  takes to answer does not count;
- one client address holds at most ``max_connections`` at once; when it opens one more,
  its connection idle the longest (no request in progress) is closed to make room, and if
  every one is busy the new one is closed. On 127.0.0.1 every local program is one client:
  the page's next request always finds room, by pushing an idle connection out.
"""

from __future__ import annotations

from uvicorn.protocols.http.h11_impl import H11Protocol

__all__ = ["GuardedH11Protocol", "guarded_protocol"]


class GuardedH11Protocol(H11Protocol):
    """uvicorn's h11 protocol with an idle timeout and a per-client connection limit.

    The two limits are class attributes; :func:`guarded_protocol` makes a subclass with
    others.
    """

    idle_timeout: float = 10.0
    max_connections: int = 16

    def connection_made(self, transport) -> None:
        super().connection_made(transport)
        self._since = self.loop.time()
        self._timer = self.loop.call_later(self.idle_timeout, self._check_idle)
        mine = [c for c in self.connections if isinstance(c, GuardedH11Protocol) and c.client_host == self.client_host]
        if len(mine) > self.max_connections:
            idle = [c for c in mine if c is not self and not c.busy]
            if idle:
                min(idle, key=lambda c: c._since).close()
            else:
                self.close()

    @property
    def client_host(self) -> str | None:
        return self.client[0] if self.client else None

    @property
    def busy(self) -> bool:
        """Whether the app is working on a request whose body has all arrived."""
        cycle = self.cycle
        return cycle is not None and not cycle.response_complete and not cycle.more_body

    def on_response_complete(self) -> None:
        self._since = self.loop.time()
        super().on_response_complete()

    def _check_idle(self) -> None:
        if self.transport.is_closing():
            return
        if self.busy:  # the app's time does not count: look again later
            self._timer = self.loop.call_later(self.idle_timeout, self._check_idle)
            return
        left = self._since + self.idle_timeout - self.loop.time()
        if left > 0:
            self._timer = self.loop.call_later(left, self._check_idle)
            return
        self.close()

    def close(self) -> None:
        """Close the connection (a request still arriving on it is dropped)."""
        self._timer.cancel()
        self.transport.close()

    def connection_lost(self, exc) -> None:
        self._timer.cancel()
        super().connection_lost(exc)


def guarded_protocol(idle_timeout: float, max_connections: int) -> type[GuardedH11Protocol]:
    """A :class:`GuardedH11Protocol` with these limits (for uvicorn's ``http=`` option)."""
    if not idle_timeout > 0 or max_connections < 1:
        raise ValueError("the idle timeout must be positive and at least one connection allowed")
    return type("GuardedH11Protocol", (GuardedH11Protocol,),
                {"idle_timeout": float(idle_timeout), "max_connections": int(max_connections)})
