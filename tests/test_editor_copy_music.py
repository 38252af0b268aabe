"""The editor's "save as a copy" keeps the show's music (Playwright against a live server on
loopback): the copy is a new show whose stored track is the same file, and the music lane shows it."""

from __future__ import annotations

import io

import httpx
import numpy as np
import pytest

from tests.live_server import BROWSER_MARKS, running_server
from tests.test_editor_browser import Page, _create_show

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")
sf = pytest.importorskip("soundfile")


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with running_server(tmp_path_factory.mktemp("copy-music-data"), viewer=False) as base:
        yield base


def test_save_as_copy_copies_the_music(ui: Page):
    page = ui.page
    _create_show(ui, "With music", 9)
    sr = 22_050
    t = np.arange(4 * sr) / sr
    buf = io.BytesIO()
    sf.write(buf, (0.3 * np.sin(2 * np.pi * 440 * t)).astype(np.float32), sr, format="WAV")
    track = ui.tmp / "tone.wav"
    track.write_bytes(buf.getvalue())
    page.set_input_files("#music-file", str(track))
    page.wait_for_function("() => (window.swarmshow.music.info || {}).filename === 'tone.wav'", timeout=240_000)
    old_id = ui.state("s.meta.id")

    assert page.evaluate("() => window.swarmshow.persist.saveCopy()") is True
    new_id = ui.state("s.meta.id")
    assert new_id != old_id and ui.state("s.show.name") == "With music (copy)"
    got = httpx.get(f"{ui.base}/api/shows/{new_id}/audio")
    assert got.status_code == 200 and got.content == track.read_bytes()
    # the lane reloaded the copy's own track
    page.wait_for_function(f"() => (window.swarmshow.music.info || {{}}).url === '/api/shows/{new_id}/audio'")
    assert ui.state("window.swarmshow.music.info.filename") == "tone.wav"
    # the original keeps its music
    assert httpx.get(f"{ui.base}/api/shows/{old_id}/audio").content == track.read_bytes()
