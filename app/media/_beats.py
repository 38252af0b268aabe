"""Beats and onsets of a track, offered to the designer as snap points.

librosa finds them: the onset strength envelope (spectral flux of a log-mel spectrogram,
Böck & Widmer 2013 without the vibrato filter), its peaks as onsets, and Ellis's dynamic
programming beat tracker over it (Ellis 2007, "Beat tracking by dynamic programming",
J. New Music Research 36(1)) for the beats and the tempo.

Both come on a frame grid (``HOP`` samples, 23 ms at 11,025 Hz) and the flux of a centred
analysis window peaks before or after the attack it responds to, so each event is then moved
to the steepest rise of the signal's short-time log energy (1 ms hops) within
:data:`REFINE_WINDOW_S` around it: a transient's attack, to about a millisecond. librosa is
imported here only, in the worker that analyses an upload, never on the app's start path
(its numba kernels compile on first use).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Analysis hop, samples (23 ms at 11,025 Hz; the refinement brings events to ~1 ms).
HOP = 256
#: STFT length of the onset envelope, samples (93 ms; memory: a 20-minute track's spectrogram is ~0.2 GB).
N_FFT = 1024
#: Events are refined to the steepest energy rise within this window around them, seconds (before, after).
REFINE_WINDOW_S = (0.06, 0.04)
#: Energy envelope resolution for the refinement, seconds.
ENVELOPE_STEP_S = 0.001


@dataclass(frozen=True)
class Beats:
    """Tempo (beats per minute), beat times and onset times (seconds from the track's start)."""

    tempo_bpm: float
    beats_s: np.ndarray
    onsets_s: np.ndarray


def detect_beats(y: np.ndarray, sr: int) -> Beats:
    """Beats, tempo and onsets of a mono signal ``y`` (S,) sampled at ``sr`` Hz (see the module docstring)."""
    import librosa

    y = np.ascontiguousarray(y, dtype=np.float32)
    if len(y) < 2 * HOP or not np.any(y):
        return Beats(0.0, np.zeros(0), np.zeros(0))
    env = librosa.onset.onset_strength(y=y, sr=sr, hop_length=HOP, n_fft=N_FFT)
    tempo, beat_frames = librosa.beat.beat_track(onset_envelope=env, sr=sr, hop_length=HOP)
    onset_frames = librosa.onset.onset_detect(onset_envelope=env, sr=sr, hop_length=HOP)
    beats = refine_to_attacks(y, sr, librosa.frames_to_time(beat_frames, sr=sr, hop_length=HOP))
    onsets = refine_to_attacks(y, sr, librosa.frames_to_time(onset_frames, sr=sr, hop_length=HOP))
    beats = np.unique(beats)
    # The tempo from the refined beats (the median interval) is finer than the tracker's frame-grid estimate.
    bpm = 60.0 / float(np.median(np.diff(beats))) if len(beats) >= 3 else float(np.atleast_1d(tempo)[0])
    return Beats(bpm, beats, np.unique(onsets))


def envelope_step(sr: int) -> int:
    """Samples per step of :func:`log_energy` (about :data:`ENVELOPE_STEP_S`)."""
    return max(1, int(round(ENVELOPE_STEP_S * sr)))


def log_energy(y: np.ndarray, sr: int) -> np.ndarray:
    """Short-time log energy of ``y`` (S,), one value per :func:`envelope_step` samples (windows of two steps)."""
    step = envelope_step(sr)
    n = len(y) // step
    power = np.square(y[: n * step].astype(np.float64)).reshape(n, step).sum(axis=1)
    # Two-step windows: the rise is measured over 2 ms, robust to a zero crossing inside one step.
    power[1:] += power[:-1]
    return np.log(power + 1e-10)


def refine_to_attacks(y: np.ndarray, sr: int, times_s: np.ndarray) -> np.ndarray:
    """Move each time (E,) to the steepest log-energy rise within :data:`REFINE_WINDOW_S` of it, seconds."""
    times_s = np.asarray(times_s, dtype=np.float64)
    if times_s.size == 0:
        return times_s
    energy = log_energy(y, sr)
    rise = np.diff(energy, prepend=energy[0])
    step_s = envelope_step(sr) / sr  # the exact step: a rounded one drifts over minutes
    before, after = (int(round(w / step_s)) for w in REFINE_WINDOW_S)
    centre = np.round(times_s / step_s).astype(np.int64)
    idx = centre[:, None] + np.arange(-before, after + 1)[None, :]  # (E, W) envelope indices
    valid = (idx >= 0) & (idx < len(rise))
    score = np.where(valid, rise[np.clip(idx, 0, len(rise) - 1)], -np.inf)
    best = idx[np.arange(len(idx)), np.argmax(score, axis=1)]
    # The rise over [k-1, k] starts at step k - 1 (with two-step windows, the attack's first step).
    return np.maximum(best - 1, 0) * step_s
