"""Shows: create / import, list, read, revision-checked update, delete, check, simulate, export."""

from __future__ import annotations

import asyncio
import json
import math
import re
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Body, Path, Query, Request, Response
from fastapi.responses import JSONResponse

from app import tasks
from app.api import deps
from app.api.errors import ApiError, draft_problems, job_body, require_valid, show_problems
from app.api.models import (
    DEFAULT_FLIGHT_PRESET,
    MAX_SEED,
    CheckOut,
    ControllerName,
    DisturbanceName,
    JobOut,
    MonteCarloOptions,
    PresetName,
    RevisionList,
    RevisionOut,
    ShowList,
    ShowOut,
    ShowSummary,
    SimulateOptions,
    error_responses,
)
from app.store import RevisionConflict, ShowData, ShowRecord
from app.web import BodyTooLarge

router = APIRouter(tags=["shows"])

_DRAFT_QUERY = Query(False, description="Keep a show that breaks the rules as a draft (with its problems "
                     "listed) instead of refusing it with 422. Check, simulate, export and playback refuse a "
                     "draft until it is saved valid.")

_UPLOAD_CONTENT = {
    "application/json": {"schema": {"$ref": "#/components/schemas/ShowFile"}},
    "multipart/form-data": {
        "schema": {
            "type": "object",
            "properties": {"file": {"type": "string", "format": "binary", "description": "The show file (JSON)."}},
            "required": ["file"],
        }
    },
    "application/octet-stream": {"schema": {"type": "string", "format": "binary"}},
}
_UPDATE_CONTENT = {"application/json": {"schema": {"$ref": "#/components/schemas/ShowUpdate"}}}


def _summary(record: ShowRecord) -> dict[str, Any]:
    fields = {k: getattr(record, k) for k in ShowSummary.model_fields if k not in ("draft", "problems")}
    problems = draft_problems(record)
    return ShowSummary(**fields, draft=problems is not None, problems=problems or []).model_dump()


def _show_response(request: Request, record: ShowRecord, *, status: int = 200,
                   headers: dict[str, str] | None = None) -> Response:
    # The stored text is already valid show JSON: splice it in rather than parse and re-encode megabytes.
    head = json.dumps(_summary(record))[:-1]
    # Whether the music sub-resource exists, so that a client (the editor) never asks for one that is not
    # there (a 404 the browser logs as an error on every music-less show).
    has_audio = deps.store(request).get_audio(record.id) is not None
    return Response(
        f'{head},"has_audio":{json.dumps(has_audio)},"show":{record.json}}}',
        status_code=status,
        media_type="application/json",
        headers={"ETag": f'"{record.revision}"', **(headers or {})},
    )


def _invalid(msg: str, *, loc: tuple[str | int, ...] = (), path: str = "") -> ApiError:
    return ApiError(422, [{"loc": ["body", *loc], "path": path, "msg": msg}])


#: Show files larger than this are validated in a worker process (seconds of CPU for the largest).
INLINE_PARSE_BYTES = 256 * 1024


async def _parse_show(request: Request, data: bytes | dict[str, Any], *, size: int,
                      prefix: tuple[str | int, ...] = (), draft: bool = False) -> ShowData:
    """Validate a show file (``size`` bytes of JSON); 422 lists every problem with its path.

    With ``draft``, a JSON object that breaks the rules comes back as a draft (its problems listed).
    """
    try:
        if size > INLINE_PARSE_BYTES:
            return ShowData(**await deps.run(request, tasks.validate_task, data, draft))
        # Validation, canonical JSON and its hash all in the thread: none of it on the event loop.
        return await asyncio.to_thread(tasks.validate_show_data, data, draft=draft)
    except tasks.TaskFailure as exc:
        if exc.kind != tasks.FailureKind.INVALID:
            raise
        raise ApiError(422, show_problems(exc.detail, prefix=prefix)) from None


async def _read_upload(request: Request, *, max_bytes: int) -> bytes:
    """The show file's bytes from a JSON, raw or multipart (``file`` part) body."""
    if request.headers.get("content-type", "").startswith("multipart/form-data"):
        form = await request.form(max_files=1, max_fields=20)
        try:
            upload = form.get("file")
            if upload is None or isinstance(upload, str):
                raise _invalid("a multipart upload needs a 'file' part holding the show file", loc=("file",),
                               path="file")
            data = await upload.read(max_bytes + 1)
        finally:
            await form.close()
    else:
        data = await request.body()
    if len(data) > max_bytes:
        # A multipart file was read only up to the limit: its real size is unknown here.
        multipart = request.headers.get("content-type", "").startswith("multipart/form-data")
        raise BodyTooLarge("a show file", max_bytes, size=None if multipart else len(data))
    if not data.strip():
        raise _invalid("the body is empty; send a show file (JSON)")
    return data


@router.post(
    "/shows",
    status_code=201,
    response_model=ShowOut,
    summary="Create a show (or import a show file)",
    responses=error_responses(413, 422),
    openapi_extra={"requestBody": {"required": True, "content": _UPLOAD_CONTENT}},
)
async def create_show(request: Request, draft: bool = _DRAFT_QUERY) -> Response:
    """Store a new show at revision 1.

    The body is a show file: as JSON, as raw bytes, or as the ``file`` part of a
    multipart upload (import). The show is validated completely before anything
    is stored; 422 lists every problem with its JSON path. With ``?draft=true`` a
    show that breaks the rules is stored anyway as a draft (``draft: true`` and its
    ``problems`` in the answer).
    """
    s = deps.settings(request)
    data = await _read_upload(request, max_bytes=s.max_show_bytes)
    show = await _parse_show(request, data, size=len(data), draft=draft)
    record = await deps.write(request, deps.store(request).create, show)
    return _show_response(request, record, status=201, headers={"Location": f"/api/shows/{record.id}"})


@router.get("/shows", response_model=ShowList, summary="List shows")
async def list_shows(
    request: Request,
    limit: int = Query(50, ge=1, le=500, description="Page size."),
    offset: int = Query(0, ge=0, le=2**62, description="Shows to skip."),
) -> ShowList:
    """A page of shows, most recently updated first (without their content)."""
    records, total = deps.store(request).list(limit=limit, offset=offset)
    return ShowList(items=[ShowSummary(**_summary(r)) for r in records], total=total, limit=limit, offset=offset)


@router.get("/shows/{show_id}", response_model=ShowOut, summary="Read a show", responses=error_responses(404))
async def get_show(request: Request, show_id: str) -> Response:
    """The show with its revision (also in the ``ETag`` header) and its show file."""
    return _show_response(request, deps.store(request).get(show_id))


@router.get("/shows/{show_id}/revisions", response_model=RevisionList, summary="A show's revision history",
            responses=error_responses(404))
async def list_revisions(
    request: Request,
    show_id: str,
    limit: int = Query(100, ge=1, le=1000, description="Page size."),
    offset: int = Query(0, ge=0, le=2**62, description="Revisions to skip."),
) -> RevisionList:
    """Every acknowledged change of the show, newest first: revision, name, content hash, time."""
    records, total = deps.store(request).revisions(show_id, limit=limit, offset=offset)
    items = [RevisionOut(revision=r.revision, name=r.name, content_hash=r.content_hash, drones=r.drones,
                         formations=r.formations, created_at=r.created_at, has_show=r.has_json,
                         draft=r.draft) for r in records]
    return RevisionList(show_id=show_id, items=items, total=total, limit=limit, offset=offset)


@router.get("/shows/{show_id}/revisions/{revision}", summary="One revision's show file",
            response_class=Response, responses={200: {"description": "The show file of that revision.",
                                                      "content": {"application/json": {}}},
                                                **error_responses(404)})
async def get_revision(request: Request, show_id: str, revision: int = Path(ge=1, le=2**62)) -> Response:
    """The show file as it was at ``revision`` (404 once only its metadata is kept)."""
    record = deps.store(request).get_revision(show_id, revision)
    if record.json is None:
        raise ApiError(404, f"revision {revision} of show {show_id!r} is too old; only its metadata is kept")
    return Response(record.json, media_type="application/json", headers={"ETag": f'"{revision}"'})


#: PUT bodies larger than this are parsed in a thread, not on the event loop.
INLINE_JSON_BYTES = 64 * 1024


def _load_json(raw: bytes) -> Any:
    """Parse a request body as strict UTF-8 JSON; 422 for anything a parser refuses (bad bytes, bad
    syntax, integers of thousands of digits, nesting deeper than the parser's stack)."""
    try:
        # Strictly UTF-8 (RFC 8259), as for a new show: json.loads alone would also take UTF-16/32 bytes.
        return json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise _invalid(f"not UTF-8 text (byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        raise _invalid(f"not valid JSON: {exc}") from None
    except RecursionError:
        raise _invalid("not valid JSON: nested too deeply") from None
    except ValueError as exc:  # "Exceeds the limit (4300 digits) for integer string conversion"
        raise _invalid(f"not valid JSON: {exc}") from None


def _revision_from(body_value: Any, if_match: str | None) -> int:
    if if_match:
        header = if_match.strip().removeprefix("W/").strip('"')
        try:
            given = int(header)
        except ValueError:
            raise ApiError(422, [{"loc": ["header", "if-match"], "path": "If-Match", "where": "the If-Match header",
                                  "msg": "must be a revision number, e.g. \"3\""}]) from None
        # If-Match is a precondition whether or not the body names a revision too: both must agree.
        if body_value is not None and body_value != given:
            raise ApiError(422, [{"loc": ["header", "if-match"], "path": "If-Match", "where": "the If-Match header",
                                  "msg": f"If-Match {given} and the body's revision {body_value!r} disagree"}])
        body_value = given
    if body_value is None:
        raise _invalid("required: the revision you read (so that a concurrent change is never overwritten)",
                       loc=("revision",), path="revision")
    if isinstance(body_value, bool) or not isinstance(body_value, int) or body_value < 1:
        raise _invalid("must be an integer >= 1", loc=("revision",), path="revision")
    return body_value


@router.put(
    "/shows/{show_id}",
    response_model=ShowOut,
    summary="Replace a show (revision-checked)",
    responses=error_responses(404, 409, 413, 422),
    openapi_extra={"requestBody": {"required": True, "content": _UPDATE_CONTENT}},
)
async def update_show(request: Request, show_id: str, draft: bool = _DRAFT_QUERY) -> Response:
    """Replace the show if it is still at ``revision``; the answer carries the new revision.

    Body: ``{"revision": r, "show": {...}}``, or the bare show file with the revision
    in an ``If-Match: "r"`` header. A stale revision gets 409 with
    ``current_revision``; nothing is overwritten. Saving identical content keeps the revision.
    With ``?draft=true`` a show that breaks the rules is saved as a draft; saving it valid
    later (with or without the flag) makes it a show again.
    """
    raw = await request.body()
    if not raw.strip():
        raise _invalid("the body is empty; send {\"revision\": r, \"show\": {...}}")
    # Megabytes of JSON take a second to parse: off the event loop (other clients' requests go on).
    body = _load_json(raw) if len(raw) <= INLINE_JSON_BYTES else await asyncio.to_thread(_load_json, raw)
    if not isinstance(body, dict):
        raise _invalid("must be a JSON object {\"revision\": r, \"show\": {...}}")
    if "show" in body and "format" not in body:
        unknown = sorted(set(body) - {"revision", "show"})
        if unknown:
            raise _invalid(f"unknown field {unknown[0]!r} (expected 'revision' and 'show')", loc=(unknown[0],),
                           path=unknown[0])
        revision = _revision_from(body.get("revision"), request.headers.get("if-match"))
        show_data = body["show"]
        prefix: tuple[str, ...] = ("show",)
        if not isinstance(show_data, dict):
            raise _invalid("must be a show file object", loc=prefix, path="show")
    else:
        revision = _revision_from(None, request.headers.get("if-match"))
        show_data, prefix = body, ()
    store = deps.store(request)
    current = store.get_revision_number(show_id)
    if current != revision:
        # Stale before any work: no validating megabytes only to refuse them (the write re-checks atomically).
        raise RevisionConflict(show_id, expected=revision, current=current)
    show = await _parse_show(request, show_data, size=len(raw), prefix=prefix, draft=draft)
    record = await deps.write(request, store.update, show_id, show, expected_revision=revision)
    return _show_response(request, record)


@router.delete(
    "/shows/{show_id}", status_code=204, summary="Delete a show", responses=error_responses(404, 409),
    response_class=Response,
)
async def delete_show(
    request: Request,
    show_id: str,
    revision: int | None = Query(None, ge=1, description="Delete only if the show is still at this revision."),
) -> Response:
    """Delete the show (only at ``revision`` when given: a stale one gets 409)."""
    await deps.write(request, deps.store(request).delete, show_id, expected_revision=revision)
    return Response(status_code=204)


@router.post(
    "/shows/{show_id}/check",
    response_model=CheckOut,
    summary="Plan and verify a show",
    responses=error_responses(404, 422),
)
async def check_show(request: Request, show_id: str) -> JSONResponse:
    """Plan the stored show with CAPT and verify it exactly (separation, speeds, acceleration, altitude).

    Runs in a worker process; an unchanged show is answered from the cache (``cached``).
    A transition forced shorter than the limits allow is reported as a violation, not an error.
    A draft is refused with 422 (``draft: true``, a plain-words ``message`` and every problem).
    """
    record = require_valid(deps.store(request).get(show_id), "checked")
    result, cached = await deps.jobs(request).run_cached(
        "check", record.content_hash, {}, tasks.check_task, record.json, gone=request.is_disconnected
    )
    return JSONResponse({
        "show_id": record.id, "revision": record.revision, "content_hash": record.content_hash,
        "cached": cached, **result,
    })


@router.post(
    "/shows/{show_id}/simulate",
    status_code=202,
    response_model=JobOut,
    summary="Fly a show in simulation (background job)",
    responses=error_responses(404, 422, 429),
)
async def simulate_show(
    request: Request, show_id: str, options: Annotated[SimulateOptions | None, Body()] = None
) -> JSONResponse:
    """Start a simulation job and answer 202 with it (``Location`` points at the job).

    Follow it with ``GET /api/jobs/{id}`` or the server-sent events of
    ``GET /api/jobs/{id}/events``; cancel it with ``DELETE /api/jobs/{id}``. An
    unchanged show simulated before with the same options gives a job that is
    already done (``cached``); the same simulation already running is shared. A draft
    is refused with 422 saying what is wrong.
    """
    record = require_valid(deps.store(request).get(show_id), "simulated")
    assert record.json is not None  # ShowStore.get always loads the text (shows.json is NOT NULL)
    opts = (options or SimulateOptions()).model_dump()
    manager = deps.jobs(request)
    job = await asyncio.to_thread(
        manager.submit, "simulate", tasks.simulate_task, show_text=record.json,
        content_hash=record.content_hash, options=opts, show_id=record.id, show_revision=record.revision,
        client=deps.client_id(request), task_options=tasks.flight_options(opts, manager.settings.dask_scheduler),
    )
    return JSONResponse(job_body(job.snapshot()), status_code=202, headers={"Location": f"/api/jobs/{job.id}"})


#: Export formats that carry the show's music.
AUDIO_FORMATS = ("skyc", "viser-html")


def _audio_track(request: Request, show_id: str) -> Any:
    """The show's stored music as an ``app.media.AudioTrack``, or None."""
    from app.media import AudioTrack, sniff_container

    store = deps.store(request)
    rec = store.get_audio(show_id, analysis=True)
    if rec is None:
        return None
    data = store.read_audio(show_id)
    duration = float(json.loads(rec.analysis or "{}").get("duration_s") or 0.0)
    return AudioTrack(data=data, container=sniff_container(data) or "mp3", media_type=rec.media_type,
                      filename=rec.filename, duration_s=duration)


@router.post(
    "/shows/{show_id}/montecarlo",
    status_code=202,
    response_model=JobOut,
    summary="Fly a show K times for its safety margin (background job)",
    responses=error_responses(404, 422, 429),
)
async def montecarlo_show(
    request: Request, show_id: str, options: Annotated[MonteCarloOptions | None, Body()] = None
) -> JSONResponse:
    """Start a Monte-Carlo job: the show flown ``runs`` times with seeds ``seed0 .. seed0 + runs - 1``
    under the error-model ``preset``; answers 202 with the job (``Location`` points at it).

    Follow it like a simulation (``GET /api/jobs/{id}``, ``/events``); when done its result holds
    the flown-separation distribution per segment, the probabilities of coming closer than the
    minimum and the collision distance with their intervals, the worst pairs, deviations and the
    extra spacing per segment, and ``GET /api/jobs/{id}/report.html`` (or ``.pdf``) draws the
    safety report. A run's flight plays in the 3D view with ``POST /api/shows/{id}/playback``
    ``{"source": "simulated", "job_id": ..., "run": k}``.
    """
    record = deps.store(request).get(show_id)
    assert record.json is not None  # ShowStore.get always loads the text (shows.json is NOT NULL)
    opts = (options or MonteCarloOptions()).model_dump()
    manager = deps.jobs(request)
    resolved = tasks.flight_options({**opts, "engine": "numba"}, manager.settings.dask_scheduler)
    job = await asyncio.to_thread(
        manager.submit, "montecarlo", tasks.montecarlo_task, show_text=record.json,
        content_hash=record.content_hash, options=opts, show_id=record.id, show_revision=record.revision,
        client=deps.client_id(request), task_options=resolved,
    )
    return JSONResponse(job_body(job.snapshot()), status_code=202, headers={"Location": f"/api/jobs/{job.id}"})


def export_formats() -> tuple[str, ...]:
    """Every format ``GET /api/shows/{id}/export/{fmt}`` serves (``show`` first)."""
    try:
        from app.exports import EXPORT_FORMATS
    except ImportError:
        return ("show",)
    return ("show", *(f for f in EXPORT_FORMATS if f != "show"))


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "-", name).strip("-.") or "show"


def _query_problem(exc: Any) -> ApiError:
    """An ``app.exports.ExportError`` about a query option as the 422 naming it (``loc`` ``["query", field]``)."""
    field = exc.field or "format"
    return ApiError(422, [{"loc": ["query", field], "path": field, "msg": str(exc)}])


def _parse_origin(origin: str) -> tuple[float, float, float]:
    """The ``origin`` query as ``(lat, lon, alt_m)``, as the CLI's ``--origin`` (``app.exports.parse_origin``)."""
    from app.exports import ExportError, parse_origin

    try:
        return parse_origin(origin)
    except ExportError as exc:
        raise _query_problem(exc) from None


def _parse_offset(offset: str) -> tuple[float, float, float]:
    try:
        values = tuple(float(v) for v in offset.split(","))
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ApiError(422, [{"loc": ["query", "offset"], "path": "offset", "msg": "must be 'x,y,z' in metres"}])
    return values[0], values[1], values[2]


_PRESET_HELP = (f"With source=simulated: the flight's error-model preset (default {DEFAULT_FLIGHT_PRESET!r}, as a "
                "simulation): the file holds the single flight the simulation panel flies.")


def _check_options(fmt: str, **options: Any) -> None:
    """Refuse what the exporter refuses (``app.exports.check_export_options``: an option the format does not use,
    a flown source for a format of the exact plan, a value out of range), 422 naming the query option, before
    any work; the ``show`` download, served from the store without an exporter, is checked the same way."""
    from app.exports import ExportError, check_export_options

    try:
        check_export_options(fmt, **options)
    except ExportError as exc:
        raise _query_problem(exc) from None


@router.get(
    "/shows/{show_id}/export/{fmt}",
    summary="Export a show",
    response_class=Response,
    responses={
        200: {"description": "The exported file (attachment).", "content": {
            "application/json": {}, "application/zip": {}, "text/csv": {}, "text/plain": {}, "text/html": {},
            "application/octet-stream": {}}},
        **error_responses(404, 422),
    },
)
async def export_show(
    request: Request,
    show_id: str,
    fmt: str,
    fps: float | None = Query(None, gt=0, le=1000, description=(
        "Sample rate, Hz, of the formats that sample (skybrush-csv, waypoints-csv, viser-html; the others refuse "
        "it with 422).")),
    origin: str | None = Query(None, description=(
        "Geographic origin 'lat,lon[,alt_m]' of the formats that place the show on Earth (skyc, qgc-plan, "
        "qgc-wpl; the others refuse it with 422). Default: the show's settings.geo.")),
    # The bounds are app.exports.MAX_HEADING_DEG, which the CLI's --heading shares (a test keeps them equal).
    heading_deg: float | None = Query(None, ge=-360, le=360, description=(
        "Direction of the show's +y axis, degrees clockwise from north (default: the show's settings.geo "
        "heading, else 0; given, it turns the show about its stored origin; the show file refuses it with 422: "
        "its heading is in settings.geo).")),
    source: Literal["planned", "simulated"] = Query("planned", description="Planned or simulated trajectories."),
    scale: float = Query(1.0, gt=0, le=10, description=(
        "Scale factor for positions (crazyswarm only, indoor shows; other formats refuse it with 422).")),
    offset: str | None = Query(None, description=(
        "'x,y,z' metres added after scaling (crazyswarm only; other formats refuse it with 422 unless it is "
        "0,0,0, which moves nothing).")),
    preset: Annotated[PresetName | None, Query(description=_PRESET_HELP)] = None,
    seed: int | None = Query(None, ge=0, le=MAX_SEED, description=(
        "With source=simulated: the flight's seed (default 0; the same seed flies the same flight).")),
    controller: Annotated[ControllerName | None, Query(description=(
        "With source=simulated: the flight's controller (default 'ismc'; 'baseline': cascaded PD), as the "
        "simulation's."))] = None,
    disturbance: Annotated[DisturbanceName | None, Query(description=(
        "With source=simulated: the fleet-wide disturbance; only with preset 'ideal' (implied when no preset is "
        "given), as the simulation's."))] = None,
) -> Response:
    """Download the show as ``fmt``: ``show`` (the show file, straight from the store) or any
    format of ``swarmshow export`` (``skybrush-csv``, ``skyc``, ``crazyswarm``, ``qgc-plan``,
    ``qgc-wpl``, ``waypoints-csv``, ``viser-html``). Warnings go in ``X-Swarmshow-Warnings`` (JSON list).
    A draft downloads only as ``show``; every other format refuses it with 422 saying what is wrong."""
    formats = export_formats()
    if fmt not in formats:
        raise ApiError(404, f"unknown export format {fmt!r}; one of: {', '.join(formats)}")
    origin_v = _parse_origin(origin) if origin is not None else None
    offset_m = _parse_offset(offset) if offset is not None else (0.0, 0.0, 0.0)
    _check_options(fmt, fps=fps, origin=origin_v, heading_deg=heading_deg, source=source, scale=scale,
                   offset_m=offset_m, preset=preset, seed=seed, controller=controller, disturbance=disturbance)
    record = deps.store(request).get(show_id)
    if fmt != "show":
        # The show file itself downloads as it is (a draft too: it is the user's work); every other
        # format needs a plan.
        require_valid(record, "exported")
    if fmt == "show":
        # Served as stored, without the exporter (its options were checked as the exporter checks them, above).
        show_text = record.json
        assert show_text is not None  # ShowStore.get always loads the text (shows.json is NOT NULL)

        def pretty() -> str:
            return json.dumps(json.loads(show_text), indent=2) + "\n"

        # Re-indenting megabytes is CPU work: off the event loop for large shows.
        text = pretty() if len(show_text) <= INLINE_JSON_BYTES else await asyncio.to_thread(pretty)
        return Response(text, media_type="application/json", headers={
            "Content-Disposition": f'attachment; filename="{_slug(record.name)}.json"',
            "ETag": f'"{record.revision}"'})
    options: dict[str, Any] = {"source": source}
    if heading_deg is not None:
        options["heading_deg"] = heading_deg
    if fps is not None:
        options["fps"] = fps
    if origin_v is not None:
        options["origin"] = origin_v
    if fmt in AUDIO_FORMATS:
        audio = await asyncio.to_thread(_audio_track, request, show_id)
        if audio is not None:
            options["audio"] = audio  # issue 18: the show's music goes into the file
    if scale != 1.0:
        options["scale"] = scale
    if offset is not None:
        options["offset_m"] = offset_m
    if preset is not None:
        options["preset"] = preset
    if seed is not None:
        options["seed"] = seed
    if controller is not None:
        options["controller"] = controller
    if disturbance is not None:
        options["disturbance"] = disturbance
    out = await deps.run(request, tasks.export_task, record.json, fmt, options)
    return Response(out["content"], media_type=out["media_type"], headers={
        "Content-Disposition": f'attachment; filename="{_slug(out["filename"])}"',
        "X-Swarmshow-Warnings": json.dumps(out["warnings"]),
    })
