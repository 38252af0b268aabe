"""3D playback with viser: the live viewer, its relay through the app's port, and the offline HTML export.

* :class:`Viewer` runs a viser server on loopback with the show's scene, playback
  controls and a 30 Hz playback thread;
* :func:`viewer_router` / :func:`install_viewer` serve viser's client at
  ``/viser/`` and relay its websocket (``/viser``) to that server, so the app's
  one port serves everything;
* :func:`export_viser_html` (re-exported from ``app.exports``, where the
  ``viser-html`` format lives) writes a self-contained HTML file that plays a
  show offline.
"""

from __future__ import annotations

from app.exports import FlightTrack as FlightTrack
from app.exports import Frame as Frame
from app.exports import PlanTrack as PlanTrack
from app.exports import framing_camera as framing_camera
from app.exports import show_bounds as show_bounds
from app.exports._viser_html import DEFAULT_EXPORT_FPS as DEFAULT_EXPORT_FPS
from app.exports._viser_html import export_viser_html as export_viser_html
from app.viewer._install import PlaybackOut as PlaybackOut
from app.viewer._install import PlaybackRequest as PlaybackRequest
from app.viewer._install import install as install
from app.viewer._install import install_viewer as install_viewer
from app.viewer._install import playback_router as playback_router
from app.viewer._relay import CLIENT_BUILD_DIR as CLIENT_BUILD_DIR
from app.viewer._relay import viewer_router as viewer_router
from app.viewer._viewer import FRAME_RATE_HZ as FRAME_RATE_HZ
from app.viewer._viewer import Viewer as Viewer
from sim.geometry import closest_pair as closest_pair

__all__ = [
    "CLIENT_BUILD_DIR",
    "DEFAULT_EXPORT_FPS",
    "FRAME_RATE_HZ",
    "FlightTrack",
    "Frame",
    "PlanTrack",
    "PlaybackOut",
    "PlaybackRequest",
    "Viewer",
    "closest_pair",
    "export_viser_html",
    "framing_camera",
    "install",
    "install_viewer",
    "playback_router",
    "show_bounds",
    "viewer_router",
]
