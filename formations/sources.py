"""Formation sources: shapes, strokes, text, image, SVG, mesh and point-file sampling, transforms and spacing.

Every source returns a :class:`PointSet` of exactly N points (metres, ENU) with colours and
keeps a minimum spacing, or raises :class:`FormationError` whose ``max_n`` is the largest N
that fits (:class:`InputTooLargeError` for uploads over the size limits).
"""

from __future__ import annotations

from formations._image import IMAGE_FORMATS as IMAGE_FORMATS
from formations._image import IMAGE_MODES as IMAGE_MODES
from formations._image import MAX_IMAGE_BYTES as MAX_IMAGE_BYTES
from formations._image import MAX_IMAGE_PIXELS as MAX_IMAGE_PIXELS
from formations._image import image_points as image_points
from formations._mesh import MAX_MESH_BYTES as MAX_MESH_BYTES
from formations._mesh import MAX_MESH_FACES as MAX_MESH_FACES
from formations._mesh import MAX_MESH_VERTICES as MAX_MESH_VERTICES
from formations._mesh import MAX_POINT_ROWS as MAX_POINT_ROWS
from formations._mesh import MESH_FORMATS as MESH_FORMATS
from formations._mesh import MESH_MODES as MESH_MODES
from formations._mesh import POINT_FORMATS as POINT_FORMATS
from formations._mesh import MeshFitError as MeshFitError
from formations._mesh import mesh_points as mesh_points
from formations._points import MAX_POINTS as MAX_POINTS
from formations._points import PLANES as PLANES
from formations._points import FormationError as FormationError
from formations._points import InputTooLargeError as InputTooLargeError
from formations._points import PointSet as PointSet
from formations._points import nearest_pair_distance as nearest_pair_distance
from formations._shapes import SHAPE_KINDS as SHAPE_KINDS
from formations._shapes import SHAPE_KINDS_3D as SHAPE_KINDS_3D
from formations._shapes import SHAPE_PARAMS as SHAPE_PARAMS
from formations._shapes import generate_shape as generate_shape
from formations._spacing import MAX_REPAIR_SHIFT as MAX_REPAIR_SHIFT
from formations._spacing import fit_to_count as fit_to_count
from formations._spacing import repair_spacing as repair_spacing
from formations._strokes import MAX_STROKES as MAX_STROKES
from formations._strokes import MAX_VERTICES as MAX_VERTICES
from formations._strokes import stroke_points as stroke_points
from formations._svg import MAX_SVG_BYTES as MAX_SVG_BYTES
from formations._svg import MAX_SVG_NUMBERS as MAX_SVG_NUMBERS
from formations._svg import MAX_SVG_VERTICES as MAX_SVG_VERTICES
from formations._svg import svg_points as svg_points
from formations._text import FONT_FILE as FONT_FILE
from formations._text import MAX_TEXT_CHARS as MAX_TEXT_CHARS
from formations._text import MAX_TEXT_LINES as MAX_TEXT_LINES
from formations._text import text_points as text_points
from formations._transforms import place_on_plane as place_on_plane
from formations._transforms import rotate as rotate
from formations._transforms import rotation_matrix as rotation_matrix
from formations._transforms import scale as scale
from formations._transforms import translate as translate

__all__ = [
    "FONT_FILE",
    "IMAGE_FORMATS",
    "IMAGE_MODES",
    "MAX_IMAGE_BYTES",
    "MAX_IMAGE_PIXELS",
    "MAX_MESH_BYTES",
    "MAX_MESH_FACES",
    "MAX_MESH_VERTICES",
    "MAX_POINT_ROWS",
    "MAX_POINTS",
    "MAX_REPAIR_SHIFT",
    "MAX_STROKES",
    "MAX_SVG_BYTES",
    "MAX_SVG_NUMBERS",
    "MAX_SVG_VERTICES",
    "MAX_TEXT_CHARS",
    "MAX_TEXT_LINES",
    "MAX_VERTICES",
    "MESH_FORMATS",
    "MESH_MODES",
    "PLANES",
    "POINT_FORMATS",
    "SHAPE_KINDS",
    "SHAPE_KINDS_3D",
    "SHAPE_PARAMS",
    "FormationError",
    "InputTooLargeError",
    "MeshFitError",
    "PointSet",
    "fit_to_count",
    "generate_shape",
    "image_points",
    "mesh_points",
    "nearest_pair_distance",
    "place_on_plane",
    "repair_spacing",
    "rotate",
    "rotation_matrix",
    "scale",
    "stroke_points",
    "svg_points",
    "text_points",
    "translate",
]
