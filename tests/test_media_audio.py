"""A show's music (issue 18): decoding within bounds, waveform peaks, beats on click tracks, the upload API
(every format round trip, HTTP ranges, bad files answered 4xx naming ``file``, the store migration)."""

from __future__ import annotations

import io
import json
import sqlite3

import numpy as np
import pytest
import soundfile as sf
from fastapi.testclient import TestClient

from app.media import AudioError, analyse_audio, decode, sniff_container
from app.media._beats import detect_beats
from app.server import create_app
from app.settings import AppSettings
from app.store import MIGRATIONS, SCHEMA_VERSION, ShowStore

SR = 44_100


def click_track(bpm: float, offset_s: float, duration_s: float = 30.0, sr: int = SR) -> tuple[np.ndarray, np.ndarray]:
    """A mono click track (10 ms 1 kHz clicks, 2 ms decay) and the click times, seconds."""
    y = np.zeros(int(duration_s * sr), np.float32)
    beats = np.arange(offset_s, duration_s - 0.1, 60.0 / bpm)
    n = int(0.01 * sr)
    click = (np.sin(2 * np.pi * 1000 * np.arange(n) / sr) * np.exp(-np.arange(n) / (0.002 * sr))).astype(np.float32)
    for b in beats:
        i = int(round(b * sr))
        y[i:i + n] += click[: len(y) - i]
    return y, beats


def encode(y: np.ndarray, fmt: str, sr: int = SR, **kw) -> bytes:
    buf = io.BytesIO()
    sf.write(buf, y, sr, format=fmt, **kw)
    return buf.getvalue()


# -- beats -------------------------------------------------------------------------------------


@pytest.mark.parametrize("bpm", [90.0, 120.0, 128.0])
def test_beats_of_a_click_track_within_20_ms(bpm):
    offset = 0.37
    y, truth = click_track(bpm, offset)
    found = analyse_audio(encode(np.stack([y, y], axis=1) * 0.5, "WAV"))
    beats = np.asarray(found["beats_s"])
    # Every detected beat is a click, to 20 ms ...
    err = np.abs(beats[:, None] - truth[None, :]).min(axis=1)
    assert err.max() <= 0.020, err.max()
    # ... and every click but the first and last (the tracker may start one late) is a detected beat.
    missed = np.abs(truth[1:-1, None] - beats[None, :]).min(axis=1) > 0.020
    assert missed.sum() == 0, truth[1:-1][missed]
    assert found["tempo_bpm"] == pytest.approx(bpm, rel=0.01)
    onsets = np.asarray(found["onsets_s"])
    assert np.abs(onsets[:, None] - truth[None, :]).min(axis=1).max() <= 0.020


def test_silence_has_no_beats():
    found = detect_beats(np.zeros(SR * 2, np.float32), SR)
    assert found.beats_s.size == 0 and found.onsets_s.size == 0


# -- decoding ----------------------------------------------------------------------------------


def test_peaks_are_the_min_and_max_of_each_bucket():
    rng = np.random.default_rng(3)
    y = (rng.uniform(-1, 1, SR * 3) * np.linspace(0, 1, SR * 3)).astype(np.float32)
    dec = decode(encode(y, "WAV", subtype="FLOAT"))
    bucket = SR // 50
    n = int(np.ceil(len(y) / bucket))
    pad = np.pad(y, (0, n * bucket - len(y)), constant_values=np.nan).reshape(n, bucket)
    want = np.clip(np.round(np.stack([np.nanmin(pad, 1), np.nanmax(pad, 1)], 1) * 127), -127, 127)
    assert dec.peaks.shape == (n, 2)
    assert np.array_equal(dec.peaks.astype(int), want.astype(int))
    assert dec.duration_s == pytest.approx(3.0)


@pytest.mark.parametrize("fmt,container", [("WAV", "wav"), ("FLAC", "flac"), ("OGG", "ogg"), ("MP3", "mp3")])
def test_each_format_decodes_to_its_duration(fmt, container):
    if fmt not in sf.available_formats():
        pytest.skip(f"this libsndfile ({sf.__libsndfile_version__}) cannot write {fmt}")
    y, _ = click_track(120, 0.1, duration_s=4.0)
    data = encode(y, fmt)
    assert sniff_container(data) == container
    dec = decode(data)
    assert dec.container == container
    # MP3 frames pad the end by up to one frame (1152 samples) plus the encoder delay.
    assert dec.duration_s == pytest.approx(4.0, abs=0.1 if fmt == "MP3" else 1e-3)


def test_bad_files_name_the_reason():
    wav = encode(np.zeros(SR, np.float32) + 0.1, "WAV")
    cases = {
        b"": "empty",
        b"hello, not audio at all" * 10: "not a WAV",
        encode(np.zeros(0, np.float32), "WAV"): "no audio",  # a header declaring no samples
        wav[:44]: "truncated",  # a header declaring a second, and no samples
        wav[: len(wav) // 2]: "truncated",
        b"RIFF\x10\x00\x00\x00WAVEjunkjunkjunk": "cannot read",
    }
    for data, words in cases.items():
        with pytest.raises(AudioError) as err:
            decode(data)
        assert words in err.value.msg, (words, err.value.msg)
        assert err.value.field == "file" and 400 <= err.value.status < 500


def test_too_long_is_refused_before_decoding():
    data = encode(np.zeros(SR * 3, np.float32), "WAV")
    with pytest.raises(AudioError) as err:
        decode(data, max_duration_s=2.0)
    assert err.value.status == 413 and "3.0 s long" in err.value.msg


# -- store -------------------------------------------------------------------------------------


def test_migration_to_the_audio_table_keeps_every_show(tmp_path):
    path = tmp_path / "old.sqlite3"
    db = sqlite3.connect(path)
    db.execute("CREATE TABLE schema_version (version INTEGER NOT NULL)")
    db.execute("INSERT INTO schema_version VALUES (4)")
    for script in MIGRATIONS[:4]:
        db.executescript(script)
    db.execute("INSERT INTO shows VALUES ('s1', 'old', 3, '{}', 'h', 4, 1, 't', 't')")
    db.commit()
    db.close()
    store = ShowStore(path)
    try:
        assert store.schema_version == SCHEMA_VERSION
        assert store.get("s1").revision == 3 and store.get("s1").json == "{}"
        assert store.get_audio("s1") is None
    finally:
        store.close()


# -- API ---------------------------------------------------------------------------------------


def show_doc(name: str = "audio test") -> dict:
    return {
        "format": "swarmshow/1", "name": name, "drones": 4,
        "home": {"grid": {"rows": 2, "cols": 2, "spacing_m": 4.5}},
        "settings": {"max_speed_z_mps": 5.0, "max_accel_mps2": 8.0, "takeoff_altitude_m": 3.0},
        "formations": [{"name": "square", "hold_s": 1.0,
                        "points": [[0, 0, 6], [5, 0, 6], [0, 0, 11], [5, 0, 11]], "color": "#ff0000"}],
    }


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    app = create_app(AppSettings(data_dir=tmp_path_factory.mktemp("data"), workers=1,
                                 max_audio_bytes=2 * 1024 * 1024))
    with TestClient(app, base_url="http://127.0.0.1") as c:
        yield c


def _new_show(client) -> str:
    r = client.post("/api/shows", json=show_doc())
    assert r.status_code == 201, r.text
    return r.json()["id"]


@pytest.mark.parametrize("fmt,media_type", [("WAV", "audio/wav"), ("FLAC", "audio/flac"), ("OGG", "audio/ogg"),
                                            ("MP3", "audio/mpeg")])
def test_upload_round_trip(client, fmt, media_type):
    if fmt not in sf.available_formats():
        pytest.skip(f"this libsndfile ({sf.__libsndfile_version__}) cannot write {fmt}")
    sid = _new_show(client)
    y, truth = click_track(120, 0.25, duration_s=8.0, sr=22_050)
    data = encode(y, fmt, sr=22_050)
    r = client.put(f"/api/shows/{sid}/audio", files={"file": (f"music.{fmt.lower()}", data)})
    assert r.status_code == 201, r.text
    info = r.json()
    assert info["media_type"] == media_type and info["size"] == len(data) and info["filename"] == f"music.{fmt.lower()}"
    assert info["duration_s"] == pytest.approx(8.0, abs=0.1)
    # The stored bytes are the upload's, whole and by ranges.
    whole = client.get(f"/api/shows/{sid}/audio")
    assert whole.status_code == 200 and whole.content == data
    assert whole.headers["content-type"].startswith(media_type) and whole.headers["accept-ranges"] == "bytes"
    part = client.get(f"/api/shows/{sid}/audio", headers={"Range": "bytes=100-1099"})
    assert part.status_code == 206 and part.content == data[100:1100]
    assert part.headers["content-range"] == f"bytes 100-1099/{len(data)}"
    tail = client.get(f"/api/shows/{sid}/audio", headers={"Range": "bytes=-10"})
    assert tail.status_code == 206 and tail.content == data[-10:]
    analysis = client.get(f"/api/shows/{sid}/audio/analysis").json()
    assert abs(len(analysis["peaks"]) / 2 - analysis["duration_s"] * analysis["peaks_per_s"]) <= 1
    # Lossless files keep the clicks' attacks to the sample; lossy codecs smear them (pre-echo, encoder delay).
    beats = np.asarray(analysis["beats_s"])
    tol = 0.02 if fmt in ("WAV", "FLAC") else 0.05
    assert np.abs(beats[:, None] - truth[None, :]).min(axis=1).max() <= tol


def test_raw_upload_replace_and_delete(client):
    sid = _new_show(client)
    one = encode(np.zeros(22_050, np.float32) + 0.1, "WAV", sr=22_050)
    r = client.put(f"/api/shows/{sid}/audio", params={"filename": "../../etc/a b.wav"}, content=one,
                   headers={"content-type": "audio/wav"})
    assert r.status_code == 201 and r.json()["filename"] == "a b.wav"
    two = encode(np.zeros(44_100, np.float32) + 0.1, "FLAC", sr=22_050)
    assert client.put(f"/api/shows/{sid}/audio", content=two).status_code == 201
    assert client.get(f"/api/shows/{sid}/audio").content == two
    assert client.get(f"/api/shows/{sid}/audio/info").json()["media_type"] == "audio/flac"
    assert client.delete(f"/api/shows/{sid}/audio").status_code == 204
    assert client.get(f"/api/shows/{sid}/audio").status_code == 404
    assert client.delete(f"/api/shows/{sid}/audio").status_code == 404
    # Deleting the show deletes its music.
    client.put(f"/api/shows/{sid}/audio", content=one)
    rev = client.get(f"/api/shows/{sid}").json()["revision"]
    assert client.delete(f"/api/shows/{sid}", params={"revision": rev}).status_code == 204
    assert client.get(f"/api/shows/{sid}/audio").status_code == 404


def test_copy_music_to_a_saved_copy(client):
    """The editor's "save as a copy" makes a new show and then copies the music: same bytes, name,
    type and analysis; the original keeps its own; 204 (nothing copied) from a show without music,
    404 naming a show that does not exist."""
    src, dst = _new_show(client), _new_show(client)
    y, _ = click_track(100, 0.25, duration_s=4.0, sr=22_050)
    data = encode(y, "WAV", sr=22_050)
    assert client.put(f"/api/shows/{src}/audio", params={"filename": "song.wav"}, content=data).status_code == 201
    r = client.post(f"/api/shows/{dst}/audio/copy", params={"from": src})
    assert r.status_code == 201, r.text
    assert r.json() == {**client.get(f"/api/shows/{src}/audio/info").json(), "show_id": dst,
                        "url": f"/api/shows/{dst}/audio", "analysis_url": f"/api/shows/{dst}/audio/analysis"}
    assert client.get(f"/api/shows/{dst}/audio").content == data
    analysis = client.get(f"/api/shows/{src}/audio/analysis").json()
    assert client.get(f"/api/shows/{dst}/audio/analysis").json() == analysis
    # independent copies: deleting one keeps the other
    assert client.delete(f"/api/shows/{src}/audio").status_code == 204
    assert client.get(f"/api/shows/{dst}/audio").content == data
    # from a show without music: nothing to copy, the target keeps what it has
    r = client.post(f"/api/shows/{dst}/audio/copy", params={"from": src})
    assert r.status_code == 204 and client.get(f"/api/shows/{dst}/audio").content == data
    for a, b in (("nope", dst), (dst, "nope")):
        r = client.post(f"/api/shows/{b}/audio/copy", params={"from": a})
        assert r.status_code == 404 and "nope" in r.text
    assert client.post(f"/api/shows/{dst}/audio/copy").status_code == 422  # `from` is required


def test_bad_uploads_are_4xx_naming_file_and_store_nothing(client):
    sid = _new_show(client)
    wav = encode(np.zeros(22_050, np.float32) + 0.1, "WAV", sr=22_050)
    cases = [
        (b"", 422), (b"<html>not audio</html>" * 20, 415), (wav[:44], 422), (wav[: len(wav) // 3], 422),
        (b"fLaC" + b"\x00" * 200, 422), (b"\xff\xfb" + bytes(500), 422),
    ]
    for data, status in cases:
        r = client.put(f"/api/shows/{sid}/audio", content=data)
        assert r.status_code == status, (data[:10], r.status_code, r.text)
        assert r.json()["detail"][0]["path"] == "file", r.text
        assert client.get(f"/api/shows/{sid}/audio").status_code == 404
    big = b"RIFF" + bytes(3 * 1024 * 1024)
    r = client.put(f"/api/shows/{sid}/audio", content=big)
    assert r.status_code == 413 and "'file'" in r.json()["detail"]
    missing = client.put("/api/shows/nope/audio", content=wav)
    assert missing.status_code == 404
    bad_range = client.put(f"/api/shows/{sid}/audio", content=wav)
    assert bad_range.status_code == 201
    r = client.get(f"/api/shows/{sid}/audio", headers={"Range": f"bytes={len(wav) + 5}-"})
    assert r.status_code == 416
    assert json.loads(client.get(f"/api/shows/{sid}/audio/analysis").content)["duration_s"] == pytest.approx(1.0)


def test_a_track_over_the_length_limit_is_413_before_decoding(client):
    sid = _new_show(client)
    # 21 minutes of silence: FLAC stores it in a few kilobytes, and its header says how long it is.
    data = encode(np.zeros(8_000 * 60 * 21, np.int16), "FLAC", sr=8_000)
    assert len(data) < 2 * 1024 * 1024
    r = client.put(f"/api/shows/{sid}/audio", content=data)
    assert r.status_code == 413, r.text
    assert r.json()["detail"][0]["path"] == "file" and "the limit is 1200 s" in r.json()["detail"][0]["msg"]


def test_the_show_says_whether_it_has_music(client):
    """QA: the editor asked GET .../audio/info of every show it opened, and a show without music answered 404,
    which the browser logs as an error. The music is a sub-resource of the show: the show's own answer (GET, and
    the answers of POST and PUT that the editor loads) says ``has_audio``, so a client asks only for what exists;
    asking anyway stays a 404 (there is no such resource)."""
    sid = _new_show(client)
    show = client.get(f"/api/shows/{sid}").json()
    assert show["has_audio"] is False
    assert client.get(f"/api/shows/{sid}/audio/info").status_code == 404
    data = encode(np.zeros(22_050, np.float32) + 0.1, "WAV", sr=22_050)
    assert client.put(f"/api/shows/{sid}/audio", content=data).status_code == 201
    assert client.get(f"/api/shows/{sid}").json()["has_audio"] is True
    put = client.put(f"/api/shows/{sid}", json={"revision": show["revision"], "show": {**show["show"], "name": "x"}})
    assert put.status_code == 200 and put.json()["has_audio"] is True
    assert client.delete(f"/api/shows/{sid}/audio").status_code == 204
    assert client.get(f"/api/shows/{sid}").json()["has_audio"] is False
    created = client.post("/api/shows", json=show_doc("new"))
    assert created.status_code == 201 and created.json()["has_audio"] is False
    # The list stays a summary (no per-show look-up of music).
    assert "has_audio" not in client.get("/api/shows", params={"limit": 1}).json()["items"][0]
