"""Fast CSV text for large numeric tables.

Python's per-value ``%`` formatting costs ~100 ns a number; a 5,000-drone,
5-minute show sampled at 4 fps is 42 million numbers. :func:`fixed_point_rows`
writes fixed-point decimals with numpy digit arithmetic instead: every value is
rounded to an integer number of units (1 mm for 3 decimals), its digits are
laid out in a byte matrix with 0 bytes as padding, and the padding is dropped
at the end. The text equals ``"%.{d}f" % value`` except that a value within
an ulp of a rounding tie may round the other way (a 0.5 mm question at 3
decimals) and that ``-0.000`` is written ``0.000``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

_MINUS = ord("-")
_DOT = ord(".")


def _lut(width_fmt: str) -> np.ndarray:
    """(1000,) uint32 whose 4 bytes (little-endian) are the 3 characters of each number, then a 0 byte.

    A 4-byte item lets numpy gather a whole group in one 1-D ``take`` instead
    of a slow row-wise 2-D fancy index.
    """
    raw = np.zeros((1000, 4), dtype=np.uint8)
    for i in range(1000):
        raw[i, :3] = [ord(c) if c != " " else 0 for c in width_fmt.format(i)]
    return raw.view("<u4").ravel()


# "000" .. "999": inner three-digit groups and fractions.
_TRIPLETS = _lut("{:03d}")
# The leading group of a number: "0" .. "999" right-aligned, 0 bytes instead of leading zeros.
_LEADING = _lut("{:>3d}")


def _chars(lut: np.ndarray, index: np.ndarray) -> np.ndarray:
    """(R, 3) uint8 characters of ``lut`` at ``index`` (R,)."""
    return lut.take(index).view(np.uint8).reshape(len(index), 4)[:, :3]


def _column_parts(values: np.ndarray, decimals: int) -> list[np.ndarray]:
    """Byte blocks (R, w) of one column: sign, integer digits, point and fraction; 0 bytes pad."""
    if decimals > 3:
        raise ValueError("at most 3 decimals")
    scale = 10**decimals
    scaled = np.rint(np.asarray(values, dtype=np.float64) * float(scale)).astype(np.int64)
    mag = np.abs(scaled)
    rows = len(mag)
    whole, frac = np.divmod(mag, scale) if decimals else (mag, None)
    top = int(whole.max()) if rows else 0
    groups = max(1, -(-len(str(top)) // 3))
    parts = [np.where(scaled < 0, _MINUS, 0).astype(np.uint8)[:, None]]
    if groups == 1:
        parts.append(_chars(_LEADING, whole))
    else:
        # Three-digit groups of the integer part, most significant first. The first non-zero
        # group (or the last one, for 0) is written without leading zeros, the ones before not at all.
        trip = np.empty((groups, rows), dtype=np.int64)
        rest = whole
        for k in range(groups - 1, -1, -1):
            rest, trip[k] = np.divmod(rest, 1000)
        lead = np.full(rows, groups - 1, dtype=np.int64)
        for k in range(1, groups):
            lead -= whole >= 1000**k
        for k in range(groups):
            block = np.where(lead == k, _LEADING.take(trip[k]), _TRIPLETS.take(trip[k]))
            block[lead > k] = 0
            parts.append(block.view(np.uint8).reshape(rows, 4)[:, :3])
    if decimals:
        # The fraction always has all its digits: 1.050, not 1.05.
        parts.append(np.full((rows, 1), _DOT, np.uint8))
        parts.append(_chars(_TRIPLETS, frac * 10 ** (3 - decimals))[:, :decimals])
    return parts


def column_bytes(values: np.ndarray, decimals: int) -> np.ndarray:
    """One column pre-formatted for :func:`fixed_point_rows` (``decimals=None``), to format a repeated column once."""
    return np.concatenate(_column_parts(np.ravel(values), int(decimals)), axis=1)


def fixed_point_rows(
    columns: Sequence[np.ndarray], decimals: Sequence[int | None], *, groups: int = 1
) -> list[bytes]:
    """CSV rows (comma separated, ``\n`` terminated) of fixed-point columns.

    Args:
        columns: C arrays of R values each (any real dtype).
        decimals: digits after the point for each column (0: integers, at most
            3), or ``None`` for a column already formatted by :func:`column_bytes`
            (an (R, W) uint8 block).
        groups: split the rows into this many equal consecutive groups (one per file).

    Returns:
        The text of each group of rows as ASCII bytes.
    """
    if len(columns) != len(decimals):
        raise ValueError("one decimals entry per column")
    rows = len(columns[0])
    if rows % groups:
        raise ValueError("rows must split evenly into groups")
    blocks: list[np.ndarray] = []
    for j, (col, d) in enumerate(zip(columns, decimals, strict=True)):
        blocks.extend([np.asarray(col, dtype=np.uint8)] if d is None else _column_parts(np.ravel(col), int(d)))
        blocks.append(np.full((rows, 1), ord(",") if j < len(columns) - 1 else ord("\n"), np.uint8))
    table = np.empty((rows, sum(b.shape[1] for b in blocks)), dtype=np.uint8)
    at = 0
    for b in blocks:
        table[:, at : at + b.shape[1]] = b
        at += b.shape[1]
    per = rows // groups
    # bytes.translate with delete characters drops the padding in one linear C loop per group:
    # several times faster than a boolean mask or bytes.replace.
    return [table[g * per : (g + 1) * per].tobytes().translate(None, b"\0") for g in range(groups)]
