"""``show``: the show file itself (JSON), loadable by ``formations.load_show``."""

from __future__ import annotations

from app.exports._archive import safe_stem
from app.exports._core import ExportContext, ExportResult, require_planned


def export_show_json(ctx: ExportContext) -> ExportResult:
    """The validated show as indented JSON (no planning needed)."""
    from formations import dump_show

    require_planned(ctx)
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}.json",
        media_type="application/json",
        content=(dump_show(ctx.show) + "\n").encode(),
    )
