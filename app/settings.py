"""Server settings, read from ``SWARMSHOW_*`` environment variables (pydantic-settings)."""

from __future__ import annotations

import os
from pathlib import Path

from pydantic import Field, SecretStr, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

#: Largest show file accepted over HTTP, bytes (DESIGN: 20 MB).
MAX_SHOW_BYTES = 20 * 1024 * 1024
#: Largest image accepted, pixels (DESIGN: 40 megapixels). Checked from the header.
MAX_IMAGE_PIXELS = 40_000_000
#: Largest image upload, bytes (a 40 MP PNG compresses far below this).
MAX_IMAGE_BYTES = 50 * 1024 * 1024
#: Largest SVG upload, bytes (DESIGN: 5 MB).
MAX_SVG_BYTES = 5 * 1024 * 1024
#: Largest mesh or point-file upload, bytes (formations.sources.MAX_MESH_BYTES).
MAX_MESH_BYTES = 50 * 1024 * 1024
#: Largest audio upload, bytes (app.media.MAX_AUDIO_BYTES; a 20-minute MP3 is ~30 MB).
MAX_AUDIO_BYTES = 64 * 1024 * 1024
#: Largest body of any other request (JSON formation parameters, updates), bytes.
MAX_OTHER_BYTES = MAX_SHOW_BYTES


def _default_workers() -> int:
    # Two workers keep one CPU free for the event loop and the viewer thread on small machines.
    return max(1, min(2, os.cpu_count() or 1))


class AppSettings(BaseSettings):
    """Settings of the web server. Every field can be set as ``SWARMSHOW_<FIELD>``."""

    model_config = SettingsConfigDict(env_prefix="SWARMSHOW_", extra="ignore")

    data_dir: Path = Field(Path("data"), description="Directory of the SQLite store (created if missing).")
    host: str = Field("127.0.0.1", description="Address to listen on (loopback unless asked otherwise).")
    port: int = Field(8000, ge=0, le=65535, description="TCP port to listen on.")
    workers: int = Field(default_factory=_default_workers, ge=1, le=64, description="Worker processes.")
    max_jobs_kept: int = Field(1000, ge=10, description="Finished jobs remembered in memory (oldest dropped).")
    max_pending_jobs: int = Field(64, ge=1, description="Queued or running jobs accepted before 429.")
    job_timeout_s: float = Field(
        3600.0, gt=0, le=7 * 86_400, description="A background job running longer than this is stopped and fails."
    )
    interactive_workers: int = Field(
        1, ge=1, le=16, description="Worker processes kept for interactive requests (checks, formations, "
        "exports, large saves, viewer planning), apart from the simulation workers.",
    )
    task_timeout_s: float = Field(
        60.0, gt=0, le=3600, description="Time budget of one interactive request's work, seconds (504 after).",
    )
    max_interactive_tasks: int = Field(
        64, ge=1, le=4096, description="Interactive requests queued or running at once before 429.",
    )
    max_jobs_per_client: int = Field(
        16, ge=1, description="Queued or running jobs of one client (session cookie, X-Swarmshow-Client "
        "header or address) before 429.",
    )
    header_timeout_s: float = Field(
        10.0, gt=0, le=600, description="A connection must send its request headers within this many seconds "
        "(slow-loris connections are closed).",
    )
    timeout_keep_alive_s: float = Field(5.0, gt=0, le=600, description="Idle keep-alive connections close "
                                        "after this many seconds.")
    worker_memory_mb: int = Field(
        2048, ge=256, le=1 << 20, description="Memory (heap and private mappings) each worker process may use, "
        "MiB; past it the task fails with 413 instead of the process being killed.",
    )
    max_cached_results: int = Field(500, ge=1, description="Results kept in the content-hash cache.")
    max_show_bytes: int = Field(MAX_SHOW_BYTES, ge=1024, description="Largest show file upload, bytes.")
    max_image_bytes: int = Field(MAX_IMAGE_BYTES, ge=1024, description="Largest image upload, bytes.")
    max_svg_bytes: int = Field(MAX_SVG_BYTES, ge=1024, description="Largest SVG upload, bytes.")
    max_mesh_bytes: int = Field(MAX_MESH_BYTES, ge=1024, description="Largest mesh or point-file upload, bytes.")
    max_audio_bytes: int = Field(MAX_AUDIO_BYTES, ge=1024, description="Largest audio upload (a show's music), bytes.")
    token: SecretStr | None = Field(
        None,
        description="Bearer token every /api and /viser request must carry (required off loopback).",
    )
    allowed_hosts: list[str] = Field(
        default_factory=list,
        description="Host names besides loopback ones a tokenless server answers to (JSON list); any other "
        "Host or Origin gets 421, so that a DNS-rebinding web page cannot reach a loopback server.",
    )
    session_ttl_s: int = Field(
        3600, ge=60, le=86_400, description="Lifetime of the session cookie POST /api/session sets, seconds."
    )
    access_log: bool = Field(False, description="Log every request (off: a write to stdout per request costs "
                             "latency under load; errors are logged either way).")
    viewer: bool = Field(True, description="Run the 3D viewer (off: /viser answers 503; starts faster).")
    keep_revisions: int = Field(
        200, ge=1, description="Show file texts kept per show in its revision history (older: metadata only)."
    )
    dask_scheduler: str | None = Field(
        None, description="Dask scheduler (tcp://HOST:PORT, or 'local') that flies simulation jobs "
        "sharded over drones; unset: the local in-process engine.",
    )
    static_dir: Path | None = Field(
        None, description="Directory served at / (default: the bundled editor, if present)."
    )

    @field_validator("token", mode="before")
    @classmethod
    def _strong_token(cls, value: object) -> object:
        # An empty variable means "no token"; a short one would be guessed, so it is refused outright.
        raw = value.get_secret_value() if isinstance(value, SecretStr) else value
        if raw is None or raw == "":
            return None
        if not isinstance(raw, str) or len(raw.strip()) < 16 or raw != raw.strip():
            raise ValueError("must be at least 16 characters without surrounding spaces")
        return value

    @property
    def db_path(self) -> Path:
        """The SQLite database file inside ``data_dir``."""
        return self.data_dir / "swarmshow.sqlite3"
