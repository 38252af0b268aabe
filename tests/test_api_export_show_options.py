"""The API's ``show`` download refuses the flight options as every other path does: ``source=simulated`` (the
show file is the exact design, ``require_planned``) and ``preset`` / ``seed`` / ``controller`` / ``disturbance``
(they choose a simulated flight). The library and the CLI refuse them for ``-f show``; the API's shortcut that
serves the stored file answered 200 and dropped them without a word.

Failed before: each request below answered 200 with the show file.
"""

from __future__ import annotations

import pytest

from app.exports import ExportError, export_show
from tests.conftest import app_client

client = app_client("showopts", workers=1)


CASES = [
    ({"source": "simulated"}, "source"),
    ({"preset": "gusty-rtk"}, "preset"),
    ({"seed": 3}, "seed"),
    ({"controller": "baseline"}, "controller"),
    ({"disturbance": "wind"}, "disturbance"),
]


@pytest.mark.parametrize(("params", "field"), CASES)
def test_the_library_refuses_them_for_the_show_format(square, params, field):
    """The independent reference: what ``export_show`` (the CLI's path) says for the same options."""
    with pytest.raises(ExportError) as exc:
        export_show(square, "show", **params)
    assert exc.value.field == field


@pytest.mark.parametrize(("params", "field"), CASES)
def test_the_api_refuses_them_naming_the_field(client, square_id, params, field):
    r = client.get(f"/api/shows/{square_id}/export/show", params=params)
    assert r.status_code == 422, (r.status_code, r.text[:200])
    assert any(e.get("path") == field or field in (e.get("loc") or []) for e in r.json()["detail"]), r.text


def test_the_plain_show_download_still_works(client, square_id):
    r = client.get(f"/api/shows/{square_id}/export/show")
    assert r.status_code == 200 and r.json()["name"]
