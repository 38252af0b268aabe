"""``POST /api/formations/{shape|text|image|svg|mesh}``: formation points and colours from a source;
``POST /api/formations/home-csv``: home positions from a CSV file."""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from fastapi import APIRouter, File, Form, Request, UploadFile
from starlette.concurrency import run_in_threadpool

from app import tasks
from app.api import deps
from app.api.errors import ApiError
from app.api.models import FormationPoints, HomePoints, Plane, ShapeRequest, TextRequest, error_responses
from app.web import BodyTooLarge
from formations import MAX_HOME_CSV_BYTES, HomeCsvError, home_points_from_csv, source_name
from formations.sources import nearest_pair_distance

router = APIRouter(prefix="/formations", tags=["formations"])

_ERRORS = error_responses(422)
_UPLOAD_ERRORS = error_responses(413, 422)
_CENTER_DOC = "Centre 'x,y,z' in metres (a JSON array works too)."


@router.post("/shape", response_model=FormationPoints, summary="Points of a preset shape", responses=_ERRORS)
async def shape(request: Request, body: ShapeRequest) -> dict[str, Any]:
    """``n`` points of a grid, circle, polygon, star, heart, sphere, helix or cube, at least
    ``min_spacing_m`` apart. If they do not fit, 422 says how many do (``max_n``)."""
    params = body.model_dump()
    out = await deps.run(request, tasks.formation_task, "shape", params, None)
    return {**out, "name": source_name("shape", text=body.kind)}


@router.post("/text", response_model=FormationPoints, summary="Points spelling a text", responses=_ERRORS)
async def text(request: Request, body: TextRequest) -> dict[str, Any]:
    """``n`` points spread over the letters of ``text``."""
    out = await deps.run(request, tasks.formation_task, "text", body.model_dump(), None)
    return {**out, "name": source_name("text", text=body.text)}


def _center(value: str) -> list[float]:
    try:
        parts = [float(v) for v in value.strip().strip("[]").split(",")]
    except ValueError:
        parts = []
    if len(parts) != 3 or not all(math.isfinite(v) for v in parts):
        raise ApiError(422, [{"loc": ["body", "center_m"], "path": "center_m", "msg": "must be three numbers 'x,y,z'"}])
    return parts


async def _read(file: UploadFile, *, limit: int, what: str) -> bytes:
    data = await file.read(limit + 1)
    if len(data) > limit:
        raise BodyTooLarge(what, limit)
    if not data:
        raise ApiError(422, [{"loc": ["body", "file"], "path": "file", "msg": "the uploaded file is empty"}])
    return data


@router.post("/image", response_model=FormationPoints, summary="Points from an image", responses=_UPLOAD_ERRORS)
async def image(
    request: Request,
    file: Annotated[UploadFile, File(description="PNG or JPEG, at most 40 megapixels.")],
    n: Annotated[int, Form(ge=1, le=20_000, description="Number of points.")],
    width_m: Annotated[float, Form(ge=0.01, le=10_000, description="Width of the whole image, m.")] = 40.0,
    center_m: Annotated[str, Form(description=_CENTER_DOC)] = "0,0,30",
    plane: Annotated[Plane, Form()] = "xz",
    min_spacing_m: Annotated[float, Form(ge=0.01, le=100)] = 3.0,
    mode: Annotated[Literal["auto", "bright", "alpha"], Form(
        description="Pixels to fill: opaque if the image has transparency, else bright ('auto').")] = "auto",
) -> dict[str, Any]:
    """``n`` points spread over the bright (or opaque) pixels, each with its pixel's colour."""
    limit = deps.settings(request).max_image_bytes
    data = await _read(file, limit=limit, what="an image")
    params = {"n": n, "width_m": width_m, "center_m": _center(center_m), "plane": plane,
              "min_spacing_m": min_spacing_m, "mode": mode}
    out = await deps.run(request, tasks.formation_task, "image", params, data)
    return {**out, "name": source_name("image", filename=file.filename or "")}


@router.post("/svg", response_model=FormationPoints, summary="Points from an SVG drawing", responses=_UPLOAD_ERRORS)
async def svg(
    request: Request,
    file: Annotated[UploadFile, File(description="An SVG file, at most 5 MB.")],
    n: Annotated[int, Form(ge=1, le=20_000, description="Number of points.")],
    width_m: Annotated[float, Form(ge=0.01, le=10_000, description="Width of the drawing, m.")] = 40.0,
    center_m: Annotated[str, Form(description=_CENTER_DOC)] = "0,0,30",
    plane: Annotated[Plane, Form()] = "xz",
    min_spacing_m: Annotated[float, Form(ge=0.01, le=100)] = 3.0,
    color: Annotated[str | None, Form(
        pattern=r"^#[0-9a-fA-F]{6}$", description="LED colour of every point (default: the drawing's own).")] = None,
) -> dict[str, Any]:
    """``n`` points along the drawing's strokes and fills."""
    limit = deps.settings(request).max_svg_bytes
    data = await _read(file, limit=limit, what="an SVG file")
    params = {"n": n, "width_m": width_m, "center_m": _center(center_m), "plane": plane,
              "min_spacing_m": min_spacing_m, "color": color}
    out = await deps.run(request, tasks.formation_task, "svg", params, data)
    return {**out, "name": source_name("svg", filename=file.filename or "")}


_MESH_TYPES = ("obj", "ply", "stl", "glb", "gltf", "csv", "xyz")


def _file_type(declared: str | None, filename: str | None) -> str:
    """The file format: ``format`` if given, else the upload's file-name extension."""
    ext = (declared or (filename or "").rsplit(".", 1)[-1]).strip().lower()
    ext = {"txt": "xyz", "xyzrgb": "xyz", "pts": "xyz"}.get(ext, ext)
    if ext not in _MESH_TYPES:
        raise ApiError(422, [{"loc": ["body", "format"], "path": "format",
                              "msg": f"unknown file format {ext!r}; use one of {', '.join(_MESH_TYPES)}"}])
    return ext


@router.post("/mesh", response_model=FormationPoints, summary="Points from a mesh or point file",
             responses=_UPLOAD_ERRORS)
async def mesh(
    request: Request,
    file: Annotated[UploadFile, File(description="OBJ, PLY, STL, glTF (embedded buffers) or GLB mesh; or a "
                                     "Skybrush CSV (Name,x,y,z,Red,Green,Blue) or XYZ(RGB) point file. At most "
                                     "50 MB, 1M faces / vertices.")],
    n: Annotated[int, Form(ge=1, le=20_000, description="Number of points.")],
    mode: Annotated[Literal["vertices", "surface", "volume"], Form(
        description="Mesh vertices, even points over the surface, or a filled volume (closed meshes).")] = "surface",
    size_m: Annotated[float | None, Form(gt=0, le=10_000, description=(
        "Largest side of the bounding box, m; empty = the smallest size that keeps min_spacing_m "
        "(point files keep their own metres)."))] = None,
    center_m: Annotated[str, Form(description=_CENTER_DOC)] = "0,0,30",
    min_spacing_m: Annotated[float, Form(ge=0.01, le=100)] = 3.0,
    up: Annotated[Literal["auto", "y", "z"], Form(
        description="The file's up axis (auto: +Y for glTF/GLB, +Z otherwise).")] = "auto",
    format: Annotated[str | None, Form(description="File format (default: from the file name).")] = None,
    color: Annotated[str, Form(pattern=r"^#[0-9a-fA-F]{6}$",
                               description="LED colour of points the file gives no colour.")] = "#ffffff",
) -> dict[str, Any]:
    """``n`` points from a mesh (vertices, surface or volume) or point file, in the file's vertex
    colours or texture. If they do not fit, 422 says the largest N (``max_n``) and the size that
    fits N (``fit_size_m``)."""
    file_type = _file_type(format, file.filename)
    limit = deps.settings(request).max_mesh_bytes
    data = await _read(file, limit=limit, what="a mesh or point file")
    params = {"n": n, "file_type": file_type, "mode": mode, "size_m": size_m, "center_m": _center(center_m),
              "min_spacing_m": min_spacing_m, "up": up, "color": color}
    out = await deps.run(request, tasks.formation_task, "mesh", params, data)
    return {**out, "name": source_name("mesh", filename=file.filename or "")}


@router.post("/home-csv", response_model=HomePoints, summary="Home positions from a CSV file",
             responses=_UPLOAD_ERRORS)
async def home_csv(
    file: Annotated[UploadFile, File(description="Skybrush-style 'Name,x,y,z' rows or plain 'x,y[,z]' rows "
                                     "(metres; an optional header row). At most 4 MB, 100,000 rows.")],
) -> dict[str, Any]:
    """Home positions for ``home.points`` (the show file then validates their spacing). A line that
    cannot be read is a 422 naming ``file`` and the line."""
    data = await _read(file, limit=MAX_HOME_CSV_BYTES, what="a home CSV")
    try:
        points, names = await run_in_threadpool(home_points_from_csv, data)
    except HomeCsvError as exc:
        raise ApiError(422, [{"loc": ["body", "file"], "path": "file", "msg": str(exc)}]) from exc
    d = nearest_pair_distance(points) if len(points) > 1 else None
    return {"points": points, "names": names, "count": len(points), "min_spacing_m": d}
