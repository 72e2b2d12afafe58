"""The annotation tool's web server: a Starlette app on 127.0.0.1, served by uvicorn.

Security, for a server that can read two photos and write one file on the user's machine:

- it listens on 127.0.0.1 only, on a port the system picks;
- every ``/api`` call must carry the session's random token, which appears on no command
  line and in no URL: the address printed (and given to the browser, whose command line
  any local user can read) carries a one-time code instead, which the page exchanges for
  the token as an HTTP-only, same-site cookie (:func:`login_cookie`) and which is dead once
  used; programs may send the token in ``X-Annotate-Token``; a browser's request for
  ``/api`` from a page of another origin (``Sec-Fetch-Site``) is refused;
- the ``Host`` header must name the loopback address (a page on another site that renames
  itself to 127.0.0.1 by DNS rebinding still sends its own name), and a state-changing
  request from a page of another origin is refused;
- nothing is served or written but the two photos, the annotation file (and its backup),
  the tool's own page, and the fitted preview head, which lives in memory;
- request bodies are limited to :data:`MAX_BODY` bytes;
- a connection must send a whole request within :data:`IDLE_TIMEOUT` seconds of opening
  (or of its last answer), else it is closed; a client holds at most
  :data:`MAX_CONNECTIONS` connections at once, and when it opens one more its longest idle
  one is closed to make room, so idle connections cannot lock the page out
  (:class:`GuardedH11Protocol`).

API (JSON unless said otherwise):

=======  ==================  ==========================================================
GET      /api/state          photos, points, catalogue, colours, how the points started
GET      /api/photo/{view}   ``front`` or ``side``: the photo
GET      /api/fdp            the annotation file as it is on disk now (404 before a save)
PUT      /api/fdp            ``{"views": ..., "force": false}``: validate and save
POST     /api/complete       ``{"views": ..., "replace_guesses": false}``: missing (and guessed) points
                             placed from the generic head fitted to the others
POST     /api/fit            ``{"views": ...}``: fit the head; a summary of the fit
POST     /api/turn           ``{"views": ...}``: the side photo's points placed again for the other facing
GET      /api/head.glb       the last fitted head (``model/gltf-binary``)
=======  ==================  ==========================================================

In the 3D mode (``recon annotate MESH``, a :class:`~recon.annotate.mesh_session.MeshSession`)
the views are ``{"mesh": {"points": {id: [x, y, z]}, "confidence": ...}}`` (metres, neutral
frame), there are no photos, and:

=======  ==================  ==========================================================
GET      /api/mesh.glb       the mesh in the neutral frame (``model/gltf-binary``)
PUT      /api/fdp            as above; each point is snapped to the surface and bound to it
=======  ==================  ==========================================================
"""

from __future__ import annotations

import hashlib
import os
import secrets
import socket
import threading
import webbrowser
from collections.abc import Callable
from importlib import resources

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.middleware import Middleware
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.requests import Request
from starlette.responses import JSONResponse, RedirectResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from mpeg4.errors import InputError
from mpeg4.io.strict_json import loads

from .connections import GuardedH11Protocol, guarded_protocol
from .mesh_session import MeshSession, is_mesh
from .session import AnnotationSession, SaveConflict

__all__ = ["MAX_BODY", "TOKEN_HEADER", "HOSTS", "IDLE_TIMEOUT", "MAX_CONNECTIONS", "OneTimeCodes", "GuardedH11Protocol",
           "login_cookie", "create_app", "make_server", "annotate", "static_dir", "three_bundle"]

#: Largest request body accepted, bytes (84 points in two views take about 10 kB).
MAX_BODY = 1 << 20
#: Request header carrying the session token (for programs; the page uses the cookie).
TOKEN_HEADER = "x-annotate-token"
#: Seconds a connection may stay without a whole request in it (after opening, or after
#: its last answer) before it is closed.
IDLE_TIMEOUT = 10.0
#: Connections one client (address) may hold at once; a browser opens at most 6 to a host.
MAX_CONNECTIONS = 16
#: Host names the server answers to.
HOSTS = ("127.0.0.1", "localhost")

_PAGE_HEADERS = {
    # The page loads nothing from anywhere else; images and the head come as blobs.
    "Content-Security-Policy": "default-src 'self'; img-src 'self' blob: data:; connect-src 'self' blob: data:; "
                               "script-src 'self'; style-src 'self'; object-src 'none'; base-uri 'none'; "
                               "frame-ancestors 'none'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "Cache-Control": "no-store",
}


def static_dir():
    """The folder of the page's files (package data)."""
    return resources.files("recon.annotate").joinpath("static")


def three_bundle() -> bool:
    """Whether three.js is bundled (``npm ci && npm run build``, run by install.sh)."""
    return static_dir().joinpath("vendor", "three.bundle.js").is_file()


def _error(status: int, what: str, where: str | None = None, fix: str | None = None) -> JSONResponse:
    body = {"error": what}
    if where:
        body["where"] = where
    if fix:
        body["fix"] = fix
    return JSONResponse(body, status_code=status, headers={"Cache-Control": "no-store"})


def _input_error(e: InputError) -> JSONResponse:
    return _error(422, str(e), e.where, e.fix)


class _TooLarge(Exception):
    pass


def login_cookie(token: str) -> str:
    """The name of the cookie that carries ``token``: one per session, so that two
    ``recon annotate`` pages open in one browser (cookies do not tell ports apart) keep
    their own."""
    return "recon-annotate-" + hashlib.sha256(token.encode()).hexdigest()[:12]


class OneTimeCodes:
    """Codes that each let one browser in once: :meth:`issue` makes one, :meth:`redeem`
    accepts it once."""

    def __init__(self):
        self._live: set[str] = set()
        self._lock = threading.Lock()

    def issue(self) -> str:
        code = secrets.token_urlsafe(16)
        with self._lock:
            self._live.add(code)
        return code

    def redeem(self, code: str) -> bool:
        with self._lock:
            if code in self._live:
                self._live.discard(code)
                return True
        return False


def _cookie(headers: dict, name: str) -> bytes:
    """The value of cookie ``name`` in a request's headers (b"" if absent)."""
    for item in headers.get("cookie", b"").split(b";"):
        key, _, value = item.strip().partition(b"=")
        if key == name.encode():
            return value
    return b""


class _Guard:
    """ASGI middleware: body size limit for every request; token (header or cookie) and
    origin for ``/api``."""

    def __init__(self, app, token: str, max_body: int):
        self.app = app
        self.token = token.encode()
        self.cookie = login_cookie(token)
        self.max_body = max_body

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = {k.decode("latin-1").lower(): v for k, v in scope["headers"]}
        length = headers.get("content-length")
        if length is not None and (not length.isdigit() or int(length) > self.max_body):
            await _error(413, f"request body over {self.max_body} bytes")(scope, receive, send)
            return
        if scope["path"].startswith("/api/") or scope["path"] == "/api":
            given = headers.get(TOKEN_HEADER) or _cookie(headers, self.cookie)
            if not secrets.compare_digest(given, self.token):
                await _error(401, "missing or wrong session token",
                             fix="open the address recon annotate printed, in this browser")(scope, receive, send)
                return
            site = headers.get("sec-fetch-site")
            if site is not None and site not in (b"same-origin", b"none"):
                await _error(403, "request from another site's page")(scope, receive, send)
                return
            origin = headers.get("origin")
            if scope["method"] not in ("GET", "HEAD") and origin is not None:
                host = headers.get("host", b"").decode("latin-1")
                if origin.decode("latin-1") != f"http://{host}":
                    await _error(403, "request from another origin")(scope, receive, send)
                    return
        seen = 0
        started = False

        async def limited_receive():
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > self.max_body:
                    raise _TooLarge
            return message

        async def tracking_send(message):
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, limited_receive, tracking_send)
        except _TooLarge:
            if not started:
                await _error(413, f"request body over {self.max_body} bytes")(scope, receive, send)


class _MalformedJSON(Exception):
    pass


async def _json_body(request: Request):
    """The request's JSON body; :class:`_MalformedJSON` with the parser's message."""
    raw = await request.body()
    try:
        return loads(raw, where="request body")
    except InputError as e:  # syntax, nesting deeper than any page sends, a key twice
        raise _MalformedJSON(f"malformed JSON: {e.what}") from None


def _views_of(body, allowed=("views",)) -> object:
    if not isinstance(body, dict) or "views" not in body or set(body) - set(allowed):
        found = sorted(body) if isinstance(body, dict) else type(body).__name__
        raise InputError(f"expected a JSON object with 'views' (and only {', '.join(allowed)}), found {found}",
                         where="request body",
                         fix='send {"views": {"front": {"points": {...}}, "side": {"points": {...}}}}')
    return body["views"]


def create_app(session: AnnotationSession | MeshSession, token: str, max_body: int = MAX_BODY,
               codes: OneTimeCodes | None = None) -> Starlette:
    """The tool's ASGI app for one session.

    Parameters
    ----------
    session : AnnotationSession or MeshSession
        Two photos, or a head mesh (the 3D mode).
    token : str
        The secret every ``/api`` call must carry, in the cookie :func:`login_cookie`
        names or in ``X-Annotate-Token``.
    max_body : int
        Largest request body, bytes.
    codes : OneTimeCodes, optional
        The one-time codes ``/?code=...`` accepts (one each) to set the cookie; the app's
        own (``app.state.codes``) when None.
    """
    static = static_dir()
    codes = codes if codes is not None else OneTimeCodes()

    async def page(request: Request):
        code = request.query_params.get("code")
        if code is not None:
            # Away from the address with the code (so a reload or the history does not keep
            # it), with the session's cookie when the code is good and unused.
            out = RedirectResponse("/", status_code=303, headers={"Cache-Control": "no-store",
                                                                 "Referrer-Policy": "no-referrer"})
            if codes.redeem(code):
                out.set_cookie(login_cookie(token), token, httponly=True, samesite="strict", path="/")
            return out
        return Response(static.joinpath("index.html").read_bytes(), media_type="text/html; charset=utf-8",
                        headers=_PAGE_HEADERS)

    async def state(request: Request):
        data = await run_in_threadpool(session.state)
        data["preview"] = {"three": three_bundle()}
        return JSONResponse(data, headers={"Cache-Control": "no-store"})

    async def photo(request: Request):
        view = request.path_params["view"]
        if view not in session.photos:
            return _error(404, f"no photo '{view}'", fix="the photos are 'front' and 'side'")
        p = session.photos[view]
        # The file opened at the start, whatever its name points to now.
        data = await run_in_threadpool(p.content)
        return Response(data, media_type=p.media_type, headers={"Cache-Control": "no-store"})

    async def read_fdp(request: Request):
        try:
            data = await run_in_threadpool(session.load)
        except FileNotFoundError:
            return _error(404, f"{session.fdp_path.name} has not been saved yet")
        return JSONResponse(data, headers={"Cache-Control": "no-store"})

    async def write_fdp(request: Request):
        body = await _json_body(request)
        views = _views_of(body, ("views", "force"))
        return JSONResponse(await run_in_threadpool(session.save, views, body.get("force") is True))

    async def complete(request: Request):
        body = await _json_body(request)
        views = _views_of(body, ("views", "replace_guesses"))
        return JSONResponse(await run_in_threadpool(session.complete, views, body.get("replace_guesses") is True))

    async def turn(request: Request):
        views = _views_of(await _json_body(request))
        return JSONResponse(await run_in_threadpool(session.turn, views))

    async def fit(request: Request):
        views = _views_of(await _json_body(request))
        return JSONResponse(await run_in_threadpool(session.fit, views))

    async def head(request: Request):
        if session.glb is None:
            return _error(404, "no head fitted yet", fix="POST /api/fit first")
        return Response(session.glb, media_type="model/gltf-binary", headers={"Cache-Control": "no-store"})

    async def no_icon(request: Request):
        return Response(status_code=204)

    async def mesh(request: Request):
        data = await run_in_threadpool(session.glb)
        return Response(data, media_type="model/gltf-binary", headers={"Cache-Control": "no-store"})

    common = [
        Route("/", page),
        Route("/favicon.ico", no_icon),
        Route("/api/state", state),
        Route("/api/fdp", read_fdp, methods=["GET"]),
        Route("/api/fdp", write_fdp, methods=["PUT"]),
        Mount("/static", StaticFiles(directory=os.fspath(static)), name="static"),
    ]
    if isinstance(session, MeshSession):
        own = [Route("/api/mesh.glb", mesh)]
    else:
        own = [Route("/api/photo/{view}", photo), Route("/api/complete", complete, methods=["POST"]),
               Route("/api/fit", fit, methods=["POST"]), Route("/api/head.glb", head),
               Route("/api/turn", turn, methods=["POST"])]
    routes = common[:-1] + own + common[-1:]
    middleware = [Middleware(TrustedHostMiddleware, allowed_hosts=list(HOSTS)),
                  Middleware(_Guard, token=token, max_body=max_body)]
    handlers = {
        InputError: lambda request, e: _input_error(e),
        _MalformedJSON: lambda request, e: _error(400, str(e), fix="send valid JSON"),
        SaveConflict: lambda request, e: _error(409, str(e),
                                                fix="load the file from disk, or save again to overwrite it"),
    }
    app = Starlette(routes=routes, middleware=middleware, exception_handlers=handlers)
    app.state.codes = codes
    return app


def make_server(app: Starlette, idle_timeout: float = IDLE_TIMEOUT, max_connections: int = MAX_CONNECTIONS):
    """A uvicorn server for ``app`` whose connections follow :class:`GuardedH11Protocol`
    (run it with ``server.run(sockets=[sock])``)."""
    import uvicorn

    # No limit_concurrency: it counts idle connections too, and answers 503 once they fill it.
    config = uvicorn.Config(app, log_level="warning", access_log=False, lifespan="off", ws="none",
                            http=guarded_protocol(idle_timeout, max_connections), timeout_graceful_shutdown=2)
    return uvicorn.Server(config)


def annotate(front, side=None, fdp=None, open_browser: bool = True, port: int = 0, detect=True,
             ipd_mm: float | None = None, focal_px: float | None = None,
             ready: Callable[[str], None] | None = None, unit: str | None = None, up: str | None = None,
             forward: str | None = None) -> os.PathLike:
    """``recon annotate``: serve the annotation page for two photos, or a head mesh, until interrupted.

    Parameters
    ----------
    front, side : path
        The photos; or ``front`` a head mesh (GLB, glTF, OBJ, PLY) and ``side`` None for
        the 3D mode.
    fdp : path, optional
        The annotation file: read when it exists, written on save (beside the front photo
        or the mesh, named after it, when None).
    open_browser : bool
        Open the page in the default browser.
    port : int
        0 for any free port.
    detect : callable or bool
        Automatic placement (see :func:`recon.annotate.placement.initial_annotation`).
    ipd_mm, focal_px : float, optional
        For the 3D preview's fit, as ``recon fit`` takes them.
    unit, up, forward : str, optional
        The mesh's unit and axes (3D mode; see :func:`recon.mark.estimate_frame`).
    ready : callable, optional
        Called with the page's address once the server listens: it carries a one-time code
        (the browser opened here uses another), never the session's token.

    Returns
    -------
    path
        The annotation file.
    """
    if side is None:
        if not is_mesh(front):
            raise InputError("one file given, and it is not a head mesh", where=os.fspath(front),
                             fix="give a front and a side photo, or one mesh (.glb, .gltf, .obj, .ply)")
        session = MeshSession(front, fdp, detect=detect, unit=unit, up=up, forward=forward)
    else:
        session = AnnotationSession(front, side, fdp, detect=detect, ipd_mm=ipd_mm, focal_px=focal_px,
                                    background=True)
    token = secrets.token_urlsafe(24)
    codes = OneTimeCodes()
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        sock.bind(("127.0.0.1", port))
    except OSError as e:
        sock.close()
        session.close()
        raise InputError(f"cannot listen on 127.0.0.1:{port} ({e.strerror})", fix="give another --port, or 0") from None
    sock.listen(64)  # before the browser is told, so its first request waits in the queue
    base = f"http://127.0.0.1:{sock.getsockname()[1]}/"
    server = make_server(create_app(session, token, codes=codes))
    if ready is not None:
        ready(f"{base}?code={codes.issue()}")
    if open_browser:
        # The browser's command line is readable by every local user: it gets a code of its
        # own, dead once the page has loaded.
        webbrowser.open(f"{base}?code={codes.issue()}")
    try:
        server.run(sockets=[sock])
    except KeyboardInterrupt:  # uvicorn stops cleanly, then passes Ctrl-C on: the normal way out
        pass
    finally:
        sock.close()
        session.close()
    return session.fdp_path
