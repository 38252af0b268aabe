"""The live 3D viewer: a loopback viser server, its scene, GUI and a 30 Hz playback thread.

One :class:`Viewer` holds the shows; each browser gets its own playback on its own
scene and GUI (``client.scene``, ``client.gui``) in per-client mode (the app's), or
every browser sees one server-wide playback. Besides the drones it draws the check's
violations and, with a flight, the gap to the plan (:mod:`app.viewer._marks`). The
app relays browsers to it through its own port (see :mod:`app.viewer._relay`).
"""

from __future__ import annotations

import contextlib
import html
import io
import secrets
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
import viser

from app.exports import (
    Frame,
    PlanTrack,
    Source,
    Track,
    framing_camera,
    make_track,
    show_bounds,
)
from app.viewer._marks import Problem, active_problems, deviation_colors, problem_list, problem_segments
from sim import ShowPlan
from sim.geometry import closest_pair

#: Playback pacing, frames per second.
FRAME_RATE_HZ = 30.0
#: Trails are recomputed at this lower rate (they are N·M segments, the heaviest message).
TRAIL_RATE_HZ = 10.0
#: Trail length: this many past samples, ``TRAIL_STEP_S`` apart.
TRAIL_SAMPLES = 6
TRAIL_STEP_S = 0.25
#: Above this many drones trails start switched off (N·M segments at 10 Hz is megabytes a second).
TRAILS_DEFAULT_MAX_DRONES = 3000
SPEEDS = ("0.25x", "0.5x", "1x", "2x", "4x", "8x")
#: A dark LED is drawn at this grey level so that an unlit drone stays visible on the night sky.
DARK_LED_FLOOR = 0.2
NO_SHOW = "(no show loaded)"
#: Shows kept in the registry (a simulated flight can be hundreds of MB); the oldest go first.
MAX_SHOWS = 8
#: Below this canvas width (pixels) a browser's control panel starts minimised (a phone, the editor's preview pane).
COMPACT_WIDTH_PX = 800

CatalogFn = Callable[[], Mapping[str, str]]
LoadFn = Callable[[str], None]


@dataclass
class _Entry:
    """A show in the viewer's registry."""

    name: str
    plan: ShowPlan
    flight: Any = None
    #: The check report (``CheckReport.to_json()``) once it is known.
    report: Any = None
    lights: Any = None  # the show's light effects (sim.light.LightStack), painted over the colours


#: How many drones' colours the page's hidden state element carries (a test hook; small to keep frames light).
LINK_COLORS = 64
#: Eye height of the audience camera, metres.
AUDIENCE_EYE_M = 1.7
CAMERAS = ("free", "audience")


def audience_camera(
    lo: np.ndarray, hi: np.ndarray, *, fov_rad: float = 1.3, audience_y_m: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The audience's view (position, look-at), metres: from eye height on the audience side (−y),
    facing +y towards the show's centre.

    The audience stands at ``audience_y_m`` (the geofence's audience edge) when given, else
    far enough back for the show's bounding sphere to fit the vertical field of view.
    """
    center = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 5.0)
    back = radius / np.sin(fov_rad / 2.0) * 1.05
    y = float(audience_y_m) if audience_y_m is not None else float(center[1]) - back
    return np.array([center[0], y, AUDIENCE_EYE_M]), center


class _Playback:
    """One playback: which show, source, time, speed and display toggles, with its own scene and GUI.

    A playback draws on a scene and GUI API: a browser client's own (``client.scene``,
    ``client.gui``: what one browser sees), the server-wide ones (every browser: the
    single-playback mode), or none (headless: the frames are computed for the API and tests).
    """

    def __init__(self, viewer: Viewer, *, scene: Any = None, gui: Any = None, client: Any = None) -> None:
        self.viewer, self.scene, self.gui, self.client = viewer, scene, gui, client
        self.headless = scene is None
        self.atomic = client.atomic if client is not None else viewer.server.atomic
        self._current: str | None = None
        self._source: Source = "planned"
        self._track: Track | None = None
        self._time_s = 0.0
        self._playing = False
        self._speed = 1.0
        self._loop = True
        self._dirty = False
        self._last_trail_s = -np.inf
        self._pair_hint_m: float | None = None
        self._next_target: int | None = None
        self._hold_starts_s = np.zeros(0)
        self._hold_knots = np.zeros(0, dtype=np.intp)
        #: A show picked in the selector that is being loaded (it switches when it arrives).
        self.wanted: str | None = None
        #: "free" or "audience" (see :meth:`set_camera`).
        self.camera = "free"
        self._bounds = (np.zeros(3), np.ones(3))
        # Set while Python writes a GUI value, so that the write's own
        # synchronous on_update callback is not mistaken for a user's input.
        self._programmatic = 0
        self.frames_rendered = 0
        #: Names this playback to the editor of the same browser tab (read from the page, see _setup_gui).
        self.token = secrets.token_urlsafe(12)
        #: The editor's unsaved effect stack for this tab (``POST /api/viewer/{token}/lights``), painted
        #: instead of the saved one until another show (or a new version of this one) is loaded.
        self._lights_override: tuple[Any] | None = None
        #: Counts the effect stacks this playback has been given (the editor reads it from the page).
        self.lights_rev = 0
        self._problems: list[Problem] = []
        self._plan_track: PlanTrack | None = None
        #: (K, 2, 3) the violation marks drawn in the last frame, metres.
        self.last_problem_segments = np.zeros((0, 2, 3), dtype=np.float32)
        #: (N,) flown-minus-planned distance of each drone in the last frame (None: not shown), metres.
        self.last_deviation_m: np.ndarray | None = None
        self.last_frame: Frame | None = None
        self.last_pair: tuple[int, int, float] = (-1, -1, float("inf"))
        if self.headless:
            # No GUI: the display toggles are a namespace with every toggle on.
            # (Typed Any like the viser handles they stand in for: viser has no type information.)
            on: Any = _Toggle(True)
            self._targets_cb = self._trails_cb = self._pair_cb = self._homes_cb = self._loop_cb = on
            self._problems_cb = self._gap_cb = on
            # No widgets either: _set_gui ignores writes to them.
            none: Any = None
            self._show_dd = self._source_dd = self._play = self._slider = self._speed_dd = self._camera_dd = none
            self._readout = self._progress = self._busy_md = self._next_problem = self._link = none
        else:
            self._setup_scene()
            self._setup_gui()

    def remove(self) -> None:
        """Forget this playback's handles (its client has gone)."""
        self._track = None
        self._playing = False

    def _setup_scene(self) -> None:
        scene = self.scene
        # Metre grid: 5 m cells, 50 m sections, resized to the show on load.
        self._grid = scene.add_grid(
            "/ground", width=200.0, height=200.0, plane="xy", cell_size=5.0, section_size=50.0,
            cell_color=(60, 60, 70), section_color=(110, 110, 125), shadow_opacity=0.0,
        )
        empty = np.zeros((1, 3), dtype=np.float32)
        self._homes = scene.add_point_cloud(
            "/home_grid", empty, (90, 90, 100), point_size=0.6, point_shape="square", precision="float32",
            visible=False,
        )
        self._targets = scene.add_point_cloud(
            "/next_targets", empty, (255, 255, 255), point_size=0.5, point_shape="diamond",
            precision="float32", visible=False,
        )
        self._drones = scene.add_point_cloud(
            "/drones", empty, (255, 255, 255), point_size=1.5, point_shape="circle", precision="float32",
            visible=False,
        )
        seg = np.zeros((1, 2, 3), dtype=np.float32)
        self._trails = scene.add_line_segments(
            "/trails", seg, (255, 255, 255), thickness=1.5, thickness_units="screen", visible=False
        )
        self._pair_line = scene.add_line_segments(
            "/closest_pair/line", seg, (255, 60, 60), thickness=3.0, thickness_units="screen", visible=False
        )
        self._pair_label = scene.add_label(
            "/closest_pair/label", "", anchor="bottom-center", visible=False
        )
        self._problem_lines = scene.add_line_segments(
            "/violations/marks", seg, (255, 40, 40), thickness=6.0, thickness_units="screen", visible=False
        )
        self._problem_label = scene.add_label("/violations/label", "", anchor="bottom-center", visible=False)
        self._planned_ghost = scene.add_point_cloud(
            "/planned_ghost", empty, (150, 150, 170), point_size=0.6, point_shape="circle", precision="float32",
            visible=False,
        )
        self._gap_lines = scene.add_line_segments(
            "/deviation", seg, (0, 255, 0), thickness=3.0, thickness_units="screen", visible=False
        )

    def _setup_gui(self) -> None:
        gui = self.gui
        gui.set_panel_label("swarmshow playback")
        self._show_dd = gui.add_dropdown("Show", (NO_SHOW,), initial_value=NO_SHOW)
        self._source_dd = gui.add_dropdown("Source", ("planned", "simulated"), initial_value="planned",
                                           disabled=True, hint="The simulated flight needs a simulation run")
        self._play = gui.add_button("Play", icon=viser.Icon.PLAYER_PLAY, disabled=True)
        self._slider = gui.add_slider("Time (s)", min=0.0, max=1.0, step=0.05, initial_value=0.0, disabled=True)
        self._speed_dd = gui.add_dropdown("Speed", SPEEDS, initial_value="1x")
        self._loop_cb = gui.add_checkbox("Loop", initial_value=True)
        self._camera_dd = gui.add_dropdown("Camera", CAMERAS, initial_value="free",
                                           hint="audience: the front view from the audience side")
        self._next_problem = gui.add_button("Next problem", icon=viser.Icon.ALERT_TRIANGLE, disabled=True,
                                            hint="Jump to the next violation of the check (drawn in red)")
        with gui.add_folder("Display"):
            self._targets_cb = gui.add_checkbox("Next formation targets", initial_value=True)
            self._trails_cb = gui.add_checkbox("Trails", initial_value=True)
            self._pair_cb = gui.add_checkbox("Closest pair", initial_value=True)
            self._homes_cb = gui.add_checkbox("Home grid", initial_value=True)
            self._problems_cb = gui.add_checkbox("Violations", initial_value=True,
                                                 hint="Red marks on the drones around each violation's time")
            self._gap_cb = gui.add_checkbox("Planned beside flown", initial_value=True,
                                            hint="With the simulated flight: the plan in grey, the gap coloured "
                                            "green (on the plan) to red (half the minimum distance off)")
        self._readout = gui.add_markdown(
            "No show loaded: pick one under **Show**, or send one from the editor "
            "(`POST /api/shows/{id}/playback`)."
        )
        self._progress = gui.add_progress_bar(0.0, visible=False, animated=True)
        self._busy_md = gui.add_markdown("", visible=False)
        # The editor embeds this page (same origin) and reads the token and the playhead from this element
        # to drive this tab's playback only (POST /api/viewer/{token}/seek).
        self._link = gui.add_html(self._link_html())

        self._show_dd.on_update(self._user(self._on_show_selected))
        self._source_dd.on_update(self._user(lambda ev: self.set_source(ev.target.value)))
        self._play.on_click(lambda _ev: self.toggle_play())
        self._slider.on_update(self._user(lambda ev: self.seek(float(ev.target.value))))
        self._speed_dd.on_update(lambda ev: self._set_speed_label(ev.target.value))
        self._loop_cb.on_update(lambda ev: setattr(self, "_loop", bool(ev.target.value)))
        self._camera_dd.on_update(self._user(lambda ev: self.set_camera(str(ev.target.value))))
        self._next_problem.on_click(lambda _ev: self.next_problem())
        for cb in (self._targets_cb, self._trails_cb, self._pair_cb, self._homes_cb, self._problems_cb, self._gap_cb):
            cb.on_update(lambda _ev: self._invalidate())

    def _link_html(self, colors_rgb: np.ndarray | None = None) -> str:
        """The hidden element naming this playback and its playhead (time, and the formation it is in or going to),
        the effect stack it paints (its revision, 0: the saved show's) and the LED colours of its first drones
        (``data-rgb``, hex, at most :data:`LINK_COLORS`) in the frame on screen."""
        seg_kind, formation = self._phase(self._time_s)
        # 0 while the saved effects show (a new load drops the editor's): the editor then sends its own again.
        lights = self.lights_rev if self._lights_override is not None else 0
        rgb = ""
        if colors_rgb is not None:
            c = np.clip(np.round(np.asarray(colors_rgb[:LINK_COLORS]) * 255.0), 0, 255).astype(int)
            rgb = " ".join(f"#{r:02x}{g:02x}{b:02x}" for r, g, b in c)
        return (f'<span id="swarmshow-viewer" hidden data-token="{html.escape(self.token)}" '
                f'data-time="{self._time_s:.2f}" data-phase="{seg_kind}" data-formation="{formation}" '
                f'data-playing="{int(self._playing)}" data-lights="{lights}" data-rgb="{rgb}"></span>')

    def _phase(self, t: float) -> tuple[str, int]:
        """(segment kind, formation index) at ``t``: the hold's formation, or the one a transition leads into."""
        if self._current is None:
            return "none", -1
        plan = self.viewer._shows[self._current].plan
        k = int(plan.segment_index(t))
        seg = plan.segments[k]
        holds_before = sum(1 for s in plan.segments[:k] if s.kind == "hold")
        if seg.kind == "hold":
            return "hold", holds_before
        if seg.kind == "transition" and holds_before < len(self._hold_starts_s):
            return "transition", holds_before
        return str(seg.kind), -1

    def _user(self, fn: Callable[[Any], None]) -> Callable[[Any], None]:
        """Wrap a GUI callback to run only for a browser's input, not for Python's own writes."""

        def callback(event: Any) -> None:
            # viser calls on_update synchronously when Python assigns .value
            # (with client None); without this guard the playback thread's
            # slider updates would seek, re-render and set the slider again.
            if self._programmatic or event.client is None:
                return
            fn(event)

        return callback

    def _set_gui(self, handle: Any, attr: str, value: Any) -> None:
        """Assign a GUI property from Python without triggering the user callbacks (none when headless)."""
        if self.headless:
            return
        with self.viewer._lock:
            self._programmatic += 1
            try:
                setattr(handle, attr, value)
            finally:
                self._programmatic -= 1

    def _refresh_show_options(self) -> None:
        v = self.viewer
        with v._lock:
            labels = list(v._shows)
            for label in v._catalog_keys:
                if label not in v._shows:
                    labels.append(label)
            # Until a show is loaded the selector says so, with the stored shows below it.
            options = labels if self._current is not None else [NO_SHOW, *labels]
            self._set_gui(self._show_dd, "options", options)
            self._set_gui(self._show_dd, "value", self._current or NO_SHOW)

    def _on_show_selected(self, event: Any) -> None:
        label = str(event.target.value)
        v = self.viewer
        with v._lock:
            if label in v._shows:
                self._activate(label, self._source if v._shows[label].flight is not None else "planned")
                return
            key = v._catalog_keys.get(label)
            # The load names the show by its label: this playback switches to it when it arrives.
            self.wanted = label
        if key is not None and v._catalog_load is not None:
            if not v._loading.acquire(blocking=False):
                client = getattr(event, "client", None)
                if client is not None:
                    v._notify(client, "Another show is loading; pick again when it is on screen.")
                return
            load = v._catalog_load

            def run() -> None:
                try:
                    load(key)
                finally:
                    v._loading.release()

            try:
                v._load_pool.submit(run)
            except RuntimeError:  # the viewer is stopping
                v._loading.release()

    # ----------------------------------------------------------------- state

    @property
    def current(self) -> str | None:
        """Name of the show on screen."""
        return self._current

    @property
    def source(self) -> Source:
        """``"planned"`` or ``"simulated"``."""
        return self._source

    @property
    def time_s(self) -> float:
        """Playback time, seconds."""
        return self._time_s

    @property
    def playing(self) -> bool:
        """Whether playback is running."""
        return self._playing

    @property
    def speed(self) -> float:
        """Playback speed factor."""
        return self._speed

    def _activate(self, name: str, source: Source) -> None:
        with self.viewer._lock:
            entry = self.viewer._shows[name]
            self._lights_override = None
            self._track = make_track(entry.plan, entry.flight, source, entry.lights)
            self._current, self._source = name, source
            self._time_s = 0.0
            self._playing = False
            self._pair_hint_m = None
            self._last_trail_s = -np.inf
            self._next_target = None
            plan = entry.plan
            holds = [seg for _, seg in plan.formation_segments()]
            self._hold_starts_s = np.array([s.start_s for s in holds])
            self._hold_knots = np.array([s.index for s in holds], dtype=np.intp)
            self._problems = problem_list(entry.report)
            self._set_gui(self._next_problem, "disabled", not self._problems)
            self._plan_track = None

            n = plan.drone_count
            spacing = float(plan.settings.min_distance_m)
            lo, hi = show_bounds(plan, entry.flight)
            if self.headless:
                self.render()
                return
            with self.atomic():
                # Ground grid sized to the show's footprint, in whole 50 m sections.
                span = float(np.max(hi[:2] - lo[:2])) + 40.0
                size = 50.0 * np.ceil(span / 50.0)
                self._grid.width = self._grid.height = size
                self._grid.position = (float((lo[0] + hi[0]) / 2), float((lo[1] + hi[1]) / 2), 0.0)
                homes = plan.knot_positions_m[0]
                self._homes.points = homes.astype(np.float32)
                self._homes.point_size = 0.25 * spacing
                self._drones.point_size = float(np.clip(0.45 * spacing, 0.5, 2.5))
                self._targets.point_size = float(np.clip(0.25 * spacing, 0.3, 1.5))
                self._set_gui(self._trails_cb, "value", n <= TRAILS_DEFAULT_MAX_DRONES)
                self._set_gui(self._slider, "max", max(float(self._track.duration_s), 0.05))
                self._set_gui(self._slider, "value", 0.0)
                self._set_gui(self._slider, "disabled", False)
                self._set_gui(self._play, "disabled", False)
                self._set_gui(self._play, "label", "Play")
                self._set_gui(self._play, "icon", viser.Icon.PLAYER_PLAY)
                self._set_gui(self._source_dd, "disabled", entry.flight is None)
                self._set_gui(self._source_dd, "value", source)
                self._set_gui(self._show_dd, "value", name)
                self._bounds = (lo, hi)
                self._place_camera()
            self.render()

    def set_camera(self, mode: str) -> None:
        """``"audience"``: the front view from the audience side; ``"free"``: the oblique overview (then orbit)."""
        if mode not in CAMERAS:
            raise ValueError(f"camera must be one of {CAMERAS}, got {mode!r}")
        self.camera = mode
        self._set_gui(self._camera_dd, "value", mode)
        if self._current is not None and not self.headless:
            self._place_camera()

    def seek_formation(self, index: int) -> float | None:
        """Jump to the start of formation ``index``'s hold; returns that time (None: no such formation)."""
        with self.viewer._lock:
            if self._track is None or not 0 <= index < len(self._hold_starts_s):
                return None
            self.seek(float(self._hold_starts_s[index]))
            return self._time_s

    def next_problem(self) -> float | None:
        """Jump to the next violation after the playhead (the first one after the last); returns its time."""
        with self.viewer._lock:
            if self._track is None or not self._problems:
                return None
            times = np.array([p.time_s for p in self._problems])
            later = times[times > self._time_s + 1e-6]
            self.seek(float(later[0] if len(later) else times[0]))
            return self._time_s

    def set_report(self, report: Any) -> None:
        """Take the check report of the show on screen (its violations are drawn)."""
        with self.viewer._lock:
            self._problems = problem_list(report)
            self._set_gui(self._next_problem, "disabled", not self._problems)
            self._invalidate()

    def _place_camera(self) -> None:
        server = self.viewer.server
        lo, hi = self._bounds
        fov = server.initial_camera.fov
        if self.camera == "audience":
            fence = self.viewer._shows[self._current].plan.settings.geofence if self._current else None
            position, look_at = audience_camera(lo, hi, fov_rad=fov, audience_y_m=fence.y_min_m if fence else None)
        else:
            position, look_at = framing_camera(lo, hi, fov_rad=fov)
        if self.client is None:
            server.initial_camera.position = tuple(position)
            server.initial_camera.look_at = tuple(look_at)
        for client in [self.client] if self.client is not None else server.get_clients().values():
            client.camera.position = tuple(position)
            client.camera.look_at = tuple(look_at)

    def set_source(self, source: Source) -> None:
        """Switch between the plan and the simulated flight of the current show, keeping the time."""
        with self.viewer._lock:
            if self._current is None:
                return
            entry = self.viewer._shows[self._current]
            if source == "simulated" and entry.flight is None:
                self._set_gui(self._source_dd, "value", self._source)
                return
            t = self._time_s
            self._track = make_track(entry.plan, entry.flight, source, self._lights_of(entry))
            self._source = source
            self._set_gui(self._source_dd, "value", source)
            self._set_gui(self._slider, "max", max(float(self._track.duration_s), 0.05))
            self._time_s = min(t, self._track.duration_s)
            self._pair_hint_m = None
            self._invalidate()

    # ----------------------------------------------------------------- transport

    def play(self) -> None:
        """Start playback (from the start if at the end)."""
        with self.viewer._lock:
            if self._track is None:
                return
            if self._time_s >= self._track.duration_s:
                self._time_s = 0.0
            self._playing = True
            self._set_gui(self._play, "label", "Pause")
            self._set_gui(self._play, "icon", viser.Icon.PLAYER_PAUSE)

    def pause(self) -> None:
        """Pause playback."""
        with self.viewer._lock:
            self._playing = False
            self._set_gui(self._play, "label", "Play")
            self._set_gui(self._play, "icon", viser.Icon.PLAYER_PLAY)
            self._invalidate()

    def toggle_play(self) -> None:
        """Play if paused, pause if playing."""
        if self._playing:
            self.pause()
        else:
            self.play()

    def _lights_of(self, entry: _Entry) -> Any:
        return entry.lights if self._lights_override is None else self._lights_override[0]

    def plan(self) -> ShowPlan | None:
        """The plan of the show on screen, None when there is none."""
        with self.viewer._lock:
            return None if self._current is None else self.viewer._shows[self._current].plan

    def set_lights(self, plan: ShowPlan, lights: Any) -> bool:
        """Paint ``lights`` (a ``sim.light.LightStack`` over ``plan``, or None: no effects) instead of the
        saved show's effects, keeping the time. False (and nothing changes) when ``plan`` is no longer on screen."""
        with self.viewer._lock:
            if self._current is None:
                return False
            entry = self.viewer._shows[self._current]
            if entry.plan is not plan:
                return False
            self._lights_override = (lights if lights else None,)
            self.lights_rev += 1
            self._track = make_track(entry.plan, entry.flight, self._source, self._lights_override[0])
            self._invalidate()
            return True

    def seek(self, time_s: float) -> None:
        """Jump to ``time_s`` (seconds, clamped); the next tick renders it."""
        with self.viewer._lock:
            if self._track is None:
                return
            self._time_s = float(np.clip(time_s, 0.0, self._track.duration_s))
            self._pair_hint_m = None
            self._invalidate()

    def set_speed(self, speed: float) -> None:
        """Playback speed factor (0.25 to 8)."""
        self._speed = float(np.clip(speed, 0.25, 8.0))
        self._set_gui(self._speed_dd, "value", min(SPEEDS, key=lambda s: abs(float(s[:-1]) - self._speed)))

    def _set_speed_label(self, label: str) -> None:
        self._speed = float(label.rstrip("x"))

    def _invalidate(self) -> None:
        self._dirty = True
        self._last_trail_s = -np.inf

    # ----------------------------------------------------------------- frames

    def _next_targets_knot(self, t: float) -> int | None:
        """Knot index of the next formation's targets at time t (landing homes after the last)."""
        if self._track is None or self._current is None:
            return None
        k = int(np.searchsorted(self._hold_starts_s, t, side="right"))
        if k < len(self._hold_knots):
            return int(self._hold_knots[k])
        return len(self.viewer._shows[self._current].plan.knot_times_s) - 1

    def _formation_text(self, t: float) -> str:
        plan = self.viewer._shows[self._current].plan if self._current else None
        if plan is None:
            return ""
        seg = plan.segments[int(plan.segment_index(t))]
        return {
            "takeoff": "takeoff",
            "transition": f"→ {seg.label}",
            "hold": seg.label,
            "landing": "landing",
        }[seg.kind]

    def render(self, *, frame_dt_s: float | None = None) -> Frame | None:
        """Push the frame at the current time to this playback's browser(s) and return it.

        Args:
            frame_dt_s: show time elapsed since the previous frame, seconds
                (bounds how far the closest distance can have moved, to speed its search).
        """
        v = self.viewer
        with v._lock:
            track = self._track
            if track is None:
                return None
            t = self._time_s
            frame = track.frame(t)
            colors = np.clip(DARK_LED_FLOOR + (1.0 - DARK_LED_FLOOR) * frame.colors_rgb, 0.0, 1.0)
            show_pair = bool(self._pair_cb.value if not self.headless else True) and track.drone_count >= 2
            pending = None
            if show_pair:
                hint = None
                if self._pair_hint_m is not None and frame_dt_s is not None:
                    # Two drones at most max speed apart close by 2·v·dt; 1 % slack for rounding.
                    hint = self._pair_hint_m * 1.01 + 2.0 * frame.max_speed_mps * abs(frame_dt_s) + 1e-3
                # The search releases the GIL: run it beside the drone update below.
                pending = v._pair_pool.submit(closest_pair, frame.positions_m, hint_m=hint)
            near = active_problems(self._problems, t) if bool(self._problems_cb.value) else []
            self.last_problem_segments = problem_segments(near, frame.positions_m)
            planned = None
            if self._source == "simulated" and bool(self._gap_cb.value) and self._current is not None:
                if self._plan_track is None:
                    self._plan_track = PlanTrack(v._shows[self._current].plan)
                planned = self._plan_track.frame(t).positions_m
                self.last_deviation_m = np.linalg.norm(frame.positions_m - planned, axis=1)
            else:
                self.last_deviation_m = None
            if self.headless:
                if pending is not None:
                    self.last_pair = pending.result()
                    self._pair_hint_m = self.last_pair[2]
                self.last_frame = frame
                self.frames_rendered += 1
                self._dirty = False
                return frame

            with self.atomic():
                self._drones.points = frame.positions_m.astype(np.float32)
                self._drones.colors = (colors * 255.0).astype(np.uint8)
                self._drones.visible = True
                self._homes.visible = bool(self._homes_cb.value)
                self._update_targets(t)
                self._update_trails(track, t, frame)
                if pending is not None:
                    i, j, d = pending.result()
                    self._pair_hint_m = d
                    self.last_pair = (i, j, d)
                    ends = frame.positions_m[[i, j]]
                    self._pair_line.points = ends[None].astype(np.float32)
                    self._pair_label.text = f"{d:.2f} m"
                    self._pair_label.position = tuple(ends.mean(axis=0) + [0.0, 0.0, 1.0])
                self._pair_line.visible = show_pair
                self._pair_label.visible = show_pair
                self._draw_marks(near, frame, planned)
                pair_text = (
                    f"{self.last_pair[2]:.2f} m (#{self.last_pair[0]}–#{self.last_pair[1]})" if show_pair else "–"
                )
                self._readout.content = (
                    f"**Time** {t:6.1f} / {track.duration_s:.1f} s · {self._source}  \n"
                    f"**Formation** {self._formation_text(t)}  \n"
                    f"**Min distance** {pair_text}  \n"
                    f"**Max speed** {frame.max_speed_mps:.2f} m/s · {track.drone_count} drones"
                    + self._problem_text(near) + self._deviation_text()
                )
                self._set_gui(self._slider, "value", round(t / 0.05) * 0.05)
                self._set_gui(self._link, "content", self._link_html(frame.colors_rgb))
            self.last_frame = frame
            self.frames_rendered += 1
            self._dirty = False
            return frame

    def _problem_text(self, near: list[Problem]) -> str:
        if not self._problems:
            return ""
        now = f" · now: {near[0].text}" if near else ""
        return f"  \n**Problems** {len(self._problems)} in the check{now}"

    def _deviation_text(self) -> str:
        dev = self.last_deviation_m
        if dev is None or len(dev) == 0:
            return ""
        worst = int(np.argmax(dev))
        biggest, mean = _length(float(dev[worst])), _length(float(dev.mean()))
        return f"  \n**Flown vs planned** max {biggest} (#{worst}) · mean {mean}"

    def _draw_marks(self, near: list[Problem], frame: Frame, planned: np.ndarray | None) -> None:
        """Violations near the playhead in red; with the flight, the plan in grey and each drone's gap coloured."""
        segs = self.last_problem_segments
        show = len(segs) > 0
        if show:
            self._problem_lines.points = segs
            self._problem_label.text = f"⚠ {near[0].text}"
            self._problem_label.position = tuple(segs[0].mean(axis=0) + [0.0, 0.0, 1.5])
        self._problem_lines.visible = show
        self._problem_label.visible = show
        gap = planned is not None and self.last_deviation_m is not None
        if gap:
            assert planned is not None and self.last_deviation_m is not None
            plan = self.viewer._shows[self._current].plan if self._current else None
            scale = 0.5 * float(plan.settings.min_distance_m) if plan is not None else 1.0
            cols = deviation_colors(self.last_deviation_m, scale)
            self._planned_ghost.points = planned.astype(np.float32)
            self._planned_ghost.point_size = float(self._drones.point_size) * 0.6
            self._gap_lines.points = np.stack([planned, frame.positions_m], axis=1).astype(np.float32)
            self._gap_lines.colors = np.repeat(cols[:, None, :], 2, axis=1)
        self._planned_ghost.visible = gap
        self._gap_lines.visible = gap

    def _update_targets(self, t: float) -> None:
        show = bool(self._targets_cb.value)
        self._targets.visible = show
        if not show or self._current is None:
            return
        knot = self._next_targets_knot(t)
        if knot == self._next_target or knot is None:
            return
        plan = self.viewer._shows[self._current].plan
        pts = plan.knot_positions_m[knot]
        col = plan.knot_colors_rgb[knot]
        self._targets.points = pts.astype(np.float32)
        self._targets.colors = (np.clip(0.35 + 0.65 * col, 0, 1) * 255).astype(np.uint8)
        self._next_target = knot

    def _update_trails(self, track: Track, t: float, frame: Frame) -> None:
        show = bool(self._trails_cb.value)
        self._trails.visible = show
        if not show:
            return
        # Lower rate than the drones: trails are the heaviest message by far.
        if abs(t - self._last_trail_s) < self._speed / TRAIL_RATE_HZ and np.isfinite(self._last_trail_s):
            return
        self._last_trail_s = t
        times = t - TRAIL_STEP_S * np.arange(TRAIL_SAMPLES + 1)
        pos = track.positions(times)  # (M+1, N, 3), newest first
        seg = np.stack([pos[:-1], pos[1:]], axis=2)  # (M, N, 2, 3)
        seg = seg.transpose(1, 0, 2, 3).reshape(-1, 2, 3)
        # Older pieces fade towards the background.
        fade = np.linspace(0.8, 0.15, TRAIL_SAMPLES)
        base = np.clip(DARK_LED_FLOOR + (1 - DARK_LED_FLOOR) * frame.colors_rgb, 0, 1)
        col = base[:, None, None, :] * fade[None, :, None, None]
        col = np.broadcast_to(col, (track.drone_count, TRAIL_SAMPLES, 2, 3)).reshape(-1, 2, 3)
        self._trails.points = seg.astype(np.float32)
        self._trails.colors = (col * 255).astype(np.uint8)

    # ----------------------------------------------------------------- thread

    def step(self, wall_dt_s: float) -> Frame | None:
        """Advance playback by ``wall_dt_s`` seconds of wall time and render if anything changed."""
        with self.viewer._lock:
            if self._track is None:
                return None
            dt = 0.0
            if self._playing:
                dt = wall_dt_s * self._speed
                t = self._time_s + dt
                if t >= self._track.duration_s:
                    if self._loop:
                        t = 0.0
                        self._pair_hint_m = None
                        dt = 0.0
                    else:
                        t = self._track.duration_s
                        self.pause()
                self._time_s = t
            elif not self._dirty:
                return None
            return self.render(frame_dt_s=dt if self._playing else None)



def _length(value_m: float) -> str:
    """A small length readably: millimetres below 10 cm (a well-tracked flight is off by fractions of one)."""
    return f"{value_m * 1000.0:.2f} mm" if value_m < 0.1 else f"{value_m:.2f} m"


class _Toggle:
    """A display toggle without a GUI (headless playbacks draw everything)."""

    def __init__(self, value: bool) -> None:
        self.value = value


class Viewer:
    """A viser server on loopback: a registry of shows and their playback.

    With ``per_client`` each browser gets its own playback (show, time, speed, source,
    display toggles, on its own scene and GUI), so one tab opening or scrubbing a show
    leaves the others alone; the viewer's own transport methods (:meth:`seek`,
    :meth:`play`, ...) then act on every browser and on the *default* playback that new
    browsers start from. Without it one playback on the server-wide scene is seen by all.

    Args:
        host: interface to bind; loopback by default (browsers reach it through the app's relay).
        port: TCP port; 0 picks a free one (see :attr:`port`).
        frame_rate_hz: playback pacing, frames per second.
        start_thread: start the playback thread (tests drive :meth:`step` by hand instead).
        per_client: one playback per browser client.
    """

    def __init__(
        self,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        frame_rate_hz: float = FRAME_RATE_HZ,
        start_thread: bool = True,
        per_client: bool = False,
    ) -> None:
        # viser prints a banner to stdout even when not verbose; the app logs elsewhere.
        with contextlib.redirect_stdout(io.StringIO()):
            self.server = viser.ViserServer(host=host, port=port, verbose=False)
        # The share button is hidden, but a client could still ask for a share
        # URL, which opens a public tunnel: refuse, the app's port is the only way in.
        self.server.request_share_url = lambda *args, **kwargs: None  # type: ignore[method-assign]
        self.frame_rate_hz = float(frame_rate_hz)
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._shows: dict[str, _Entry] = {}
        self._catalog: CatalogFn | None = None
        self._catalog_load: LoadFn | None = None
        self._catalog_keys: dict[str, str] = {}
        self._busy: tuple[str, float | None] | None = None
        self._notifications: dict[int, Any] = {}
        self.per_client = bool(per_client)
        self._pair_pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="viewer-closest-pair")
        # One loader thread for every browser's picks; a pick while one loads is refused, not queued
        # (a client sending selections in a loop once started one thread, and one plan, each).
        self._load_pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="viewer-catalog-load")
        self._loading = threading.Lock()
        scene = self.server.scene
        scene.set_up_direction("+z")
        self.server.gui.configure_theme(dark_mode=True, show_share_button=False, control_width="medium")
        self.server.initial_camera.far = 5000.0
        #: The default playback: server-wide (single mode) or headless (per client: new browsers copy it).
        self._main = _Playback(self) if per_client else _Playback(self, scene=scene, gui=self.server.gui)
        #: Each browser's own playback, by client id (per-client mode).
        self._clients: dict[int, _Playback] = {}
        self.server.on_client_connect(self._on_connect)
        self.server.on_client_disconnect(self._on_disconnect)
        self._thread: threading.Thread | None = None
        if start_thread:
            self._thread = threading.Thread(target=self._run, name="viewer-playback", daemon=True)
            self._thread.start()

    # ----------------------------------------------------------------- lifecycle

    @property
    def host(self) -> str:
        """Interface the viser server listens on."""
        return self.server.get_host()

    @property
    def port(self) -> int:
        """TCP port the viser server listens on."""
        return self.server.get_port()

    def stop(self) -> None:
        """Stop the playback thread and the viser server (idempotent)."""
        if self._stop.is_set():
            return
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self._pair_pool.shutdown(wait=True)
        self._load_pool.shutdown(wait=False, cancel_futures=True)
        with contextlib.redirect_stdout(io.StringIO()):
            self.server.stop()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # ----------------------------------------------------------------- registry

    @property
    def shows(self) -> list[str]:
        """Names of the loaded shows, in load order."""
        with self._lock:
            return list(self._shows)

    @property
    def playbacks(self) -> list[_Playback]:
        """The default playback and every browser's own (per-client mode)."""
        with self._lock:
            return [self._main, *self._clients.values()]

    def __getattr__(self, name: str) -> Any:
        # The default playback's state and handles (``_slider``, ``_drones``, ``last_frame``, ...).
        if name.startswith("__") or name in ("_main", "_clients"):
            raise AttributeError(name)
        return getattr(self._main, name)

    @property
    def current(self) -> str | None:
        """Name of the show of the default playback."""
        return self._main.current

    @property
    def source(self) -> Source:
        """``"planned"`` or ``"simulated"`` (the default playback's)."""
        return self._main.source

    @property
    def time_s(self) -> float:
        """Playback time of the default playback, seconds."""
        return self._main.time_s

    @property
    def playing(self) -> bool:
        """Whether any playback is running."""
        return any(pb.playing for pb in self.playbacks)

    @property
    def speed(self) -> float:
        """Playback speed factor of the default playback."""
        return self._main.speed

    def playback_by_token(self, token: str) -> _Playback | None:
        """The browser playback whose page carries ``token`` (see ``_Playback.token``), None if none."""
        with self._lock:
            for pb in self._clients.values():
                if secrets.compare_digest(pb.token, token):
                    return pb
            return None

    def set_report(self, name: str, report: Any) -> None:
        """Attach the check report (``CheckReport.to_json()``) to the loaded show ``name``; its violations are drawn."""
        with self._lock:
            entry = self._shows.get(name)
            if entry is None:
                return
            entry.report = report
            for pb in self.playbacks:
                if pb.current == name:
                    pb.set_report(report)

    def client_playback(self, client_id: int) -> _Playback | None:
        """A browser's own playback (per-client mode), None if it has none."""
        with self._lock:
            return self._clients.get(client_id)

    def set_catalog(self, list_fn: CatalogFn, load_fn: LoadFn) -> None:
        """Let the show selector offer shows that are not loaded yet.

        Args:
            list_fn: returns ``{key: label}`` of the shows that could be loaded.
            load_fn: loads the show ``key`` (it plans and then calls :meth:`load`);
                called from a worker thread when a browser picks that show.
        """
        self._catalog, self._catalog_load = list_fn, load_fn
        self._refresh_show_options()

    def _refresh_show_options(self) -> None:
        with self._lock:
            self._catalog_keys = {}
            if self._catalog is not None:
                try:
                    catalog = dict(self._catalog())
                except Exception:  # a failing catalog must not take the viewer down
                    catalog = {}
                for key, label in catalog.items():
                    if label not in self._shows:
                        self._catalog_keys[label] = key
            for pb in self.playbacks:
                pb._refresh_show_options()

    # ----------------------------------------------------------------- loading

    def load(self, plan: ShowPlan, *, name: str, flight: Any = None, source: Source | None = None,
             report: Any = None, lights: Any = None) -> None:
        """Load (or replace) a show: the default playback shows it (new browsers start on it), and
        so do the browsers showing nothing, an older version of it, or that picked it in the selector.

        Args:
            plan: the show's plan.
            name: registry name shown in the selector (loading the same name replaces it).
            flight: optional simulated flight (``times_s``, ``positions_m`` (T, N, 3), ``colors_rgb``).
            source: ``"planned"`` or ``"simulated"``; default: simulated when a flight is given.
            report: the check report (``CheckReport.to_json()``), if known (else see :meth:`set_report`).
            lights: the show's light effects (``sim.light.LightStack``), played over the colours.
        """
        if flight is not None and np.shape(flight.positions_m)[1] != plan.drone_count:
            raise ValueError("the flight and the plan have different drone counts")
        with self._lock:
            old = self._shows.pop(name, None)
            # A new flight of the same plan keeps the plan's check.
            if report is None and old is not None and old.plan is plan:
                report = old.report
            self._shows[name] = _Entry(name, plan, flight, report, lights)
            while len(self._shows) > MAX_SHOWS:
                del self._shows[next(iter(self._shows))]
            src: Source = source or ("simulated" if flight is not None else "planned")
            self._main._activate(name, src)
            for pb in list(self._clients.values()):
                # Another browser keeps its show: only an empty one, one showing this show (a
                # new version: it keeps its time) or one that asked for it switches.
                if pb.current is None or pb.wanted == name:
                    pb.wanted = None
                    pb._activate(name, src)
                elif pb.current == name:
                    t, playing = pb.time_s, pb.playing
                    pb._activate(name, src if flight is not None or src == "planned" else "planned")
                    pb.seek(t)
                    if playing:
                        pb.play()
            self._refresh_show_options()

    # ----------------------------------------------------------------- transport

    def set_source(self, source: Source) -> None:
        """Switch every playback of the default show between plan and flight, keeping their times."""
        for pb in self.playbacks:
            if pb is self._main or pb.current == self._main.current:
                pb.set_source(source)

    def set_camera(self, mode: str) -> None:
        """Put every playback's camera in ``mode`` (``"free"`` or ``"audience"``)."""
        for pb in self.playbacks:
            pb.set_camera(mode)

    def play(self) -> None:
        """Start every playback (from the start if at the end)."""
        for pb in self.playbacks:
            pb.play()

    def pause(self) -> None:
        """Pause every playback."""
        for pb in self.playbacks:
            pb.pause()

    def toggle_play(self) -> None:
        """Play if paused, pause if playing."""
        if self.playing:
            self.pause()
        else:
            self.play()

    def seek(self, time_s: float) -> None:
        """Jump every playback to ``time_s`` (seconds, clamped); the next tick renders it."""
        for pb in self.playbacks:
            pb.seek(time_s)

    def set_speed(self, speed: float) -> None:
        """Playback speed factor (0.25 to 8) of every playback."""
        for pb in self.playbacks:
            pb.set_speed(speed)

    def render(self, *, frame_dt_s: float | None = None) -> Frame | None:
        """Render every playback at its time; returns the default playback's frame."""
        for pb in self.playbacks[1:]:
            pb.render(frame_dt_s=frame_dt_s)
        return self._main.render(frame_dt_s=frame_dt_s)

    # ----------------------------------------------------------------- busy

    def set_busy(self, message: str | None, fraction: float | None = None) -> None:
        """Show (or with ``message=None`` clear) a progress bar and a notification in every browser.

        Args:
            message: what is being done, for example ``"Planning Demo"``; None when done.
            fraction: progress in [0, 1], or None for an indeterminate (animated) bar.
        """
        with self._lock:
            self._busy = None if message is None else (message, fraction)
            if message is None:
                for pb in self.playbacks:
                    pb._set_gui(pb._progress, "visible", False)
                    pb._set_gui(pb._busy_md, "visible", False)
                for handle in self._notifications.values():
                    if not handle._impl.removed:
                        handle.remove()
                self._notifications.clear()
                return
            value = 100.0 * float(np.clip(fraction, 0.0, 1.0)) if fraction is not None else 100.0
            text = message if fraction is None else f"{message}: {value:.0f} %"
            for pb in self.playbacks:
                pb._set_gui(pb._progress, "value", value)
                pb._set_gui(pb._progress, "animated", fraction is None)
                pb._set_gui(pb._progress, "visible", True)
                pb._set_gui(pb._busy_md, "content", text)
                pb._set_gui(pb._busy_md, "visible", True)
            for client in self.server.get_clients().values():
                self._notify(client, text)

    def _notify(self, client: Any, text: str) -> None:
        handle = self._notifications.get(client.client_id)
        if handle is None or handle._impl.removed:
            self._notifications[client.client_id] = client.add_notification(
                "swarmshow", text, loading=True, with_close_button=False
            )
        else:
            handle.body = text

    def _on_connect(self, client: Any) -> None:
        # viser calls this once the browser has reported its camera (a real browser does at once).
        with self._lock:
            if self.per_client:
                # The browser's own playback starts where the default one is, and plays if it plays.
                pb = _Playback(self, scene=client.scene, gui=client.gui, client=client)
                self._clients[client.client_id] = pb
                # A small window (a phone, the editor's preview pane) starts with the panel minimised.
                with contextlib.suppress(Exception):  # the camera is reported by every browser; be lenient
                    if 0 < int(client.camera.image_width) < COMPACT_WIDTH_PX:
                        client.gui.main_panel.minimize()
                main = self._main
                if main.current is not None:
                    pb._activate(main.current, main.source)
                    pb.seek(main.time_s)
                    pb.set_speed(main.speed)
                    # Started before this page connected (the editor's music lane plays the show as the
                    # preview opens): join it, or the sound runs with a paused picture.
                    if main.playing:
                        pb.play()
            if self._busy is not None:
                self._notify(client, self._busy[0])
        self._refresh_show_options()

    def _on_disconnect(self, client: Any) -> None:
        with self._lock:
            self._notifications.pop(client.client_id, None)
            pb = self._clients.pop(client.client_id, None)
            if pb is not None:
                pb.remove()

    # ----------------------------------------------------------------- thread

    def step(self, wall_dt_s: float) -> Frame | None:
        """Advance every playback by ``wall_dt_s`` seconds of wall time; returns the default one's frame."""
        for pb in self.playbacks[1:]:
            pb.step(wall_dt_s)
        return self._main.step(wall_dt_s)

    @property
    def frames_rendered(self) -> int:
        """Frames rendered by all playbacks."""
        return sum(pb.frames_rendered for pb in self.playbacks)

    def _run(self) -> None:
        period = 1.0 / self.frame_rate_hz
        last = time.perf_counter()
        deadline = last
        while not self._stop.is_set():
            deadline += period
            now = time.perf_counter()
            try:
                self.step(now - last)
            except Exception as exc:  # keep the thread alive; report in the GUI
                for pb in self.playbacks:
                    if not pb.headless:
                        pb._readout.content = f"**Playback error** {exc!r}"
            last = now
            delay = deadline - time.perf_counter()
            if delay < -period:
                # Fell behind (a slow frame): resynchronise instead of bursting.
                deadline = time.perf_counter()
            elif delay > 0:
                self._stop.wait(delay)


__all__ = ["COMPACT_WIDTH_PX", "FRAME_RATE_HZ", "Viewer", "audience_camera"]
