"""Audio files: recognise, decode with bounded CPU and memory, and summarise as waveform peaks.

A show's music arrives as bytes (WAV, MP3, OGG Vorbis/Opus or FLAC). :func:`analyse_audio`
checks it in this order, so that every bad file gets one clear reason naming the ``file``
field: empty; not one of the four containers (magic bytes, before any decoder sees it);
unreadable by libsndfile; longer than :data:`MAX_DURATION_S`; too many channels or too high a
sample rate; fewer frames decodable than the header declares (truncated). Decoding streams
the file in blocks of :data:`BLOCK_FRAMES` frames, mixes them to mono and resamples them with
a streaming resampler (soxr), so memory is bounded by the analysis rate (not the file's) and
CPU by the duration limit.

The analysis returned (JSON-safe) holds the waveform peaks (min/max per bucket of
1/:data:`PEAKS_PER_S` s, scaled to -127..127) and the beats and onsets of
:mod:`app.media._beats`.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: Largest audio upload, bytes (a 20-minute MP3 is ~30 MB; a 20-minute 16-bit stereo WAV ~210 MB).
MAX_AUDIO_BYTES = 64 * 1024 * 1024
#: Longest track accepted, seconds (a drone show rarely runs past 20 minutes).
MAX_DURATION_S = 20 * 60.0
#: Most channels accepted (7.1 surround).
MAX_CHANNELS = 8
#: Highest sample rate accepted, Hz.
MAX_SAMPLE_RATE = 384_000
#: Frames decoded at a time (bounded memory whatever the file's length).
BLOCK_FRAMES = 1 << 16
#: Rate of the mono signal the analysis works on, Hz (beats need < 5 kHz of content).
ANALYSIS_RATE_HZ = 11_025
#: Waveform buckets per second of audio.
PEAKS_PER_S = 50
#: A file decoding to fewer than this share of its declared frames is truncated.
TRUNCATED_SHARE = 0.98

#: Container -> MIME type served to the browser (and written into exports).
MEDIA_TYPES = {"wav": "audio/wav", "mp3": "audio/mpeg", "ogg": "audio/ogg", "flac": "audio/flac"}


class AudioError(ValueError):
    """A bad audio file: ``status`` (HTTP 4xx), the ``field`` it names and a one-line reason."""

    def __init__(self, msg: str, status: int = 422, field: str = "file") -> None:
        super().__init__(msg, status, field)
        self.msg, self.status, self.field = msg, status, field

    def __str__(self) -> str:
        return f"{self.field}: {self.msg}"


@dataclass(frozen=True)
class AudioTrack:
    """A show's music as stored: the file's bytes, its container and MIME type, and where it starts.

    ``start_s`` is the show time at which the audio's first sample plays (Skybrush's ``startTime``).
    """

    data: bytes = field(repr=False)
    container: str
    media_type: str
    filename: str = "audio"
    start_s: float = 0.0
    duration_s: float = 0.0


def sniff_container(data: bytes) -> str | None:
    """``"wav"``, ``"mp3"``, ``"ogg"`` or ``"flac"`` from the first bytes, or None.

    MP3: an ID3v2 tag or an MPEG audio frame header (11 sync bits, layer III/II/I not reserved).
    """
    head = data[:12]
    if head[:4] == b"RIFF" and head[8:12] == b"WAVE":
        return "wav"
    if head[:4] == b"RF64" or head[:4] == b"BW64":
        return "wav"
    if head[:4] == b"OggS":
        return "ogg"
    if head[:4] == b"fLaC":
        return "flac"
    if head[:3] == b"ID3":
        return "mp3"
    if len(head) >= 2 and head[0] == 0xFF and (head[1] & 0xE0) == 0xE0 and (head[1] & 0x06) != 0:
        return "mp3"
    return None


@dataclass(frozen=True)
class Decoded:
    """A decoded track: mono samples at ``rate_hz`` and the waveform peaks of the original."""

    container: str
    sample_rate_hz: int
    channels: int
    duration_s: float
    mono: np.ndarray = field(repr=False)  # (S,) float32 at rate_hz
    rate_hz: int
    peaks: np.ndarray = field(repr=False)  # (B, 2) int8 min/max per bucket


def decode(data: bytes, *, max_duration_s: float = MAX_DURATION_S, rate_hz: int = ANALYSIS_RATE_HZ) -> Decoded:
    """Check and decode an audio file to mono at ``rate_hz`` (see the module docstring).

    Raises:
        AudioError: the file is empty, not audio, unreadable, too long, truncated, or out of range.
    """
    import soundfile as sf

    if len(data) == 0:
        raise AudioError("the file is empty (0 bytes); upload a WAV, MP3, OGG or FLAC file")
    container = sniff_container(data)
    if container is None:
        raise AudioError("not a WAV, MP3, OGG or FLAC file (its first bytes are none of theirs)", status=415)
    if container == "wav":
        _check_wav_length(data)
    try:
        snd = sf.SoundFile(io.BytesIO(data))
    except (sf.LibsndfileError, RuntimeError, TypeError, ValueError) as exc:
        raise AudioError(f"cannot read this {container.upper()} file: {_reason(exc)}") from None
    with snd:
        sr, channels, frames = int(snd.samplerate), int(snd.channels), int(snd.frames)
        if sr <= 0 or sr > MAX_SAMPLE_RATE:
            raise AudioError(f"sample rate {sr} Hz is outside 1..{MAX_SAMPLE_RATE} Hz")
        if channels < 1 or channels > MAX_CHANNELS:
            raise AudioError(f"{channels} channels; at most {MAX_CHANNELS}")
        if frames <= 0:
            raise AudioError("contains no audio (0 samples)")
        declared_s = frames / sr
        if declared_s > max_duration_s:
            raise AudioError(f"the track is {declared_s:.1f} s long; the limit is {max_duration_s:g} s", status=413)
        mono, peaks, got = _stream(snd, sr, channels, frames, rate_hz)
    if got == 0:
        raise AudioError("contains no decodable audio (0 samples)")
    if got < TRUNCATED_SHARE * frames:
        raise AudioError(
            f"truncated: the header declares {declared_s:.2f} s but only {got / sr:.2f} s can be decoded"
        )
    return Decoded(container, sr, channels, got / sr, mono, rate_hz, peaks)


def _check_wav_length(data: bytes) -> None:
    """Refuse a RIFF/WAVE file whose ``data`` chunk declares more bytes than the file holds.

    libsndfile quietly plays such a file up to where it ends, so a truncated upload would pass as a
    shorter track. (A streamed WAV's unknown length, 0 or 0xFFFFFFFF, is not checked.)
    """
    if data[:4] != b"RIFF":
        return
    pos = 12
    while pos + 8 <= len(data):
        chunk, size = data[pos:pos + 4], int.from_bytes(data[pos + 4:pos + 8], "little")
        if chunk == b"data":
            have = len(data) - pos - 8
            if 0 < size < 0xFFFFFFFF and have < TRUNCATED_SHARE * size:
                raise AudioError(f"truncated: the header declares {size} bytes of samples but the file holds {have}")
            return
        pos += 8 + size + (size & 1)


def _reason(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return text[:200]


def _stream(snd: Any, sr: int, channels: int, frames: int, rate_hz: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Decode block by block: (mono at rate_hz, (B, 2) int8 peaks, frames decoded)."""
    import soundfile as sf
    import soxr

    bucket = max(1, int(round(sr / PEAKS_PER_S)))
    n_buckets = math.ceil(frames / bucket)
    lo = np.zeros(n_buckets, dtype=np.float32)
    hi = np.zeros(n_buckets, dtype=np.float32)
    # Exactly as many output samples as the duration implies (+1 for rounding): no growth beyond.
    out = np.zeros(int(math.ceil(frames * rate_hz / sr)) + 1, dtype=np.float32)
    n_out = 0
    resampler = soxr.ResampleStream(sr, rate_hz, 1, dtype="float32") if sr != rate_hz else None
    got = 0
    try:
        while got < frames:
            block = snd.read(min(BLOCK_FRAMES, frames - got), dtype="float32", always_2d=True)
            if len(block) == 0:
                break
            mono = block.mean(axis=1, dtype=np.float32)
            _peaks_into(mono, got, bucket, lo, hi)
            got += len(mono)
            chunk = resampler.resample_chunk(mono, last=False) if resampler is not None else mono
            take = min(len(chunk), len(out) - n_out)
            out[n_out:n_out + take] = chunk[:take]
            n_out += take
    except (sf.LibsndfileError, RuntimeError) as exc:
        if got == 0:
            raise AudioError(f"cannot decode this file: {_reason(exc)}") from None
        # A decoder error part-way: keep what decoded; the truncation check decides.
    if resampler is not None:
        tail = resampler.resample_chunk(np.zeros(0, dtype=np.float32), last=True)
        take = min(len(tail), len(out) - n_out)
        out[n_out:n_out + take] = tail[:take]
        n_out += take
    used = math.ceil(got / bucket)
    peaks = np.stack([lo[:used], hi[:used]], axis=1)
    peaks = np.clip(np.round(peaks * 127.0), -127, 127).astype(np.int8)
    return out[:n_out], peaks, got


def _peaks_into(mono: np.ndarray, start: int, bucket: int, lo: np.ndarray, hi: np.ndarray) -> None:
    """Fold one block's (S,) samples into the running min / max per bucket (vectorised)."""
    idx = (start + np.arange(len(mono))) // bucket
    first = int(idx[0])
    local = idx - first
    nb = int(local[-1]) + 1
    bmin = np.full(nb, np.inf, dtype=np.float32)
    bmax = np.full(nb, -np.inf, dtype=np.float32)
    np.minimum.at(bmin, local, mono)
    np.maximum.at(bmax, local, mono)
    # A bucket split across blocks: combine with what the previous block left in it.
    seen_first = start % bucket != 0
    lo_seg, hi_seg = lo[first:first + nb], hi[first:first + nb]
    if seen_first:
        bmin[0] = min(bmin[0], lo_seg[0])
        bmax[0] = max(bmax[0], hi_seg[0])
    lo_seg[:] = bmin
    hi_seg[:] = bmax


def analyse_audio(data: bytes, *, max_duration_s: float = MAX_DURATION_S, beats: bool = True) -> dict[str, Any]:
    """Decode ``data`` and return its analysis (JSON-safe): container, rates, duration, peaks, beats.

    Runs in a worker process (seconds of CPU for a long track). Raises :class:`AudioError`.
    """
    dec = decode(data, max_duration_s=max_duration_s)
    out: dict[str, Any] = {
        "container": dec.container,
        "media_type": MEDIA_TYPES[dec.container],
        "sample_rate_hz": dec.sample_rate_hz,
        "channels": dec.channels,
        "duration_s": round(dec.duration_s, 6),
        "peaks_per_s": PEAKS_PER_S,
        "peaks": dec.peaks.reshape(-1).tolist(),
    }
    if beats:
        from app.media._beats import detect_beats

        found = detect_beats(dec.mono, dec.rate_hz)
        out.update(
            tempo_bpm=round(found.tempo_bpm, 3),
            beats_s=[round(float(t), 4) for t in found.beats_s],
            onsets_s=[round(float(t), 4) for t in found.onsets_s],
        )
    return out
