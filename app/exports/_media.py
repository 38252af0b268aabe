"""A show's music in the exports (issue 18): ``media.audio`` of the ``.skyc``, and sound in the offline HTML.

``.skyc`` (Skybrush Studio 5's layout, as read by ``@skybrush/show-format``): the file is a member
of the archive and ``show.json`` refers to it with a JSON reference,
``"media": {"audio": {"data": {"$ref": "./music.mp3"}, "mediaType": "audio/mpeg", "startTime": 0}}``.
Skybrush plays MPEG audio only, so a WAV, OGG or FLAC track is transcoded to MP3 on the way
(libsndfile, block by block: bounded memory); where this libsndfile cannot write MP3 the track
goes in as it is, with its own media type and a warning.

The offline HTML (viser's client playing an embedded recording) gets the track as a data URI and
a small script that follows the client's own playback bar (its time slider's ``aria-valuenow``,
its play / pause button, its speed) with an ``<audio>`` element: the music plays with the
recording, seeks with the scrub bar and loops with it.
"""

from __future__ import annotations

import base64
import io
import json
from typing import TYPE_CHECKING, Any

from app.exports._archive import ZipBuilder

if TYPE_CHECKING:
    from app.exports._core import ExportContext
    from app.media import AudioTrack

#: The ``.skyc`` member holding the music.
SKYC_AUDIO_NAME = "music.mp3"
#: Sample rates MPEG-1/2/2.5 layer III encodes, Hz.
_MP3_RATES_HZ = frozenset({8_000, 11_025, 12_000, 16_000, 22_050, 24_000, 32_000, 44_100, 48_000})
#: Frames transcoded at a time.
_BLOCK_FRAMES = 1 << 16


def as_mp3(audio: AudioTrack) -> bytes | None:
    """The track as MP3 bytes (itself when it is one), or None when this libsndfile cannot write MP3."""
    if audio.container == "mp3":
        return audio.data
    import soundfile as sf

    if "MP3" not in sf.available_formats():
        return None
    out = io.BytesIO()
    with sf.SoundFile(io.BytesIO(audio.data)) as src:
        channels = min(src.channels, 2)  # MPEG-1 layer III: mono or stereo
        rate = src.samplerate
        if rate not in _MP3_RATES_HZ:
            return None  # (a resampling transcode is not worth it here: the track goes in as it is)
        with sf.SoundFile(out, "w", samplerate=rate, channels=channels, format="MP3",
                          subtype="MPEG_LAYER_III") as dst:
            for block in src.blocks(blocksize=_BLOCK_FRAMES, dtype="float32", always_2d=True):
                dst.write(block[:, :channels] if block.shape[1] >= channels else block.repeat(channels, axis=1))
    return out.getvalue()


def add_skyc_audio(ctx: ExportContext, doc: dict[str, Any], z: ZipBuilder) -> None:
    """Put the show's music (``ctx.options.audio``, if any) into the ``.skyc``: member and ``media.audio``."""
    audio = ctx.options.audio
    if audio is None:
        return
    data, media_type, name = as_mp3(audio), "audio/mpeg", SKYC_AUDIO_NAME
    if data is None:
        data, media_type = audio.data, audio.media_type
        name = f"music.{audio.container}"
        ctx.warn(f"the music stays {audio.container.upper()} in the .skyc: Skybrush plays MPEG audio only")
    member = z.add(name, data)
    media: dict[str, Any] = {"data": {"$ref": f"./{member}"}, "mediaType": media_type}
    if audio.filename:
        media["filename"] = audio.filename
    media["startTime"] = round(float(audio.start_s), 6)
    doc["media"] = {"audio": media}


_SYNC_SCRIPT = """
(function () {
  var spec = window.__SWARMSHOW_AUDIO__;
  if (!spec) return;
  var bytes = Uint8Array.from(atob(spec.data), function (c) { return c.charCodeAt(0); });
  var audio = new Audio(URL.createObjectURL(new Blob([bytes], { type: spec.type })));
  audio.preload = "auto";
  window.__SWARMSHOW_AUDIO_ELEMENT__ = audio;
  var button = document.createElement("button");
  button.textContent = "\\u266a Sound on";
  button.setAttribute("aria-label", "Play the music with the show");
  button.style.cssText = "position:fixed;top:10px;left:10px;z-index:1000;padding:6px 12px;border-radius:6px;" +
    "border:1px solid #888;background:#1e2430;color:#eee;font:14px sans-serif;cursor:pointer";
  var wanted = false;
  button.onclick = function () {
    wanted = !wanted;
    button.textContent = wanted ? "\\u266a Sound off" : "\\u266a Sound on";
    if (!wanted) audio.pause();
    follow();
  };
  document.addEventListener("DOMContentLoaded", function () { document.body.appendChild(button); });
  function state() {
    var slider = document.querySelector('[role="slider"]');
    if (!slider) return null;
    var t = parseFloat(slider.getAttribute("aria-valuenow"));
    var paused = !!document.querySelector(".tabler-icon-player-play-filled");
    var speed = 1;
    document.querySelectorAll("input").forEach(function (el) {
      if (/^[0-9.]+x$/.test(el.value)) speed = parseFloat(el.value);
    });
    return isFinite(t) ? { t: t, paused: paused, speed: speed } : null;
  }
  function follow() {
    var s = state();
    if (!s) return;
    var at = s.t - spec.start;
    var audible = wanted && !s.paused && at >= 0 && at < (audio.duration || Infinity);
    audio.playbackRate = Math.min(4, Math.max(0.25, s.speed));
    if (!audible) { if (!audio.paused) audio.pause(); return; }
    if (Math.abs(audio.currentTime - at) > 0.25 * Math.max(1, s.speed)) audio.currentTime = at;
    if (audio.paused) audio.play().catch(function () {});
  }
  setInterval(follow, 200);
})();
"""


def html_with_audio(html: bytes, audio: AudioTrack | None) -> bytes:
    """The offline HTML with the music and the script that plays it with the recording (module docstring)."""
    if audio is None:
        return html
    spec = {"type": audio.media_type, "start": float(audio.start_s),
            "data": base64.b64encode(audio.data).decode("ascii")}
    inject = (f"<script>window.__SWARMSHOW_AUDIO__={json.dumps(spec)};</script>"
              f"<script>{_SYNC_SCRIPT}</script>").encode()
    head_end = html.find(b"</head>")
    if head_end < 0:
        return html + inject
    return html[:head_end] + inject + html[head_end:]


__all__ = ["SKYC_AUDIO_NAME", "add_skyc_audio", "as_mp3", "html_with_audio"]
