"""A show's music: upload (checked and analysed in a worker), stream with HTTP ranges, analysis, delete."""

from __future__ import annotations

import json
import re
from typing import Any

from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import JSONResponse, StreamingResponse
from pydantic import BaseModel

from app.api import deps
from app.api.errors import ApiError
from app.api.models import error_responses
from app.media import MAX_AUDIO_BYTES, AudioError, analyse_audio
from app.web import BodyTooLarge

router = APIRouter(tags=["audio"])

#: Time budget of decoding and analysing one upload, seconds (librosa's kernels compile on a worker's
#: first analysis; a 20-minute track then takes seconds).
ANALYSIS_BUDGET_S = 300.0
#: Bytes sent per chunk of a streamed answer.
CHUNK_BYTES = 256 * 1024

_UPLOAD_CONTENT = {
    "application/octet-stream": {"schema": {"type": "string", "format": "binary"}},
    "multipart/form-data": {
        "schema": {
            "type": "object",
            "properties": {"file": {"type": "string", "format": "binary", "description": "WAV, MP3, OGG or FLAC."}},
            "required": ["file"],
        }
    },
}
_RANGE = re.compile(r"^bytes=(\d*)-(\d*)$")


class AudioInfoOut(BaseModel):
    """What the server keeps of a show's music."""

    show_id: str
    filename: str
    media_type: str
    size: int
    sha256: str
    duration_s: float | None
    sample_rate_hz: int | None
    channels: int | None
    tempo_bpm: float | None
    beats: int
    onsets: int
    url: str
    analysis_url: str


class AudioAnalysisOut(BaseModel):
    """Waveform peaks (min, max pairs, -127..127, ``peaks_per_s`` pairs a second), beats and onsets."""

    container: str
    media_type: str
    sample_rate_hz: int
    channels: int
    duration_s: float
    peaks_per_s: int
    peaks: list[int]
    tempo_bpm: float | None = None
    beats_s: list[float] = []
    onsets_s: list[float] = []


_AUDIO_TYPES: dict[str, dict[str, Any]] = {t: {} for t in ("audio/wav", "audio/mpeg", "audio/ogg", "audio/flac")}
_ERROR_JSON = {"application/json": {"schema": {"$ref": "#/components/schemas/ErrorOut"}}}


def _bad(msg: str, status: int = 422, field: str = "file") -> ApiError:
    return ApiError(status, [{"loc": ["body", field], "path": field, "msg": msg}])


def _max_bytes(request: Request) -> int:
    return int(getattr(deps.settings(request), "max_audio_bytes", MAX_AUDIO_BYTES))


async def _read_upload(request: Request, max_bytes: int) -> tuple[bytes, str | None]:
    """The file's bytes and its name from a raw or multipart (``file`` part) body."""
    name: str | None = None
    if request.headers.get("content-type", "").startswith("multipart/form-data"):
        form = await request.form(max_files=1, max_fields=10)
        try:
            upload = form.get("file")
            if upload is None or isinstance(upload, str):
                raise _bad("a multipart upload needs a 'file' part holding the audio file")
            name = upload.filename
            data = await upload.read(max_bytes + 1)
        finally:
            await form.close()
        if len(data) > max_bytes:
            raise BodyTooLarge("an audio file ('file')", max_bytes, size=None)
    else:
        data = await request.body()
        if len(data) > max_bytes:
            raise BodyTooLarge("an audio file ('file')", max_bytes, size=len(data))
    return data, name


def _clean_name(name: str | None) -> str:
    base = (name or "audio").replace("\\", "/").rsplit("/", 1)[-1]
    base = re.sub(r"[^A-Za-z0-9._ +-]+", "_", base).strip(" .") or "audio"
    return base[:120]


def _summary(show_id: str, filename: str, media_type: str, size: int, sha256: str,
             analysis: dict[str, Any]) -> dict[str, Any]:
    return {
        "show_id": show_id, "filename": filename, "media_type": media_type, "size": size, "sha256": sha256,
        "duration_s": analysis.get("duration_s"), "sample_rate_hz": analysis.get("sample_rate_hz"),
        "channels": analysis.get("channels"), "tempo_bpm": analysis.get("tempo_bpm"),
        "beats": len(analysis.get("beats_s", [])), "onsets": len(analysis.get("onsets_s", [])),
        "url": f"/api/shows/{show_id}/audio", "analysis_url": f"/api/shows/{show_id}/audio/analysis",
    }


@router.put(
    "/shows/{show_id}/audio",
    status_code=201,
    response_model=AudioInfoOut,
    summary="Upload a show's music (WAV, MP3, OGG or FLAC)",
    responses={**error_responses(404, 413, 422),
               415: {"description": "Not a WAV, MP3, OGG or FLAC file.", "content": _ERROR_JSON}},
    openapi_extra={"requestBody": {"required": True, "content": _UPLOAD_CONTENT}},
)
async def put_audio(
    request: Request, show_id: str,
    filename: str | None = Query(None, max_length=200, description="The file's name (raw uploads)."),
) -> JSONResponse:
    """Store the show's music, replacing any. The file is decoded completely in a worker first (bounded
    duration, channels and rate; a truncated or non-audio file is refused, naming ``file``), its waveform
    peaks, beats and onsets computed; nothing is stored unless all of that succeeds."""
    store = deps.store(request)
    store.get_revision_number(show_id)  # 404 before reading megabytes
    data, part_name = await _read_upload(request, _max_bytes(request))
    if not data:
        raise _bad("the file is empty (0 bytes); upload a WAV, MP3, OGG or FLAC file")
    try:
        analysis = await deps.jobs(request).run(analyse_audio, data, gone=request.is_disconnected,
                                                budget_s=ANALYSIS_BUDGET_S)
    except AudioError as exc:
        raise _bad(exc.msg, exc.status, exc.field) from None
    except MemoryError:
        raise _bad("decoding this file needs more memory than a worker may use", 413) from None
    name = _clean_name(filename or part_name)
    record = await deps.write(request, store.put_audio, show_id, filename=name, media_type=analysis["media_type"],
                              data=data, analysis=json.dumps(analysis, separators=(",", ":")))
    return JSONResponse(_summary(show_id, name, record.media_type, record.size, record.sha256, analysis),
                        status_code=201)


@router.post(
    "/shows/{show_id}/audio/copy",
    status_code=201,
    response_model=AudioInfoOut,
    summary="Give a show the music of another show (e.g. after saving it as a copy)",
    responses={**error_responses(404), 204: {"description": "The other show has no music: nothing copied."}},
)
async def copy_audio(
    request: Request, show_id: str,
    from_show: str = Query(..., alias="from", min_length=1, max_length=200,
                           description="The show whose music is copied."),
) -> Response:
    """Copy the stored track (bytes and analysis, replacing this show's) inside the store: no upload, no
    second decode. 204 when ``from`` has no music; 404 naming a show that does not exist."""
    record = await deps.write(request, deps.store(request).copy_audio, from_show, show_id)
    if record is None:
        return Response(status_code=204)
    r = _record(request, show_id, analysis=True)
    return JSONResponse(_summary(show_id, r.filename, r.media_type, r.size, r.sha256, json.loads(r.analysis)),
                        status_code=201)


def _record(request: Request, show_id: str, *, analysis: bool = False) -> Any:
    store = deps.store(request)
    record = store.get_audio(show_id, analysis=analysis)
    if record is None:
        store.get_revision_number(show_id)  # 404 naming the show when there is no show
        raise ApiError(404, f"show {show_id!r} has no audio track")
    return record


@router.get("/shows/{show_id}/audio/info", response_model=AudioInfoOut,
            summary="A show's music: name, type, size, duration, tempo",
            responses=error_responses(404))
async def audio_info(request: Request, show_id: str) -> JSONResponse:
    """What :func:`put_audio` answered for the stored track."""
    r = _record(request, show_id, analysis=True)
    return JSONResponse(_summary(show_id, r.filename, r.media_type, r.size, r.sha256, json.loads(r.analysis)))


@router.get("/shows/{show_id}/audio/analysis", summary="Waveform peaks, beats and onsets of a show's music",
            response_model=AudioAnalysisOut, responses=error_responses(404))
async def audio_analysis(request: Request, show_id: str) -> Response:
    """``{duration_s, peaks_per_s, peaks: [min0, max0, min1, max1, ...] (-127..127), tempo_bpm, beats_s, onsets_s}``."""
    r = _record(request, show_id, analysis=True)
    return Response(r.analysis, media_type="application/json", headers={"ETag": f'"{r.sha256[:32]}"'})


@router.get("/shows/{show_id}/audio", summary="Stream a show's music (HTTP ranges)", response_class=Response,
            responses={200: {"description": "The audio file.", "content": _AUDIO_TYPES},
                       206: {"description": "A byte range of it.", "content": _AUDIO_TYPES}, **error_responses(404),
                       416: {"description": "The range is outside the file.", "content": _ERROR_JSON}})
async def get_audio(request: Request, show_id: str) -> Response:
    """The stored file as uploaded; a ``Range: bytes=a-b`` request gets 206 with that part, so that the
    browser's audio element can seek without downloading the whole track."""
    r = _record(request, show_id)
    size = int(r.size)
    start, end = 0, size - 1
    status = 200
    headers = {"Accept-Ranges": "bytes", "ETag": f'"{r.sha256[:32]}"', "Cache-Control": "no-cache"}
    spec = request.headers.get("range")
    if spec:
        m = _RANGE.match(spec.strip())
        if m is None or (not m.group(1) and not m.group(2)):
            raise ApiError(416, "Range must be one 'bytes=start-end' range",
                           headers={"Content-Range": f"bytes */{size}"})
        if m.group(1):
            start = int(m.group(1))
            end = min(int(m.group(2)), size - 1) if m.group(2) else size - 1
        else:  # a suffix: the last n bytes
            start = max(0, size - int(m.group(2)))
        if start >= size or end < start:
            raise ApiError(416, f"range {spec!r} is outside the file's {size} bytes",
                           headers={"Content-Range": f"bytes */{size}"})
        status = 206
        headers["Content-Range"] = f"bytes {start}-{end}/{size}"
    headers["Content-Length"] = str(end - start + 1)
    store = deps.store(request)
    if request.method == "HEAD":
        return Response(status_code=status, headers=headers, media_type=r.media_type)

    async def chunks() -> Any:
        pos = start
        while pos <= end:
            n = min(CHUNK_BYTES, end - pos + 1)
            yield store.read_audio(show_id, pos, n)
            pos += n

    return StreamingResponse(chunks(), status_code=status, headers=headers, media_type=r.media_type)


@router.delete("/shows/{show_id}/audio", status_code=204, summary="Remove a show's music", response_class=Response,
               responses=error_responses(404))
async def delete_audio(request: Request, show_id: str) -> Response:
    """Remove the show's music (404 when it has none)."""
    _record(request, show_id)
    await deps.write(request, deps.store(request).delete_audio, show_id)
    return Response(status_code=204)
