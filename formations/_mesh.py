"""Mesh and point-file sources: OBJ, PLY, STL, glTF/GLB (via trimesh) as vertices, surface or
volume points; Skybrush static CSV and XYZ(RGB) point files (metres, ENU).

Every file is checked against byte, vertex and face limits *before* it is parsed (the counts a
binary header declares must match the bytes it holds, so a GLB or PLY cannot promise a small
file and allocate a huge one), and every coordinate must be finite. Points are picked from
dense candidates (area-weighted random surface samples, interior voxel centres or the distinct
vertices) by farthest-point order, which spreads them evenly (blue noise) and makes the
achieved spacing of any prefix known exactly; surface picks are then relaxed on the faces toward
the hexagonal packing (:func:`relax_on_surface`, about 1.3x the density of the picks alone).
Picking works in unit-sized coordinates, so the size that fits N at the minimum spacing is a
closed form, and the largest N that fits a given size is a count (the farthest-point prefix, or
the count the relaxed density predicts, verified).
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
import struct
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from formations._image import MAX_IMAGE_PIXELS
from formations._points import (
    FormationError,
    InputTooLargeError,
    PointSet,
    check_center,
    check_n,
    check_positive,
    nearest_pair_distance,
    parse_color,
)
from formations._spacing import ensure_spacing, farthest_point_order, largest_fitting

#: Mesh file formats (trimesh file types).
MESH_FORMATS: tuple[str, ...] = ("obj", "ply", "stl", "glb", "gltf")
#: Point-file formats: Skybrush static CSV (``Name,x,y,z,Red,Green,Blue``) and XYZ(RGB) text.
POINT_FORMATS: tuple[str, ...] = ("csv", "xyz")
#: How a mesh becomes points.
MESH_MODES: tuple[str, ...] = ("vertices", "surface", "volume")
#: Up axis of the file: "auto" is +Y for glTF/GLB (the glTF convention) and +Z otherwise.
UP_AXES: tuple[str, ...] = ("auto", "y", "z")
#: Largest mesh or point file accepted, bytes.
MAX_MESH_BYTES = 50 * 1024 * 1024
#: Most faces (triangles) and vertices a mesh may have.
MAX_MESH_FACES = 1_000_000
MAX_MESH_VERTICES = 1_000_000
#: Most rows of a point file.
MAX_POINT_ROWS = 500_000
#: Surface candidates: the same for every N, so the farthest-point order is the same for every N
#: and the largest N that fits (a prefix) and the size that fits N are exactly what a request for
#: them gets. Farthest-point sampling costs N x candidates (20,000 of 100,000: about a second of
#: CPU), which bounds a request.
SURFACE_CANDIDATES = 100_000
#: Volume candidates: interior voxel centres, about this many per wanted point (a grid much finer
#: than the spacing would let farthest-point picks hug the boundary; this one fills the inside),
#: at most VOLUME_CANDIDATES. Since the grid depends on N, the largest N that fits is found by
#: bisection over fresh requests (:func:`formations._spacing.largest_fitting`).
VOLUME_CANDIDATES_PER_POINT = 24
VOLUME_CANDIDATES = 100_000
#: Most voxels of the volume grid (its bounding box), bounds memory of the fill.
MAX_VOXELS = 4_000_000
#: Most faces the voxelisation's subdivision may make (area / pitch^2).
MAX_SUBDIVIDED_FACES = 4_000_000
_TOL = 1e-6
_MARGIN = 1e-7


class MeshFitError(FormationError):
    """``n`` points do not fit; ``max_n`` fits at the given size and ``fit_size_m`` fits ``n``."""

    def __init__(self, message: str, *, max_n: int, fit_size_m: float | None) -> None:
        super().__init__(message, max_n=max_n)
        self.fit_size_m = fit_size_m


def _err(message: str, field: str = "file") -> FormationError:
    exc = FormationError(f"{field}: {' '.join(message.split())}")
    exc.field = field  # type: ignore[attr-defined]
    return exc


def _too_large(message: str, field: str = "file") -> InputTooLargeError:
    exc = InputTooLargeError(f"{field}: {message}")
    exc.field = field  # type: ignore[attr-defined]
    return exc


@dataclass(frozen=True)
class Mesh:
    """A triangle mesh (or a point cloud when ``faces`` is empty) with colour sources.

    Attributes:
        vertices: (V, 3) float64, file units, ENU axes.
        faces: (F, 3) int64 vertex indices.
        vertex_rgb: (V, 3) uint8 colour per vertex (vertex colours, texture at the vertex UV,
            material colour, or the default).
        uv: (V, 2) float64 texture coordinates (NaN where the part has no texture).
        face_texture: (F,) int64 index into ``textures`` (-1: none).
        textures: (H, W, 3) uint8 images.
        face_rgb: (F, 3) uint8 colour of face-coloured faces; ``face_colored`` (F,) bool says which.
    """

    vertices: np.ndarray
    faces: np.ndarray
    vertex_rgb: np.ndarray
    uv: np.ndarray
    face_texture: np.ndarray
    textures: tuple[np.ndarray, ...]
    face_rgb: np.ndarray
    face_colored: np.ndarray


# ----------------------------------------------------------------------------------------------
# Pre-parse checks (declared sizes vs actual bytes)


def _check_counts(vertices: int, faces: int) -> None:
    if vertices > MAX_MESH_VERTICES:
        raise _too_large(f"the mesh has {vertices} vertices; the limit is {MAX_MESH_VERTICES}")
    if faces > MAX_MESH_FACES:
        raise _too_large(f"the mesh has {faces} faces; the limit is {MAX_MESH_FACES}")


def _precheck_stl(data: bytes) -> None:
    # Some exporters start binary headers with "solid" too: binary if the sizes agree or no
    # ASCII "facet" follows.
    binary = len(data) >= 84 and (data[:5].lower() != b"solid"
                                  or 84 + 50 * struct.unpack_from("<I", data, 80)[0] == len(data)
                                  or b"facet" not in data[:4096])
    if binary:
        (count,) = struct.unpack_from("<I", data, 80)
        _check_counts(0, count)
        if 84 + 50 * count != len(data):
            raise _err(f"the binary STL declares {count} triangles ({84 + 50 * count} bytes) "
                       f"but holds {len(data)} bytes")
        return
    _check_counts(0, data.count(b"endfacet"))


_PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
              "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}


def _precheck_ply(data: bytes) -> None:
    end = data.find(b"end_header", 0, 65536)
    if not data.startswith(b"ply") or end < 0:
        raise _err("not a PLY file (no 'ply ... end_header' header in the first 64 KiB)")
    header = data[:end].decode("ascii", "replace").splitlines()
    binary = any(line.startswith("format binary") for line in header)
    counts: dict[str, int] = {}
    need, row, name = 0, 0, ""
    for line in header:
        parts = line.split()
        if parts[:1] == ["element"] and len(parts) == 3:
            need += counts.get(name, 0) * row
            name, row = parts[1], 0
            try:
                counts[name] = int(parts[2])
            except ValueError:
                raise _err(f"bad PLY element line {line!r}") from None
            if counts[name] < 0:
                raise _err(f"bad PLY element count in {line!r}")
        elif parts[:1] == ["property"] and len(parts) >= 3:
            # A list property needs at least its count byte per row.
            row += _PLY_SIZES.get(parts[2], 1) if parts[1] == "list" else _PLY_SIZES.get(parts[1], 1)
    need += counts.get(name, 0) * row
    _check_counts(counts.get("vertex", 0), counts.get("face", 0))
    if binary and need > len(data) - end:
        raise _err(f"the PLY header declares {need} bytes of data but the file holds {len(data) - end}")


def _precheck_obj(data: bytes) -> None:
    v = data.count(b"\nv ") + data.startswith(b"v ")
    f = data.count(b"\nf ") + data.startswith(b"f ")
    _check_counts(v, f)


def _data_uri_bytes(uri: str, what: str) -> int:
    if not uri.startswith("data:"):
        raise _err(f"{what} refers to an external file {uri[:60]!r}; only embedded (data:) buffers are read")
    payload = uri.partition(",")[2]
    return len(payload) * 3 // 4


def _check_gltf(doc: Any, bin_len: int) -> None:
    """Refuse glTF JSON whose buffers, views and accessors declare more than they hold,
    that needs extensions (Draco...), refers to external files, or reuses nodes (a node DAG
    instancing a mesh exponentially many times)."""
    if not isinstance(doc, dict):
        raise _err("the glTF JSON is not an object")
    if doc.get("extensionsRequired"):
        raise _err(f"the glTF requires extensions {doc['extensionsRequired']!r}, which are not supported")
    buf_len: list[int] = []
    for i, b in enumerate(doc.get("buffers") or []):
        declared = int(b.get("byteLength", 0))
        actual = _data_uri_bytes(str(b["uri"]), f"buffers[{i}]") if "uri" in b else bin_len
        if declared > actual + 3 or declared < 0:
            raise _err(f"glTF buffers[{i}] declares {declared} bytes but holds {actual}")
        buf_len.append(declared)
    view_len: list[int] = []
    for i, v in enumerate(doc.get("bufferViews") or []):
        b, off, n = int(v.get("buffer", -1)), int(v.get("byteOffset", 0)), int(v.get("byteLength", 0))
        if not 0 <= b < len(buf_len) or off < 0 or n < 0 or off + n > buf_len[b]:
            raise _err(f"glTF bufferViews[{i}] lies outside its buffer")
        view_len.append(n)
    sizes = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
    comp = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
    accessors = doc.get("accessors") or []
    for i, a in enumerate(accessors):
        count = int(a.get("count", 0))
        elem = sizes.get(str(a.get("type")), 16) * comp.get(int(a.get("componentType", 5126)), 4)
        if count < 0 or count > 3 * MAX_MESH_FACES:
            raise _too_large(f"glTF accessors[{i}] has {count} elements; the limit is {3 * MAX_MESH_FACES} "
                             f"(3 per face, at most {MAX_MESH_FACES} faces)")
        if "bufferView" in a:
            vi = int(a["bufferView"])
            if not 0 <= vi < len(view_len) or int(a.get("byteOffset", 0)) + count * elem > view_len[vi] + elem:
                raise _err(f"glTF accessors[{i}] declares {count} elements, more than its buffer view holds")
    for i, im in enumerate(doc.get("images") or []):
        if "uri" in im:
            _data_uri_bytes(str(im["uri"]), f"images[{i}]")
    children = [c for nd in doc.get("nodes") or [] for c in nd.get("children") or []]
    roots = [r for sc in doc.get("scenes") or [] for r in sc.get("nodes") or []]
    if len(set(children)) != len(children) or set(children) & set(roots):
        raise _err("the glTF node graph uses a node more than once")
    verts = faces = 0
    meshes = doc.get("meshes") or []
    for nd in doc.get("nodes") or []:
        if "mesh" not in nd:
            continue
        mi = int(nd["mesh"])
        for prim in (meshes[mi].get("primitives") or []) if 0 <= mi < len(meshes) else []:
            pos = (prim.get("attributes") or {}).get("POSITION")
            if isinstance(pos, int) and 0 <= pos < len(accessors):
                verts += int(accessors[pos].get("count", 0))
            idx = prim.get("indices")
            if isinstance(idx, int) and 0 <= idx < len(accessors):
                faces += int(accessors[idx].get("count", 0)) // 3
    _check_counts(verts, faces)


def _precheck_glb(data: bytes) -> None:
    if len(data) < 20 or data[:4] != b"glTF":
        raise _err("not a GLB file (no 'glTF' magic)")
    _, length = struct.unpack_from("<II", data, 4)
    if length != len(data):
        raise _err(f"the GLB header declares {length} bytes but the file holds {len(data)}")
    jlen, jtype = struct.unpack_from("<II", data, 12)
    if jtype != 0x4E4F534A or 20 + jlen > len(data):
        raise _err("the GLB JSON chunk is missing or longer than the file")
    bin_len, off = 0, 20 + jlen
    if off + 8 <= len(data):
        blen, btype = struct.unpack_from("<II", data, off)
        if btype == 0x004E4942:
            if off + 8 + blen > len(data):
                raise _err(f"the GLB BIN chunk declares {blen} bytes but the file holds {len(data) - off - 8}")
            bin_len = blen
    try:
        doc = json.loads(data[20:20 + jlen])
    except (ValueError, UnicodeDecodeError) as exc:
        raise _err(f"the GLB JSON chunk is not valid JSON ({exc})") from None
    _check_gltf(doc, bin_len)


def _precheck_gltf(data: bytes) -> None:
    try:
        doc = json.loads(data)
    except (ValueError, UnicodeDecodeError) as exc:
        raise _err(f"not valid glTF JSON ({exc})") from None
    _check_gltf(doc, 0)


_PRECHECK = {"stl": _precheck_stl, "ply": _precheck_ply, "obj": _precheck_obj,
             "glb": _precheck_glb, "gltf": _precheck_gltf}


# ----------------------------------------------------------------------------------------------
# Loading


def _rgb(colors: Any, count: int) -> np.ndarray | None:
    arr = np.asarray(colors)
    if arr.ndim != 2 or arr.shape[0] != count or arr.shape[1] < 3:
        return None
    if arr.dtype.kind == "f":
        arr = np.rint(np.clip(arr, 0.0, 1.0) * 255.0)
    out: np.ndarray = np.clip(arr[:, :3], 0, 255).astype(np.uint8)
    return out


def _texture_image(material: Any) -> np.ndarray | None:
    image = getattr(material, "image", None)
    if image is None:
        image = getattr(material, "baseColorTexture", None)
    if image is None:
        return None
    w, h = image.size
    if w * h > MAX_IMAGE_PIXELS:
        raise _too_large(f"a texture is {w}x{h} pixels; the limit is {MAX_IMAGE_PIXELS}")
    return np.asarray(image.convert("RGB"), dtype=np.uint8)


def _material_rgb(material: Any, default: np.ndarray) -> np.ndarray:
    main = getattr(material, "main_color", None)
    rgb = _rgb(np.asarray(main).reshape(1, -1), 1) if main is not None else None
    return rgb[0] if rgb is not None else default


def uv_lookup(uv: np.ndarray, image: np.ndarray) -> np.ndarray:
    """Colours (K, 3) uint8 of ``image`` (H, W, 3) at texture coordinates ``uv`` (K, 2):
    (0, 0) is the image's bottom-left corner, coordinates outside [0, 1] repeat (the glTF default),
    nearest pixel. Inside [0, 1] nothing wraps: u = 1 is the right edge's texel (a mesh whose UVs
    span the image has surface points on its border, and they take the border's colour)."""
    h, w = image.shape[:2]

    def wrap(t: np.ndarray) -> np.ndarray:
        out: np.ndarray = np.where((t >= 0.0) & (t <= 1.0), t, np.mod(t, 1.0))
        return out

    u, v = wrap(uv[:, 0]), wrap(uv[:, 1])
    col = np.clip(np.floor(u * w), 0, w - 1).astype(np.int64)
    row = np.clip(np.floor((1.0 - v) * h), 0, h - 1).astype(np.int64)
    out: np.ndarray = image[row, col]
    return out


def _to_enu(vertices: np.ndarray, up: str) -> np.ndarray:
    if up == "y":  # (x, y up, z towards the viewer) -> (east, north, up), a proper rotation
        return np.column_stack([vertices[:, 0], -vertices[:, 2], vertices[:, 1]])
    return vertices


def load_mesh(data: bytes, file_type: str, *, up: str = "auto", color: str = "#ffffff") -> Mesh:
    """Parse mesh bytes (checked against the limits first) into a :class:`Mesh`.

    Raises:
        InputTooLargeError: over MAX_MESH_BYTES, MAX_MESH_VERTICES or MAX_MESH_FACES.
        FormationError: unreadable, inconsistent, non-finite or empty files.
    """
    import trimesh  # ~0.3 s import, paid only by mesh imports

    if file_type not in MESH_FORMATS:
        raise _err(f"must be one of {', '.join(MESH_FORMATS)}, got {file_type!r}", "format")
    if up not in UP_AXES:
        raise _err(f"must be one of {', '.join(UP_AXES)}, got {up!r}", "up")
    if len(data) > MAX_MESH_BYTES:
        raise _too_large(f"is {len(data)} bytes; the limit is {MAX_MESH_BYTES}")
    if not data:
        raise _err("is empty")
    default = parse_color(color)
    try:
        _PRECHECK[file_type](data)
    except FormationError:
        raise
    except (TypeError, ValueError, AttributeError, KeyError, IndexError, struct.error) as exc:
        # JSON of the wrong shape ("buffers": "x", "count": "many", ...) is malformed input, not a bug.
        raise _err(f"malformed {file_type} file ({type(exc).__name__}: {exc})") from None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = trimesh.load(io.BytesIO(data), file_type=file_type, process=False, resolver=None)
    except MemoryError:
        raise
    except FormationError:
        raise
    except Exception as exc:  # trimesh's parsers raise anything on malformed input
        raise _err(f"could not read the {file_type} file: {type(exc).__name__}: {exc}"[:300]) from None
    geoms = loaded.dump(concatenate=False) if isinstance(loaded, trimesh.Scene) else [loaded]
    verts: list[np.ndarray] = []
    faces: list[np.ndarray] = []
    vrgb: list[np.ndarray] = []
    uvs: list[np.ndarray] = []
    ftex: list[np.ndarray] = []
    frgb: list[np.ndarray] = []
    fcol: list[np.ndarray] = []
    textures: list[np.ndarray] = []
    offset = 0
    for g in geoms:
        v = np.asarray(getattr(g, "vertices", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)
        f = np.asarray(getattr(g, "faces", np.zeros((0, 3))), dtype=np.int64).reshape(-1, 3)
        _check_counts(offset + len(v), sum(len(x) for x in faces) + len(f))
        nv, nf = len(v), len(f)
        if nf and (f.min() < 0 or f.max() >= nv):
            raise _err("a face refers to a vertex that does not exist")
        vc = np.tile(default, (nv, 1))
        uv = np.full((nv, 2), np.nan)
        tex = np.full(nf, -1, dtype=np.int64)
        fc = np.zeros((nf, 3), dtype=np.uint8)
        fcolored = np.zeros(nf, dtype=bool)
        visual = getattr(g, "visual", None)
        kind = getattr(visual, "kind", None)
        if isinstance(g, trimesh.PointCloud):
            c = _rgb(g.colors, nv) if len(getattr(g, "colors", [])) else None
            vc = c if c is not None else vc
        elif kind == "vertex":
            c = _rgb(visual.vertex_colors, nv)  # type: ignore[union-attr]
            vc = c if c is not None else vc
        elif kind == "face":
            c = _rgb(visual.face_colors, nf)  # type: ignore[union-attr]
            if c is not None:
                fc, fcolored = c, np.ones(nf, dtype=bool)
                np.add.at(vc_acc := np.zeros((nv, 3)), f, c[:, None, :].astype(np.float64))
                hits = np.bincount(f.ravel(), minlength=nv)[:, None]
                vc = np.where(hits > 0, np.rint(vc_acc / np.maximum(hits, 1)), vc).astype(np.uint8)
        elif kind == "texture":
            material = getattr(visual, "material", None)
            image = _texture_image(material)
            tuv = np.asarray(getattr(visual, "uv", None) if getattr(visual, "uv", None) is not None else [])
            if image is not None and tuv.shape == (nv, 2) and np.isfinite(tuv).all():
                textures.append(image)
                uv, tex = tuv.astype(np.float64), np.full(nf, len(textures) - 1, dtype=np.int64)
                vc = uv_lookup(uv, image)
            else:
                vc = np.tile(_material_rgb(material, default), (nv, 1))
        verts.append(v)
        faces.append(f + offset)
        vrgb.append(vc)
        uvs.append(uv)
        ftex.append(tex)
        frgb.append(fc)
        fcol.append(fcolored)
        offset += nv
    if offset == 0:
        raise _err("the file holds no vertices")
    vertices = np.concatenate(verts)
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        raise _err(f"vertex {int(np.flatnonzero(bad)[0])} has a non-finite coordinate "
                   f"{vertices[bad][0].tolist()!r}")
    eff_up = ("y" if file_type in ("glb", "gltf") else "z") if up == "auto" else up
    return Mesh(
        vertices=_to_enu(vertices, eff_up),
        faces=np.concatenate(faces) if faces else np.zeros((0, 3), dtype=np.int64),
        vertex_rgb=np.concatenate(vrgb).astype(np.uint8),
        uv=np.concatenate(uvs),
        face_texture=np.concatenate(ftex),
        textures=tuple(textures),
        face_rgb=np.concatenate(frgb).astype(np.uint8),
        face_colored=np.concatenate(fcol),
    )


# ----------------------------------------------------------------------------------------------
# Point files

_NUM = re.compile(r"^[\s+\-.0-9eE]+$")


def _parse_float(text: str, row: int, column: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise _err(f"row {row}, column {column!r}: {text[:40]!r} is not a number") from None
    if not math.isfinite(value):
        raise _err(f"row {row}, column {column!r}: {text[:40]!r} is not a finite number")
    return value


def read_points(data: bytes, file_type: str, *, color: str = "#ffffff") -> tuple[np.ndarray, np.ndarray]:
    """Read a Skybrush static CSV (``Name,x,y,z,Red,Green,Blue``, a header row optional) or an
    XYZ / XYZRGB text file (whitespace or commas; ``#`` comments; colours 0-255, or 0-1 floats).

    Returns:
        (points (M, 3) float64 metres, colours (M, 3) uint8).
    """
    if file_type not in POINT_FORMATS:
        raise _err(f"must be one of {', '.join(POINT_FORMATS)}, got {file_type!r}", "format")
    if len(data) > MAX_MESH_BYTES:
        raise _too_large(f"is {len(data)} bytes; the limit is {MAX_MESH_BYTES}")
    if data.count(b"\n") > MAX_POINT_ROWS + 1:
        raise _too_large(f"has more than {MAX_POINT_ROWS} rows")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise _err("is not UTF-8 text") from None
    default = parse_color(color)
    if file_type == "csv":
        rows = [r for r in csv.reader(io.StringIO(text)) if r and any(c.strip() for c in r)]
    else:
        rows = [re.split(r"[\s,;]+", line.strip()) for line in text.splitlines()
                if line.strip() and not line.lstrip().startswith("#")]
    if not rows:
        raise _err("holds no points")
    names = ["name", "x", "y", "z", "red", "green", "blue"] if file_type == "csv" else ["x", "y", "z", "r", "g", "b"]
    first = [c.strip().lower() for c in rows[0]]
    header = 0
    if not all(_NUM.match(c) for c in first[1 if file_type == "csv" else 0:]):
        rows, header = rows[1:], 1
        aliases = {"r": "red", "g": "green", "b": "blue"}
        col = {aliases.get(c, c): i for i, c in enumerate(first)}
        if file_type == "xyz":
            col = {k[0] if k in ("red", "green", "blue") else k: v for k, v in col.items()}
    else:
        col = {k: i for i, k in enumerate(names)}
    for axis in "xyz":
        if axis not in col:
            raise _err(f"has no {axis!r} column (header {rows[0] if rows else first!r})")
    cnames = ("red", "green", "blue") if file_type == "csv" else ("r", "g", "b")
    pts = np.empty((len(rows), 3))
    rgb = np.tile(default.astype(np.float64), (len(rows), 1))
    for i, r in enumerate(rows):
        line = i + 1 + header
        for a, axis in enumerate("xyz"):
            if col[axis] >= len(r):
                raise _err(f"row {line}: missing column {axis!r}")
            pts[i, a] = _parse_float(r[col[axis]], line, axis)
        for a, cname in enumerate(cnames):
            if cname in col and col[cname] < len(r) and r[col[cname]].strip():
                rgb[i, a] = _parse_float(r[col[cname]], line, cname)
    if not len(rows):
        raise _err("holds no points")
    has_color = all(c in col for c in cnames) and all(len(r) > max(col[c] for c in cnames) for r in rows)
    if has_color and rgb.max() <= 1.0 and np.any(rgb % 1.0 != 0):
        rgb = rgb * 255.0
    if rgb.min() < 0 or rgb.max() > 255:
        raise _err("colours must be in 0..255")
    return pts, np.rint(rgb).astype(np.uint8)


# ----------------------------------------------------------------------------------------------
# Candidates


def _face_areas(tri: np.ndarray) -> np.ndarray:
    out: np.ndarray = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    return out


def _face_colors(mesh: Mesh, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """Colours (K, 3) at barycentric points ``bary`` (K, 3) of faces ``face`` (K,): the texture
    at the interpolated UV, the face colour, or the interpolated vertex colours."""
    corner = mesh.faces[face]
    out = np.einsum("kj,kjc->kc", bary, mesh.vertex_rgb[corner].astype(np.float64))
    fc = mesh.face_colored[face]
    out[fc] = mesh.face_rgb[face[fc]]
    tex = mesh.face_texture[face]
    for t, image in enumerate(mesh.textures):
        sel = tex == t
        if sel.any():
            uv = np.einsum("kj,kjc->kc", bary[sel], mesh.uv[corner[sel]])
            out[sel] = uv_lookup(uv, image)
    result: np.ndarray = np.rint(out).astype(np.uint8)
    return result


def _surface_samples(mesh: Mesh, count: int, *, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``count`` uniformly random points on the surface (area-weighted face choice, uniform
    barycentric coordinates by the square-root rule; Osada et al. 2002, eq. 1).

    Returns:
        (points (count, 3), their faces (count,), barycentric coordinates (count, 3)).
    """
    tri = mesh.vertices[mesh.faces]
    area = _face_areas(tri)
    total = float(area.sum())
    if not math.isfinite(total) or total <= 0.0:
        raise _err("the mesh has no surface area (all faces are degenerate)")
    rng = np.random.default_rng(seed)
    cum = np.cumsum(area)
    face = np.minimum(np.searchsorted(cum, rng.random(count) * cum[-1], side="right"), len(area) - 1)
    r1, r2 = np.sqrt(rng.random(count)), rng.random(count)
    bary = np.column_stack([1.0 - r1, r1 * (1.0 - r2), r1 * r2])
    pts = np.einsum("kj,kjc->kc", bary, tri[face])
    return pts, face, bary


def surface_candidates(mesh: Mesh, count: int, *, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``count`` uniformly random points on the surface (:func:`_surface_samples`) and their colours.

    Returns:
        (points (count, 3), colours (count, 3) uint8).
    """
    pts, face, bary = _surface_samples(mesh, count, seed=seed)
    return pts, _face_colors(mesh, face, bary)


def _on_triangles(q: np.ndarray, tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The closest points to ``q`` (K, 3) on the triangles ``tri`` (K, 3, 3), by the Voronoi
    regions of the triangle's vertices, edges and face (Ericson 2004, "Real-Time Collision
    Detection", 5.1.5), vectorised.

    Returns:
        (points (K, 3), barycentric coordinates (K, 3)).
    """
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    ab, ac, ap = b - a, c - a, q - a
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    bp = q - b
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    cp = q - c
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4

    def ratio(num: np.ndarray, den: np.ndarray) -> np.ndarray:
        out: np.ndarray = num / np.where(np.abs(den) > 0.0, den, 1.0)
        return out

    v_ab = ratio(d1, d1 - d3)  # on edge ab: a + v ab
    w_ac = ratio(d2, d2 - d6)  # on edge ac: a + w ac
    w_bc = ratio(d4 - d3, (d4 - d3) + (d5 - d6))  # on edge bc: b + w (c - b)
    den = va + vb + vc
    v_in, w_in = ratio(vb, den), ratio(vc, den)
    one, zero = np.ones_like(d1), np.zeros_like(d1)
    conds = [
        (d1 <= 0) & (d2 <= 0),  # vertex a
        (d3 >= 0) & (d4 <= d3),  # vertex b
        (d6 >= 0) & (d5 <= d6),  # vertex c
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),  # edge ab
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),  # edge ac
        (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),  # edge bc
    ]
    v = np.select(conds, [zero, one, zero, v_ab, zero, 1.0 - w_bc], v_in)
    w = np.select(conds, [zero, zero, one, zero, w_ac, w_bc], w_in)
    bary = np.column_stack([1.0 - v - w, v, w])
    return np.einsum("kj,kjc->kc", bary, tri), bary


#: Surface relaxation: iterations of the pairwise push (each a cKDTree of the N points; 2,000
#: points on a 100k-face mesh take about a second for all of them), fewer for large N so that
#: N x iterations stays within RELAX_POINT_ITERATIONS (20,000 points: 30 iterations, a few
#: seconds, within an interactive request's budget), and the push per iteration, the fraction of a
#: pair's overlap each of its two points moves.
RELAX_ITERATIONS = 150
RELAX_MIN_ITERATIONS = 30
RELAX_POINT_ITERATIONS = 600_000
RELAX_STEP = 0.5


def relax_on_surface(
    mesh: Mesh, cand: np.ndarray, cand_face: np.ndarray, start: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spread (N, 3) points ``start`` on the surface toward the hexagonal packing.

    Farthest-point picks keep a minimum spacing of only about 0.72 of the hexagonal spacing
    ``h = sqrt(2 A / (sqrt(3) N))`` of N points on area A (density ~0.52 of the ideal). Soft-disk
    relaxation closes most of the gap: every pair closer than ``h`` is pushed apart along its
    joining line by a fraction of the overlap (the "spring" step of Turk 1992, "Re-tiling
    polygonal surfaces", with a cut-off at the target spacing as in soft-sphere jamming), and
    each moved point goes back to the plane of the face of its nearest dense surface sample.
    The iterate with the largest nearest-pair distance is kept; at the end every point is put on
    the closest point of the faces near it.

    Args:
        mesh: the (unit-sized) mesh; ``cand`` (M, 3) dense surface samples on it, ``cand_face``
            (M,) their faces; ``start`` (N, 3) the initial points.

    Returns:
        (points (N, 3) on the faces, faces (N,), barycentric coordinates (N, 3)).
    """
    from scipy.spatial import cKDTree

    tri = mesh.vertices[mesh.faces]
    n = len(start)
    area = float(_face_areas(tri).sum())
    h = math.sqrt(2.0 * area / (math.sqrt(3.0) * n))
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = normal / np.where(length > 0.0, length, 1.0)
    samples = cKDTree(cand)
    pts = np.array(start, dtype=np.float64)
    best, best_d = pts.copy(), _nearest_pair(pts)
    iterations = min(RELAX_ITERATIONS, max(RELAX_MIN_ITERATIONS, RELAX_POINT_ITERATIONS // n))
    for _ in range(iterations):
        pairs = cKDTree(pts).query_pairs(h, output_type="ndarray")
        if len(pairs) == 0:
            break
        i, j = pairs[:, 0], pairs[:, 1]
        delta = pts[j] - pts[i]
        dist = np.linalg.norm(delta, axis=1)
        unit = delta / np.maximum(dist, 1e-12 * h)[:, None]
        push = (0.5 * RELAX_STEP * (h - dist))[:, None] * unit
        disp = np.zeros_like(pts)
        np.add.at(disp, i, -push)
        np.add.at(disp, j, push)
        q = pts + disp
        # Back onto the surface: the plane of the nearest face of the 4 nearest samples (on a
        # fine mesh the true face is often not among them, and clamping to theirs would snap
        # the point to their edges), clamped onto that face where the plane leaves the surface
        # by more than 5 % of h (across a sharp edge, e.g. off a cube's face).
        on, f, _ = _on_faces(q, tri, samples, cand_face, 4)
        nf = normal[f]
        planar = q - ((q - tri[f, 0]) * nf).sum(axis=1, keepdims=True) * nf
        off = ((planar - on) ** 2).sum(axis=1) > (0.05 * h) ** 2
        pts = np.where(off[:, None], on, planar)
        d = _nearest_pair(pts)
        if d > best_d:
            best, best_d = pts.copy(), d
    # The last placement decides the spacing, so look wider: the faces of the 8 nearest samples
    # (right for large faces) and the 8 faces with the nearest centroids (on a fine mesh the
    # point's own face often holds no sample); the closest of the 16 points.
    near_samples = _on_faces(best, tri, samples, cand_face, 8)
    centroids = cKDTree(tri.mean(axis=1))
    near_faces = _on_faces(best, tri, centroids, np.arange(len(tri)), 8)
    closer = ((near_faces[0] - best) ** 2).sum(axis=1) < ((near_samples[0] - best) ** 2).sum(axis=1)
    pts, faces, bary = (np.where(closer.reshape((-1,) + (1,) * (a.ndim - 1)), b, a)
                        for a, b in zip(near_samples, near_faces, strict=True))
    return pts, faces, bary


def _on_faces(
    q: np.ndarray, tri: np.ndarray, samples: Any, sample_face: np.ndarray, k: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closest points to ``q`` (N, 3) on the faces of their ``k`` nearest surface samples
    (``samples``: a cKDTree of them, ``sample_face`` their faces).

    Returns:
        (points (N, 3), faces (N,), barycentric coordinates (N, 3)).
    """
    n = len(q)
    k = min(k, len(sample_face))
    _, near = samples.query(q, k=k)
    faces = sample_face[np.asarray(near).reshape(n, k)]
    on, bary = _on_triangles(np.repeat(q, k, axis=0), tri[faces.ravel()])
    on, bary = on.reshape(n, k, 3), bary.reshape(n, k, 3)
    pick = ((on - q[:, None, :]) ** 2).sum(axis=2).argmin(axis=1)
    rows = np.arange(n)
    return on[rows, pick], faces[rows, pick], bary[rows, pick]


def _nearest_pair(points: np.ndarray) -> float:
    from scipy.spatial import cKDTree

    d, _ = cKDTree(points).query(points, k=2)
    return float(d[:, 1].min())


def volume_candidates(mesh: Mesh, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Centres of the interior voxels of the closed mesh (voxel fill), about ``count`` of them,
    coloured like the nearest vertex.

    Returns:
        (points (M, 3), colours (M, 3) uint8).
    """
    import trimesh
    from scipy.spatial import cKDTree

    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=True)
    if not tm.is_watertight:
        raise _err("volume mode needs a closed (watertight) mesh; this one has holes")
    volume = abs(float(tm.volume))
    extent = tm.extents
    if not math.isfinite(volume) or volume <= 1e-12 * float(np.prod(np.maximum(extent, 1e-300))) or volume <= 0:
        raise _err("the mesh encloses no volume")
    pitch = (volume / count) ** (1.0 / 3.0)
    pitch = max(pitch, (float(np.prod(extent + 0.0)) / MAX_VOXELS) ** (1.0 / 3.0), float(extent.max()) / 400.0)
    # Voxelisation subdivides the faces down to the pitch: bound the faces that makes (a crumpled
    # mesh of large area in a small box would otherwise need hundreds of millions).
    pitch = max(pitch, math.sqrt(float(tm.area) / MAX_SUBDIVIDED_FACES))
    try:
        shell = tm.voxelized(pitch)
        filled = shell.copy().fill()
    except MemoryError:
        raise
    except Exception as exc:  # voxelisation gives up on some degenerate meshes
        raise _err(f"could not fill the mesh volume ({type(exc).__name__}: {exc})") from None
    inside = filled.points
    surface = {tuple(p) for p in np.round(shell.points / pitch).astype(np.int64).tolist()}
    keep = np.array([tuple(p) not in surface for p in np.round(inside / pitch).astype(np.int64).tolist()], bool)
    pts = inside[keep] if keep.any() else inside
    if len(pts) == 0:
        raise _err("the mesh encloses no volume")
    _, near = cKDTree(mesh.vertices).query(pts)
    return pts, mesh.vertex_rgb[near]


# ----------------------------------------------------------------------------------------------
# Picking N


Improve = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def _picks(
    candidates: np.ndarray, colors: np.ndarray, n: int, improve: Improve | None
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """``n`` picks: farthest-point order, then ``improve`` (indices -> points, colours) if it
    spreads them further.

    Returns:
        (points (k, 3), colours (k, 3), their nearest-pair distance (0 if k < n, inf if n = 1),
        the farthest-point distances (k,)).
    """
    idx, dist = farthest_point_order(candidates, n)
    if len(idx) < n:
        return candidates[idx], colors[idx], 0.0, dist
    if n == 1:
        return candidates[idx], colors[idx], math.inf, dist
    idx = np.sort(idx)
    pts, cols, d_n = candidates[idx], colors[idx], float(dist[-1])
    if improve is not None and n >= 3:
        better, better_cols = improve(idx)
        d_better = nearest_pair_distance(better)
        if d_better > d_n:
            pts, cols, d_n = better, better_cols, d_better
    return pts, cols, d_n, dist


def pick_points(
    candidates: np.ndarray,
    colors: np.ndarray,
    n: int,
    *,
    min_spacing_m: float,
    scale: float | None,
    extent: float,
    center_m: np.ndarray,
    origin: np.ndarray,
    what: str,
    improve: Improve | None = None,
) -> tuple[PointSet, float]:
    """Exactly ``n`` of the (M, 3) ``candidates`` spread by farthest-point order (then by
    ``improve``, e.g. :func:`relax_on_surface`, when that spreads them further), scaled by
    ``scale`` metres per candidate unit about ``origin`` (the source's bounding-box centre, (3,)),
    which goes to ``center_m``.

    With ``scale`` None the smallest scale at which they keep ``min_spacing_m`` is used (the
    picks are made in candidate units, so distances scale linearly: ``min_spacing_m / d_n``).

    Returns:
        (points, the size in metres: ``extent * scale``).

    Raises:
        MeshFitError: ``n`` do not fit; ``max_n`` (verified to fit at that size) and
            ``fit_size_m`` say what would.
    """
    pts, cols, d_n, dist = _picks(candidates, colors, n, improve)
    fit_scale = min_spacing_m * (1.0 + _MARGIN) / d_n if d_n > 0.0 else None
    if scale is None:
        if fit_scale is None:
            raise MeshFitError(f"{what} has only {len(pts)} distinct points, fewer than {n}",
                               max_n=len(pts), fit_size_m=None)
        scale = fit_scale if math.isfinite(fit_scale) and fit_scale > 0 else 1.0
    if d_n * scale < min_spacing_m * (1.0 - _TOL):
        # Any farthest-point prefix that keeps the spacing fits (improving only spreads it
        # further); a relaxed set packs denser, so also try the count its density predicts.
        max_n = int((dist * scale >= min_spacing_m * (1.0 - _TOL)).sum())
        if improve is not None and d_n > 0.0:
            guess = min(n - 1, int(n * (d_n * scale / min_spacing_m) ** 2))
            if guess > max_n and _picks(candidates, colors, guess, improve)[2] * scale >= min_spacing_m:
                max_n = guess
        fit = extent * fit_scale if fit_scale is not None else None
        hint = (f", or a size of {fit:.4g} m fits {n}" if fit is not None
                else f" ({what} has {len(pts)} distinct points)")
        raise MeshFitError(
            f"{n} points do not fit {what} at a size of {extent * scale:.4g} m and a minimum spacing of "
            f"{min_spacing_m:g} m; the largest N that fits is {max_n}{hint}",
            max_n=max_n, fit_size_m=fit,
        )
    out = (pts - origin) * scale + center_m
    good = ensure_spacing(out, min_spacing_m)
    if good is None:  # pragma: no cover - d_n and the scale guarantee the spacing
        raise FormationError(f"{n} points do not fit {what}")
    return PointSet(good, cols), extent * scale


def _box_centre(points: np.ndarray) -> np.ndarray:
    out: np.ndarray = 0.5 * (points.min(axis=0) + points.max(axis=0))
    return out


def _extent(vertices: np.ndarray) -> float:
    ext = float((vertices.max(axis=0) - vertices.min(axis=0)).max())
    if not math.isfinite(ext) or ext <= 0.0:
        raise _err("all vertices coincide (the mesh has no extent)")
    return ext


def mesh_points(
    data: bytes,
    n: int,
    *,
    file_type: str,
    mode: str = "surface",
    size_m: float | None = None,
    center_m: ArrayLike = (0.0, 0.0, 30.0),
    min_spacing_m: float = 3.0,
    up: str = "auto",
    color: str = "#ffffff",
) -> tuple[PointSet, float]:
    """Exactly ``n`` points from a mesh or point file, in the file's colours.

    Args:
        data: file bytes (at most MAX_MESH_BYTES).
        n: number of points, 1..20000.
        file_type: one of MESH_FORMATS or POINT_FORMATS.
        mode: "vertices", "surface" (even blue-noise spacing over the faces) or "volume"
            (filled interior of a closed mesh); point files are always their points.
        size_m: the largest side of the bounding box, metres; None = the smallest size that keeps
            ``min_spacing_m`` (a point file keeps its own metres when None).
        center_m: where the bounding-box centre goes, metres.
        min_spacing_m: minimum distance between any two points, metres.
        up: "auto", "y" or "z": the file's up axis (mapped to ENU +z).
        color: colour of points whose file has no colours.

    Returns:
        (points, the size in metres actually used).

    Raises:
        InputTooLargeError: over the byte, vertex, face or row limits.
        FormationError: bad arguments or file (``field`` names it); MeshFitError when ``n`` do
            not fit (``max_n``, ``fit_size_m``).
    """
    n = check_n(n)
    s = check_positive(min_spacing_m, name="min_spacing_m")
    center = check_center(center_m)
    size = None if size_m is None else check_positive(size_m, name="size_m")
    if mode not in MESH_MODES:
        raise _err(f"must be one of {', '.join(MESH_MODES)}, got {mode!r}", "mode")
    if not isinstance(data, bytes | bytearray | memoryview):
        raise _err("must be bytes")
    data = bytes(data)
    if file_type in POINT_FORMATS:
        pts, rgb = read_points(data, file_type, color=color)
        bad = ~np.isfinite(pts).all(axis=1)
        if bad.any():  # pragma: no cover - _parse_float refuses these
            raise _err("non-finite coordinates")
        extent = float((pts.max(axis=0) - pts.min(axis=0)).max())
        if size is None:
            scale: float | None = 1.0
            extent_out = extent
        else:
            if extent <= 0.0:
                raise _err("all points coincide, so they cannot be scaled to size_m")
            scale, extent_out = size / extent, extent
        uniq, first = np.unique(pts, axis=0, return_index=True)
        return pick_points(uniq, rgb[first], n, min_spacing_m=s, scale=scale, extent=extent_out,
                           center_m=center, origin=_box_centre(pts), what=f"the {len(pts)} points of the file")
    mesh = load_mesh(data, file_type, up=up, color=color)
    extent = _extent(mesh.vertices)
    unit = 1.0 / extent  # candidates live in a box whose largest side is 1
    verts = mesh.vertices * unit
    unit_mesh = Mesh(verts, mesh.faces, mesh.vertex_rgb, mesh.uv, mesh.face_texture, mesh.textures,
                     mesh.face_rgb, mesh.face_colored)
    if mode == "vertices":
        cand, first = np.unique(verts, axis=0, return_index=True)
        cols = mesh.vertex_rgb[first]
        what = f"the {len(cand)} vertices of the mesh"
    elif len(mesh.faces) == 0:
        raise _err(f"{mode} mode needs faces; the file holds only points (use mode 'vertices')", "mode")
    elif mode == "surface":
        cand, face, bary = _surface_samples(unit_mesh, SURFACE_CANDIDATES)
        cols = _face_colors(unit_mesh, face, bary)

        def relax(idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            pts, f, b = relax_on_surface(unit_mesh, cand, face, cand[idx])
            return pts, _face_colors(unit_mesh, f, b)

        return pick_points(cand, cols, n, min_spacing_m=s, scale=size, extent=1.0, center_m=center,
                           origin=_box_centre(verts), what="the mesh surface", improve=relax)
    else:
        return _volume_points(unit_mesh, n, s=s, size=size, center=center, origin=_box_centre(verts))
    return pick_points(cand, cols, n, min_spacing_m=s, scale=None if size is None else size,
                       extent=1.0, center_m=center, origin=_box_centre(verts), what=what)


def _volume_count(n: int) -> int:
    return min(VOLUME_CANDIDATES, max(2000, VOLUME_CANDIDATES_PER_POINT * n))


def _volume_points(
    unit_mesh: Mesh, n: int, *, s: float, size: float | None, center: np.ndarray, origin: np.ndarray
) -> tuple[PointSet, float]:
    """Volume mode: ``n`` picks among the interior voxels of a grid sized for ``n``; when they do
    not fit, ``max_n`` is the largest k whose own request fits (bisection, each k verified)."""
    what = "the mesh volume"
    cand, cols = volume_candidates(unit_mesh, _volume_count(n))
    try:
        return pick_points(cand, cols, n, min_spacing_m=s, scale=size, extent=1.0, center_m=center,
                           origin=origin, what=what)
    except MeshFitError as exc:
        if size is None or exc.max_n is None:
            raise

        def fits(k: int) -> bool:
            c, col = volume_candidates(unit_mesh, _volume_count(k))
            try:
                pick_points(c, col, k, min_spacing_m=s, scale=size, extent=1.0, center_m=center, origin=origin,
                            what=what)
            except MeshFitError:
                return False
            return True

        max_n = largest_fitting(fits, n)
        message = str(exc).replace(f"the largest N that fits is {exc.max_n}", f"the largest N that fits is {max_n}")
        raise MeshFitError(message, max_n=max_n, fit_size_m=exc.fit_size_m) from None
