"""The studio's web server: the page, its assets, the design API and the run control, on localhost.

Routes (JSON in and out; an error is {"error": message} with a 4xx status):
    GET  /                         the page            GET /static/<file>, /vendor/three/<file>: its assets
    GET  /api/files?kind=K         worlds or missions found as magna run finds them
    POST /api/world/open|new|check|save, /api/mission/open|new|check|save
    GET  /api/mission/state_types  the forms of each state type
    POST /api/run/start|stop       GET /api/run/status      one magna run, and its bridge's WebSocket URL
    GET  /reports/<path>           a dataset's reports, read from the data root

The page is served to this machine only, and a POST must carry the header X-Magna-Studio (a page of
another site cannot set it without a CORS preflight, which this server never grants), and name this
server in its Host header (against DNS rebinding): another site open in the same browser can neither
save files nor start runs.
"""
from __future__ import annotations

import asyncio
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import tornado.web

from magna_studio import documents, mission_design, world_design
from magna_studio.run_control import RunError, RunRequest, StudioRun

WEB = Path(__file__).resolve().parents[2] / "web"
THREE = WEB / "node_modules" / "three"
POST_HEADER = "X-Magna-Studio"
MAX_BODY = 16 * 1024 * 1024  # a world or mission document; the corpus's largest is under 1 MB


class Studio:
    """What the handlers share: where to look for files, and the run."""

    def __init__(self, search_path: list[Path], data_root: Path, run: StudioRun, hosts: set[str]):
        self.search_path, self.data_root, self.run, self.hosts = search_path, data_root, run, hosts


class ApiHandler(tornado.web.RequestHandler):
    def initialize(self, studio: Studio) -> None:
        self.studio = studio

    def prepare(self) -> None:
        host = (self.request.host or "").rsplit(":", 1)[0].strip("[]")
        if host not in self.studio.hosts:
            raise tornado.web.HTTPError(403, reason=f"the studio answers as {', '.join(sorted(self.studio.hosts))}")
        if self.request.method == "POST" and self.request.headers.get(POST_HEADER) != "1":
            raise tornado.web.HTTPError(403, reason=f"a POST to the studio needs the header {POST_HEADER}: 1")

    def body(self) -> dict:
        try:
            body = json.loads(self.request.body or b"{}")
        except ValueError as err:
            raise tornado.web.HTTPError(400, reason=f"the request is not JSON: {err}") from None
        if not isinstance(body, dict):
            raise tornado.web.HTTPError(400, reason="the request is not a JSON object")
        return body

    def write_error(self, status_code: int, **kwargs: Any) -> None:
        self.set_header("Content-Type", "application/json")
        self.finish(json.dumps({"error": self._reason}))

    async def answer(self, work: Callable[[], Any]) -> None:
        """Run `work` off the event loop (loading, checking and drawing take time) and send what it returns."""
        try:
            result = await asyncio.get_running_loop().run_in_executor(None, work)
        except documents.DocumentExists as err:
            self.set_status(409)
            self.finish({"error": str(err), "exists": True})
            return
        except (documents.DesignError, RunError) as err:
            self.set_status(400)
            self.finish({"error": " ".join(str(err).split())})
            return
        self.finish(json.dumps(result))


def _text(body: dict, key: str) -> str:
    value = body.get(key)
    if not isinstance(value, str) or not value:
        raise tornado.web.HTTPError(400, reason=f"{key}: give a text")
    return value


def _document(body: dict, key: str = "data") -> dict:
    value = body.get(key)
    if not isinstance(value, dict):
        raise tornado.web.HTTPError(400, reason=f"{key}: give the document, a JSON object")
    return value


class FilesHandler(ApiHandler):
    async def get(self) -> None:
        kind = self.get_query_argument("kind", "")
        if kind not in ("world", "mission"):
            raise tornado.web.HTTPError(400, reason="kind: give world or mission")
        await self.answer(lambda: {"files": documents.list_files(kind, self.studio.search_path)})


def _seed(body: dict) -> int:
    seed = body.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise tornado.web.HTTPError(400, reason="seed: give a whole number (the world's lay-out seed)")
    return seed


class DocumentHandler(ApiHandler):
    """What the world and mission routes share: saving a document."""

    async def save(self, body: dict) -> None:
        data, path, overwrite = _document(body), Path(_text(body, "path")).expanduser(), body.get("overwrite") is True
        await self.answer(lambda: {"path": str(documents.save_document(data, path, overwrite))})


class WorldHandler(DocumentHandler):
    async def post(self, action: str) -> None:
        body, search = self.body(), self.studio.search_path
        seed = _seed(body)
        if action == "open":
            spec = _text(body, "spec")
            await self.answer(lambda: world_design.open_world(spec, search, seed))
        elif action == "new":
            await self.answer(lambda: {"data": world_design.new_world()})
        elif action == "check":
            data, source = _document(body), body.get("source") or "world.json"
            await self.answer(lambda: world_design.check_world(data, str(source), search, seed))
        else:
            await self.save(body)


class MissionHandler(DocumentHandler):
    async def post(self, action: str) -> None:
        body, search = self.body(), self.studio.search_path
        seed = _seed(body)
        if action == "open":
            spec = _text(body, "spec")
            await self.answer(lambda: mission_design.open_mission(spec, search))
        elif action == "new":
            await self.answer(lambda: {"data": mission_design.new_mission()})
        elif action == "check":
            data, source = _document(body), str(body.get("source") or "mission.json")
            world = body.get("world")
            if world is not None and not (isinstance(world, dict) and isinstance(world.get("data"), dict)):
                raise tornado.web.HTTPError(400, reason="world: give {'data': the world document, 'source': name}")

            def check() -> dict:
                found = mission_design.check_mission(data, source, world, search, seed)
                if world is not None:
                    found["pose_choices"] = world_design.pose_choices(world["data"], str(world.get("source") or
                                                                                         "world.json"), search, seed)
                return found

            await self.answer(check)
        else:
            await self.save(body)


class StateTypesHandler(ApiHandler):
    async def get(self) -> None:
        await self.answer(mission_design.state_types)


class RunHandler(ApiHandler):
    async def post(self, action: str) -> None:
        run = self.studio.run
        if action == "start":
            body = self.body()
            await self.answer(lambda: run.start(RunRequest.from_json(body)))
        elif action == "stop":
            def stop() -> dict:
                run.stop()
                return run.status()

            await self.answer(stop)
        else:
            raise tornado.web.HTTPError(404)

    def get(self, action: str) -> None:
        if action != "status":
            raise tornado.web.HTTPError(404)
        self.finish(json.dumps(self.studio.run.status()))


class PageHandler(tornado.web.RequestHandler):
    def get(self) -> None:
        self.set_header("Cache-Control", "no-store")
        self.set_header("Content-Type", "text/html; charset=utf-8")
        self.finish((WEB / "index.html").read_bytes())


def missing_assets() -> str:
    """Why the page cannot be served ("" when it can): its npm assets are made by `make setup`."""
    if not (WEB / "index.html").is_file():
        return f"{WEB / 'index.html'} is missing; the checkout is incomplete"
    if not (THREE / "build" / "three.module.js").is_file():
        return f"the page's 3-D library is not installed in {THREE.parent}; run 'make setup' in the workspace"
    return ""


def make_app(studio: Studio) -> tornado.web.Application:
    api = {"studio": studio}
    return tornado.web.Application([
        (r"/", PageHandler),
        (r"/api/files", FilesHandler, api),
        (r"/api/world/(open|new|check|save)", WorldHandler, api),
        (r"/api/mission/(open|new|check|save)", MissionHandler, api),
        (r"/api/mission/state_types", StateTypesHandler, api),
        (r"/api/run/(start|stop|status)", RunHandler, api),
        (r"/static/(.*)", tornado.web.StaticFileHandler, {"path": str(WEB)}),
        (r"/vendor/three/(.*)", tornado.web.StaticFileHandler, {"path": str(THREE)}),
        (r"/reports/(.*)", tornado.web.StaticFileHandler, {"path": str(studio.data_root)}),
    ], max_body_size=MAX_BODY)
