"""Media: a show's music, recognised, decoded within bounds, summarised as waveform peaks, beats and onsets."""

from __future__ import annotations

from app.media._audio import MAX_AUDIO_BYTES as MAX_AUDIO_BYTES
from app.media._audio import MAX_DURATION_S as MAX_DURATION_S
from app.media._audio import MEDIA_TYPES as MEDIA_TYPES
from app.media._audio import AudioError as AudioError
from app.media._audio import AudioTrack as AudioTrack
from app.media._audio import analyse_audio as analyse_audio
from app.media._audio import decode as decode
from app.media._audio import sniff_container as sniff_container

__all__ = [
    "MAX_AUDIO_BYTES",
    "MAX_DURATION_S",
    "MEDIA_TYPES",
    "AudioError",
    "AudioTrack",
    "analyse_audio",
    "decode",
    "sniff_container",
]
