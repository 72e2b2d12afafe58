"""The annotation tool's web server: a Starlette app on 127.0.0.1, served by uvicorn.

Security, for a server that can read two photos and write one file on the user's machine:

- it listens on 127.0.0.1 only, on a port the system picks;
- every ``/api`` call must carry the session's random token (``X-Annotate-Token``), which
  only the opened URL holds (in its fragment, which browsers never send to a server);
- the ``Host`` header must name the loopback address (a page on another site that renames
  itself to 127.0.0.1 by DNS rebinding still sends its own name), and a state-changing
  request from a page of another origin is refused;
- nothing is served or written but the two photos, the annotation file (and its backup),
  the tool's own page, and the fitted preview head, which lives in memory;
- request bodies are limited to :data:`MAX_BODY` bytes.

API (JSON unless said otherwise):

=======  ==================  ==========================================================
GET      /api/state          photos, points, catalogue, colours, how the points started
GET      /api/photo/{view}   ``front`` or ``side``: the photo
GET      /api/fdp            the annotation file as it is on disk now (404 before a save)
PUT      /api/fdp            ``{"views": ..., "force": false}``: validate and save
POST     /api/complete       ``{"views": ..., "replace_guesses": false}``: missing (and guessed) points
                             placed from the generic head fitted to the others
POST     /api/fit            ``{"views": ...}``: fit the head; a summary of the fit
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

import os
import secrets
import socket
import webbrowser
from collections.abc import Callable
from importlib import resources

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.middleware import Middleware
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from mpeg4.errors import InputError
from mpeg4.io.strict_json import loads

from .mesh_session import MeshSession, is_mesh
from .session import AnnotationSession, SaveConflict

__all__ = ["MAX_BODY", "TOKEN_HEADER", "HOSTS", "create_app", "annotate", "static_dir", "three_bundle"]

#: Largest request body accepted, bytes (84 points in two views take about 10 kB).
MAX_BODY = 1 << 20
#: Request header carrying the session token.
TOKEN_HEADER = "x-annotate-token"
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


class _Guard:
    """ASGI middleware: body size limit for every request; token and origin for ``/api``."""

    def __init__(self, app, token: str, max_body: int):
        self.app = app
        self.token = token.encode()
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
            given = headers.get(TOKEN_HEADER, b"")
            if not secrets.compare_digest(given, self.token):
                await _error(401, "missing or wrong session token",
                             fix="open the URL recon annotate printed (it carries the token)")(scope, receive, send)
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


def create_app(session: AnnotationSession | MeshSession, token: str, max_body: int = MAX_BODY) -> Starlette:
    """The tool's ASGI app for one session.

    Parameters
    ----------
    session : AnnotationSession or MeshSession
        Two photos, or a head mesh (the 3D mode).
    token : str
        The secret every ``/api`` call must carry in ``X-Annotate-Token``.
    max_body : int
        Largest request body, bytes.
    """
    static = static_dir()

    async def page(request: Request):
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
        data = await run_in_threadpool(p.content)
        if data is not None:
            return Response(data, media_type="image/png", headers={"Cache-Control": "no-store"})
        return FileResponse(p.path, media_type=p.media_type, headers={"Cache-Control": "no-store"})

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
               Route("/api/fit", fit, methods=["POST"]), Route("/api/head.glb", head)]
    routes = common[:-1] + own + common[-1:]
    middleware = [Middleware(TrustedHostMiddleware, allowed_hosts=list(HOSTS)),
                  Middleware(_Guard, token=token, max_body=max_body)]
    handlers = {
        InputError: lambda request, e: _input_error(e),
        _MalformedJSON: lambda request, e: _error(400, str(e), fix="send valid JSON"),
        SaveConflict: lambda request, e: _error(409, str(e),
                                                fix="load the file from disk, or save again to overwrite it"),
    }
    return Starlette(routes=routes, middleware=middleware, exception_handlers=handlers)


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
        Called with the page's URL (which carries the token) once the server listens.

    Returns
    -------
    path
        The annotation file.
    """
    import uvicorn

    if side is None:
        if not is_mesh(front):
            raise InputError("one file given, and it is not a head mesh", where=os.fspath(front),
                             fix="give a front and a side photo, or one mesh (.glb, .gltf, .obj, .ply)")
        session = MeshSession(front, fdp, detect=detect, unit=unit, up=up, forward=forward)
    else:
        session = AnnotationSession(front, side, fdp, detect=detect, ipd_mm=ipd_mm, focal_px=focal_px,
                                    background=True)
    token = secrets.token_urlsafe(24)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        sock.bind(("127.0.0.1", port))
    except OSError as e:
        sock.close()
        raise InputError(f"cannot listen on 127.0.0.1:{port} ({e.strerror})", fix="give another --port, or 0") from None
    sock.listen(64)  # before the browser is told, so its first request waits in the queue
    url = f"http://127.0.0.1:{sock.getsockname()[1]}/#token={token}"
    config = uvicorn.Config(create_app(session, token), log_level="warning", access_log=False, lifespan="off",
                            limit_concurrency=32, timeout_graceful_shutdown=2)
    server = uvicorn.Server(config)
    if ready is not None:
        ready(url)
    if open_browser:
        webbrowser.open(url)
    try:
        server.run(sockets=[sock])
    except KeyboardInterrupt:  # uvicorn stops cleanly, then passes Ctrl-C on: the normal way out
        pass
    finally:
        sock.close()
        session.close()
    return session.fdp_path
