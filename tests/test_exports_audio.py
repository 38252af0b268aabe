"""The show's music in the exports (issue 18): ``media.audio`` of the ``.skyc`` resolved as Skybrush's
show-format reader does (a JSON reference into the archive), read back with libsndfile; the offline
HTML carries the track; the API export takes the stored track."""

from __future__ import annotations

import base64
import io
import json
import re
import zipfile

import numpy as np
import pytest
import soundfile as sf
from fastapi.testclient import TestClient

from app.exports import export_show
from app.media import AudioTrack, sniff_container
from app.server import create_app
from app.settings import AppSettings
from formations import parse_show
from tests.test_media_audio import click_track, encode, show_doc


def track(fmt: str, sr: int = 22_050, seconds: float = 3.0) -> AudioTrack:
    y, _ = click_track(120, 0.25, duration_s=seconds, sr=sr)
    data = encode(np.stack([y, 0.5 * y], axis=1), fmt, sr=sr)
    container = sniff_container(data)
    assert container is not None
    return AudioTrack(data=data, container=container, media_type={"wav": "audio/wav", "mp3": "audio/mpeg",
                      "flac": "audio/flac", "ogg": "audio/ogg"}[container], filename=f"song.{container}")


def resolve_refs(node, z: zipfile.ZipFile, base: str = "show.json"):
    """Dereference ``{"$ref": "./x"}`` against the archive (relative to ``base``), as
    ``@skybrush/show-format`` does: JSON members parsed, any other member as bytes."""
    if isinstance(node, dict):
        if set(node) == {"$ref"}:
            ref = node["$ref"]
            folder = base.rpartition("/")[0]
            name = ref[2:] if ref.startswith("./") else ref
            path = f"{folder}/{name}" if folder else name
            raw = z.read(path)
            return json.loads(raw) if path.endswith(".json") else raw
        return {k: resolve_refs(v, z, base) for k, v in node.items()}
    if isinstance(node, list):
        return [resolve_refs(v, z, base) for v in node]
    return node


@pytest.fixture(scope="module")
def show():
    return parse_show(show_doc())


@pytest.mark.parametrize("fmt", ["WAV", "FLAC", "MP3"])
def test_skyc_embeds_the_music_as_media_audio(show, fmt):
    audio = track(fmt)
    res = export_show(show, "skyc", audio=audio)
    z = zipfile.ZipFile(io.BytesIO(res.content))
    doc = json.loads(z.read("show.json"))
    media = doc["media"]["audio"]
    assert media["mediaType"] == "audio/mpeg" and media["data"] == {"$ref": "./music.mp3"}
    assert media["startTime"] == 0 and media["filename"] == audio.filename
    resolved = resolve_refs(doc, z)["media"]["audio"]["data"]
    assert isinstance(resolved, bytes) and sniff_container(resolved) == "mp3"
    if fmt == "MP3":
        assert resolved == audio.data  # an MP3 goes in untouched
    with sf.SoundFile(io.BytesIO(resolved)) as f:
        assert f.frames / f.samplerate == pytest.approx(3.0, abs=0.1)
        assert f.channels == 2
    # The rest of the show is unchanged by the music.
    plain = json.loads(zipfile.ZipFile(io.BytesIO(export_show(show, "skyc").content)).read("show.json"))
    assert "media" not in plain
    assert {k: v for k, v in doc.items() if k != "media"} == plain


def test_a_rate_mp3_cannot_hold_goes_in_as_it_is_with_a_warning(show):
    audio = track("WAV", sr=96_000, seconds=1.0)
    res = export_show(show, "skyc", audio=audio)
    z = zipfile.ZipFile(io.BytesIO(res.content))
    media = json.loads(z.read("show.json"))["media"]["audio"]
    assert media["mediaType"] == "audio/wav" and z.read(media["data"]["$ref"][2:]) == audio.data
    assert any("MPEG audio only" in w for w in res.warnings)


def test_offline_html_carries_the_track_and_its_player(show):
    audio = track("OGG", seconds=1.0)
    html = export_show(show, "viser-html", audio=audio).content.decode()
    spec = json.loads(re.search(r"window\.__SWARMSHOW_AUDIO__=(\{.*?\});</script>", html).group(1))
    assert base64.b64decode(spec["data"]) == audio.data and spec["type"] == "audio/ogg"
    assert html.index("__SWARMSHOW_AUDIO__") < html.index("</head>")
    assert "__SWARMSHOW_AUDIO__" not in export_show(show, "viser-html").content.decode()


def test_api_exports_take_the_stored_track(tmp_path):
    app = create_app(AppSettings(data_dir=tmp_path, workers=1))
    with TestClient(app, base_url="http://127.0.0.1") as client:
        sid = client.post("/api/shows", json=show_doc()).json()["id"]
        audio = track("MP3")
        assert client.put(f"/api/shows/{sid}/audio", content=audio.data).status_code == 201
        r = client.get(f"/api/shows/{sid}/export/skyc")
        assert r.status_code == 200, r.text
        z = zipfile.ZipFile(io.BytesIO(r.content))
        assert z.read("music.mp3") == audio.data
        assert json.loads(z.read("show.json"))["media"]["audio"]["mediaType"] == "audio/mpeg"
        csv = client.get(f"/api/shows/{sid}/export/skybrush-csv")
        names = zipfile.ZipFile(io.BytesIO(csv.content)).namelist()
        assert csv.status_code == 200 and not any(n.endswith(".mp3") for n in names)  # other formats ignore it


def test_cli_export_with_audio(show, tmp_path, capsys):
    from app.cli import main
    from formations import dump_show

    src = tmp_path / "show.json"
    src.write_text(dump_show(show))
    song = tmp_path / "song.flac"
    song.write_bytes(track("FLAC").data)
    out = tmp_path / "show.skyc"
    assert main(["export", str(src), "--format", "skyc", "-o", str(out), "--audio", str(song)]) == 0
    z = zipfile.ZipFile(out)
    media = json.loads(z.read("show.json"))["media"]["audio"]
    assert media["filename"] == "song.flac" and sniff_container(z.read("music.mp3")) == "mp3"
    # A bad track: exit 2, one line naming --audio and the reason, nothing written.
    bad = tmp_path / "bad.wav"
    bad.write_bytes(track("WAV").data[:100])
    out2 = tmp_path / "bad.skyc"
    capsys.readouterr()
    assert main(["export", str(src), "--format", "skyc", "-o", str(out2), "--audio", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert "--audio" in err and "truncated" in err and len(err.splitlines()) == 1
    assert not out2.exists()
