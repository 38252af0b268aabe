"""Launch layouts (issue 21 item 4): launch boxes holding several drones, and home points from CSV.

A *launch box* is how operators carry and set out drones: a case holding ``per_box`` drones
in a small pattern (``cols`` per row at ``spacing_m``, well below ``min_distance_m``: 8 drones
at 0.8 m in a 4 x 2 pattern). The boxes themselves are set out on a grid of box centres or at
given centres. Drones fill the boxes in order: box b holds homes ``b*per_box .. (b+1)*per_box - 1``.

**The spacing rule.** Inside one box, drones are ``spacing_m`` apart (at least
:data:`MIN_BOX_SPACING_M`); a drone of one box and a drone of another box (and all loose home
points) keep the show's usual ``min_distance_m``, and at least the downwash radius, so that a
drone lifting off from one box never has a parked drone of another box inside its downwash
(``settings.downwash_radius_m``). The planner takes off and lands the drones of a box in waves
(:mod:`sim.plan._waves`), and the exact check treats drones resting on their home as *parked*
(:mod:`sim.verify._parked`).

Home points may also come from a CSV file (Skybrush's ``Name,x,y,z`` rows, or plain ``x,y[,z]``
rows): :func:`home_points_from_csv`.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterator
from typing import Annotated

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator
from pydantic_core import PydanticCustomError

#: Closest two drones of one launch box may be, metres (a box holds real airframes side by side).
MIN_BOX_SPACING_M = 0.2
#: Most drones one launch box may hold.
MAX_PER_BOX = 64
#: Largest home CSV accepted, bytes.
MAX_HOME_CSV_BYTES = 4 * 1024 * 1024
#: Most rows of a home CSV.
MAX_HOME_CSV_ROWS = 100_000

_CONFIG = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True, revalidate_instances="never")


class BoxGrid(BaseModel):
    """Box centres on a rectangular ground grid, centred on ``center_m``; box b at cell b (row-major)."""

    model_config = _CONFIG

    rows: int = Field(ge=1, le=20_000)
    cols: int = Field(ge=1, le=20_000)
    spacing_m: float = Field(ge=0.1, le=1000, description="Distance between neighbouring box centres, metres.")
    center_m: Annotated[list[float], Field(min_length=2, max_length=2)] = Field(
        default_factory=lambda: [0.0, 0.0], description="Grid centre [x, y], metres."
    )

    def centers_m(self) -> np.ndarray:
        """(rows*cols, 2) box centres, metres, row-major (y then x)."""
        xs = (np.arange(self.cols) - (self.cols - 1) / 2.0) * self.spacing_m + self.center_m[0]
        ys = (np.arange(self.rows) - (self.rows - 1) / 2.0) * self.spacing_m + self.center_m[1]
        gx, gy = np.meshgrid(xs, ys)
        return np.column_stack([gx.ravel(), gy.ravel()])


class LaunchBoxes(BaseModel):
    """``per_box`` drones per box in ``cols`` columns at ``spacing_m``; boxes on ``grid`` or at ``centers``."""

    model_config = _CONFIG

    per_box: int = Field(ge=1, le=MAX_PER_BOX, description="Drones one box holds.")
    cols: int | None = Field(None, ge=1, le=MAX_PER_BOX,
                             description="Drones per row inside a box (default: ceil(sqrt(per_box))).")
    spacing_m: float = Field(ge=MIN_BOX_SPACING_M, le=100,
                             description="Distance between neighbouring drones inside a box, metres.")
    grid: BoxGrid | None = Field(None, description="Box centres on a grid.")
    centers: Annotated[list[Annotated[list[float], Field(min_length=2, max_length=2)]],
                       Field(min_length=1, max_length=20_000)] | None = Field(
        None, description="Box centres [x, y], metres.")

    @model_validator(mode="after")
    def _one_placement(self) -> LaunchBoxes:
        if (self.grid is None) == (self.centers is None):
            raise PydanticCustomError("boxes_placement", "give the box centres as either 'grid' or 'centers'")
        return self

    @property
    def box_count(self) -> int:
        """Number of boxes."""
        return self.grid.rows * self.grid.cols if self.grid is not None else len(self.centers or ())

    def pattern_m(self) -> np.ndarray:
        """(per_box, 2) drone offsets inside a box from its centre, metres (rows of ``cols``, centred)."""
        cols = self.cols or math.ceil(math.sqrt(self.per_box))
        cols = min(cols, self.per_box)
        rows = math.ceil(self.per_box / cols)
        k = np.arange(self.per_box)
        x = (k % cols - (cols - 1) / 2.0) * self.spacing_m
        y = (k // cols - (rows - 1) / 2.0) * self.spacing_m
        return np.column_stack([x, y])

    def centers_m(self) -> np.ndarray:
        """(B, 2) box centres, metres."""
        if self.grid is not None:
            return self.grid.centers_m()
        return np.asarray(self.centers, dtype=np.float64).reshape(-1, 2)

    def positions_m(self) -> np.ndarray:
        """(B*per_box, 3) home positions, metres, z = 0, box by box."""
        xy = (self.centers_m()[:, None, :] + self.pattern_m()[None, :, :]).reshape(-1, 2)
        return np.column_stack([xy, np.zeros(len(xy))])

    def box_ids(self) -> np.ndarray:
        """(B*per_box,) the box of each home position."""
        return np.repeat(np.arange(self.box_count, dtype=np.int64), self.per_box)


def boxes_problem(boxes: LaunchBoxes, min_distance_m: float, downwash_radius_m: float,
                  ) -> tuple[tuple[str | int, ...], str] | None:
    """The first spacing rule the boxes break, as (path below ``home.boxes``, reason), or None.

    Inside a box: ``spacing_m`` (>= MIN_BOX_SPACING_M, a field rule). Between drones of different
    boxes: at least max(min_distance_m, downwash radius), so that nobody lifting off from one box
    has a parked drone of another box inside its downwash.
    """
    pts = boxes.positions_m()
    ids = boxes.box_ids()
    need = max(min_distance_m, downwash_radius_m)
    if boxes.box_count < 2:
        return None
    from scipy.spatial import cKDTree  # only boxes layouts pay for the import (validate stays fast)

    pairs = cKDTree(pts[:, :2]).query_pairs(need * (1 - 1e-9), output_type="ndarray")
    if len(pairs):
        pairs = pairs[ids[pairs[:, 0]] != ids[pairs[:, 1]]]
    if not len(pairs):
        return None
    d = np.linalg.norm(pts[pairs[:, 0], :2] - pts[pairs[:, 1], :2], axis=1)
    q = int(np.argmin(d))
    i, j = int(pairs[q, 0]), int(pairs[q, 1])
    bi, bj = int(ids[i]), int(ids[j])
    what = (f"drones of boxes {bi} and {bj} (homes {i} and {j}) are {d[q]:.3f} m apart; drones of different "
            f"boxes must be at least {need:g} m apart (settings.min_distance_m {min_distance_m:g} m and the "
            f"downwash radius {downwash_radius_m:g} m)")
    if boxes.grid is not None:
        return ("grid", "spacing_m"), what
    return ("centers", bj), what


class HomeCsvError(ValueError):
    """A home CSV cannot be read; ``line`` is its 1-based line number (0: the whole file)."""

    def __init__(self, message: str, *, line: int = 0) -> None:
        super().__init__(message if not line else f"line {line}: {message}")
        self.line = line


def home_points_from_csv(data: bytes | str) -> tuple[list[list[float]], list[str]]:
    """Home points from CSV text: Skybrush's ``Name,x,y,z`` rows or plain ``x,y[,z]`` rows (z default 0).

    A first row that is not numeric is a header. Returns (points [[x, y, z], ...] in metres,
    names: the Name column, or "" where there is none).

    Raises:
        HomeCsvError: too large, not UTF-8, a row of the wrong width, a value that is not a
            finite number; the message names the line.
    """
    if isinstance(data, bytes | bytearray):
        if len(data) > MAX_HOME_CSV_BYTES:
            raise HomeCsvError(f"the CSV is {len(data)} bytes; the limit is {MAX_HOME_CSV_BYTES}")
        try:
            data = bytes(data).decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise HomeCsvError(f"not UTF-8 text (byte {exc.start})") from exc
    elif len(data) > MAX_HOME_CSV_BYTES:
        raise HomeCsvError(f"the CSV is {len(data)} characters; the limit is {MAX_HOME_CSV_BYTES}")
    points: list[list[float]] = []
    names: list[str] = []
    named: bool | None = None
    for line_no, row in enumerate(_csv_rows(data), start=1):
        cells = [c.strip() for c in row]
        if not any(cells):
            continue
        if len(points) >= MAX_HOME_CSV_ROWS:
            raise HomeCsvError(f"more than {MAX_HOME_CSV_ROWS} rows", line=line_no)
        if named is None and not points:
            if _is_header(cells):
                continue
            named = not _is_number(cells[0])
        values = cells[1:] if named else cells
        if not 2 <= len(values) <= 3:
            raise HomeCsvError(f"expected {'Name,x,y,z' if named else 'x,y[,z]'}, got {len(cells)} columns",
                               line=line_no)
        try:
            xyz = [float(v) for v in values]
        except ValueError:
            raise HomeCsvError(f"{values!r} are not all numbers", line=line_no) from None
        if not all(math.isfinite(v) for v in xyz):
            raise HomeCsvError("coordinates must be finite numbers", line=line_no)
        points.append(xyz + [0.0] * (3 - len(xyz)))
        names.append(cells[0] if named else "")
    if not points:
        raise HomeCsvError("no home points in the CSV")
    return points, names


def _csv_rows(text: str) -> Iterator[list[str]]:
    """The CSV rows of ``text``; a malformed file raises HomeCsvError (naming the line), not csv.Error.

    ``newline=""`` hands line ends to the csv module, so a lone carriage return (classic Mac line
    ends) ends a row instead of raising csv.Error.
    """
    rows = csv.reader(io.StringIO(text, newline=""))
    try:
        yield from rows
    except csv.Error as exc:
        raise HomeCsvError(f"not readable as CSV ({exc})", line=rows.line_num) from None


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _is_header(cells: list[str]) -> bool:
    """Skybrush's ``Name,x_m,y_m,z_m`` (or ``x,y,z``): no cell after the first is a number."""
    return not any(_is_number(c) for c in cells[1:])


def home_points_to_csv(points: np.ndarray, names: list[str] | None = None) -> str:
    """Skybrush-style ``Name,x_m,y_m,z_m`` CSV of home points (N, 3) metres (round trip of the reader)."""
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["Name", "x_m", "y_m", "z_m"])
    for k, p in enumerate(np.asarray(points, dtype=np.float64)):
        w.writerow([names[k] if names else f"Drone {k + 1}", *(repr(float(v)) for v in p)])
    return out.getvalue()


__all__ = [
    "MAX_PER_BOX",
    "MIN_BOX_SPACING_M",
    "BoxGrid",
    "HomeCsvError",
    "LaunchBoxes",
    "boxes_problem",
    "home_points_from_csv",
    "home_points_to_csv",
]
