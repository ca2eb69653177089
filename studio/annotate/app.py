"""The FastAPI application of the annotation page and its uvicorn server, over an
:class:`~studio.annotate.server.AnnotateServer` (the endpoints are listed in :mod:`studio.annotate.server`).

Bound to 127.0.0.1 only; every error is ``{"error": "..."}`` JSON with a 4xx status.
"""

from __future__ import annotations

import contextlib
import json
import math
import socket
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from starlette.exceptions import HTTPException as StarletteHTTPException

from studio.annotate.server import (
    MAX_BODY,
    STATIC_DIR,
    STATIC_TYPES,
    AnnotateServer,
    ApiError,
    ServerError,
)
from studio.errors import StudioError

__all__ = ["bind_socket", "create_app", "make_server", "serve_in_thread"]


def _json_error(status: int, message: str, extra: dict[str, Any] | None = None) -> Any:
    return JSONResponse({"error": message, **(extra or {})}, status_code=status)


def create_app(state: AnnotateServer) -> Any:
    """The FastAPI application serving ``state`` (see the module doc for the endpoints)."""
    app = FastAPI(title="studio annotate", docs_url=None, redoc_url=None, openapi_url=None)
    static_names = {p.name for p in STATIC_DIR.iterdir() if p.is_file() and p.suffix in STATIC_TYPES}

    @app.exception_handler(ApiError)
    async def _api_error(_: Request, exc: ApiError) -> Any:
        return _json_error(exc.status, exc.message, exc.extra)

    @app.exception_handler(StarletteHTTPException)
    async def _http_error(request: Request, exc: StarletteHTTPException) -> Any:
        msg = f"no such page: {request.url.path}" if exc.status_code == 404 else str(exc.detail)
        return _json_error(exc.status_code, msg)

    @app.exception_handler(RequestValidationError)
    async def _bad_request(_: Request, exc: RequestValidationError) -> Any:
        errs = exc.errors()
        where = ".".join(str(x) for x in errs[0].get("loc", ())) if errs else ""
        return _json_error(400, f"bad request ({where}): {errs[0].get('msg') if errs else exc}")

    @app.exception_handler(StudioError)
    async def _studio_error(_: Request, exc: StudioError) -> Any:
        return _json_error(422, str(exc))

    def _static(name: str) -> Response:
        if name not in static_names:  # a fixed list: no path is ever built from the request
            raise ApiError(404, f"no such file: {name}")
        path = STATIC_DIR / name
        return Response(
            path.read_bytes(), media_type=STATIC_TYPES[path.suffix], headers={"Cache-Control": "no-cache"}
        )

    @app.get("/")
    def index() -> Response:
        return _static("index.html")

    @app.get("/static/{name}")
    def static(name: str) -> Response:
        return _static(name)

    @app.get("/api/meta")
    def meta() -> Any:
        return state.meta()

    @app.get("/api/state")
    def state_() -> Any:
        return state.state()

    @app.get("/api/frame/{n}")
    def frame(n: str) -> Any:
        return JSONResponse(_finite(state.frame(n)))

    @app.get("/api/frame/{n}/panorama.jpg")
    def panorama(n: str) -> Response:
        data = state.panorama(n)
        return Response(data, media_type="image/jpeg", headers={"Cache-Control": "private, max-age=3600"})

    async def _body(request: Request) -> Any:
        declared = request.headers.get("content-length", "")
        if declared.isdigit() and int(declared) > MAX_BODY:
            raise ApiError(413, f"request body too large ({declared} bytes; at most {MAX_BODY})")
        chunks, size = [], 0
        async for chunk in request.stream():
            size += len(chunk)
            if size > MAX_BODY:
                raise ApiError(413, f"request body too large (over {MAX_BODY} bytes)")
            chunks.append(chunk)
        raw = b"".join(chunks)
        if not raw:
            return {}
        try:
            return json.loads(raw)
        except (ValueError, UnicodeDecodeError) as exc:
            raise ApiError(400, f"malformed JSON body: {exc}") from None

    @app.post("/api/op")
    async def op(request: Request) -> Any:
        body = await _body(request)
        return await _in_thread(state.apply, body, "op")

    @app.post("/api/undo")
    async def undo(request: Request) -> Any:
        return await _in_thread(state.apply, await _body(request), "undo")

    @app.post("/api/redo")
    async def redo(request: Request) -> Any:
        return await _in_thread(state.apply, await _body(request), "redo")

    @app.get("/api/history")
    def history(frame: str | None = None, limit: str | None = None) -> Any:
        return state.history(frame, limit)

    @app.get("/api/metrics")
    def metrics(wait: str | None = None) -> Any:
        return JSONResponse(_finite(state.metrics(wait)))

    @app.get("/api/next")
    def next_(
        kind: str = "flag",
        start: str | None = None,
        dir: str | None = None,
        wait: str | None = None,
    ) -> Any:
        return state.next_frame(kind, start if start is not None else "0", dir, wait)

    @app.get("/api/rerun")
    def rerun_status() -> Any:
        return state.rerun.status() if state.rerun is not None else {"connected": False}

    @app.post("/api/rerun/time")
    async def rerun_time(request: Request) -> Any:
        body = await _body(request)
        if not isinstance(body, dict):
            raise ApiError(400, "the request body must be a JSON object")
        k = state.check_frame(body.get("frame"))
        if state.rerun is None:
            raise ApiError(404, "no Rerun viewer is linked")
        return state.rerun.set_frame(k)

    return app


async def _in_thread(fn: Callable[..., Any], *args: Any) -> Any:
    from starlette.concurrency import run_in_threadpool

    return await run_in_threadpool(fn, *args)


def _finite(v: Any) -> Any:
    """NaN/inf → None, recursively (JSON has no NaN)."""
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_finite(x) for x in v]
    return v


def bind_socket(port: int, *, host: str = "127.0.0.1") -> socket.socket:
    """A listening socket on ``host:port`` (0: a free port).

    Raises:
        ServerError: the port is taken or invalid.
    """
    if not 0 <= port <= 65535:
        raise ServerError(f"--port must be 0..65535, got {port}")
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # restart at once after a crash
    try:
        sock.bind((host, port))
    except OSError as exc:
        sock.close()
        raise ServerError(
            f"cannot listen on {host}:{port} ({exc.strerror or exc}); try another --port"
        ) from None
    sock.listen(128)
    return sock


def make_server(state: AnnotateServer, *, log_level: str = "warning") -> Any:
    """A uvicorn server for ``state``: ``server.run(sockets=[bind_socket(port)])`` (blocks; Ctrl-C stops it).

    Set ``server.should_exit = True`` to stop it from another thread.
    """
    import uvicorn

    config = uvicorn.Config(create_app(state), log_level=log_level, access_log=False, lifespan="off")
    return uvicorn.Server(config)


@contextlib.contextmanager
def serve_in_thread(state: AnnotateServer, *, port: int = 0) -> Iterator[str]:
    """Serve ``state`` from a background thread (tests, embedding); yields the page's URL.

    The server stops when the block ends; ``state`` stays open (the caller closes it).
    """
    sock = bind_socket(port)
    srv = make_server(state)
    th = threading.Thread(target=srv.run, kwargs={"sockets": [sock]}, daemon=True)
    th.start()
    while not srv.started and th.is_alive():
        time.sleep(0.05)
    try:
        yield f"http://127.0.0.1:{sock.getsockname()[1]}"
    finally:
        srv.should_exit = True
        th.join(timeout=10)
