"""The show model and formation sources.

The show file format (``swarmshow/1``) and its validation live in ``_show``, its light
effects (``lights``: groups and the effect stack) in ``_effects``, a formation's motion during its
hold (``motion``: keyframed rotate, translate, scale) in ``_motion``;
formation sources (shapes, strokes, text, image, SVG, transforms, spacing
repair) are re-exported from :mod:`formations.sources`.
"""

from __future__ import annotations

from formations._demo import demo_show as demo_show
from formations._demo import load_demo_show as load_demo_show
from formations._effects import DroneGroups as DroneGroups
from formations._effects import LightEffect as LightEffect
from formations._effects import Lights as Lights
from formations._effects import check_group_names as check_group_names
from formations._effects import groups_problem as groups_problem
from formations._effects import lights_problem as lights_problem
from formations._launch import MAX_HOME_CSV_BYTES as MAX_HOME_CSV_BYTES
from formations._launch import HomeCsvError as HomeCsvError
from formations._launch import LaunchBoxes as LaunchBoxes
from formations._launch import home_points_from_csv as home_points_from_csv
from formations._launch import home_points_to_csv as home_points_to_csv
from formations._motion import Motion as Motion
from formations._motion import MotionKey as MotionKey
from formations._naming import source_name as source_name
from formations._show import MAX_DRONES as MAX_DRONES
from formations._show import MAX_ORIGIN_ALT_M as MAX_ORIGIN_ALT_M
from formations._show import MAX_SHOW_FILE_BYTES as MAX_SHOW_FILE_BYTES
from formations._show import MIN_ORIGIN_ALT_M as MIN_ORIGIN_ALT_M
from formations._show import SHOW_FORMAT as SHOW_FORMAT
from formations._show import DronesByCount as DronesByCount
from formations._show import DronesFromGroup as DronesFromGroup
from formations._show import Formation as Formation
from formations._show import Geofence as Geofence
from formations._show import GeoPlacement as GeoPlacement
from formations._show import HomeFromBoxes as HomeFromBoxes
from formations._show import HomeFromGrid as HomeFromGrid
from formations._show import HomeFromPoints as HomeFromPoints
from formations._show import HomeGrid as HomeGrid
from formations._show import Settings as Settings
from formations._show import ShowFile as ShowFile
from formations._show import ShowValidationError as ShowValidationError
from formations._show import dump_show as dump_show
from formations._show import hex_to_rgb as hex_to_rgb
from formations._show import load_show as load_show
from formations._show import parse_show as parse_show
from formations._show import plain_path as plain_path
from formations._show import plain_words as plain_words
from formations._show import rgb_to_hex as rgb_to_hex
from formations._show import show_json_schema as show_json_schema

__all__ = [
    "MAX_HOME_CSV_BYTES",
    "MAX_DRONES",
    "MAX_ORIGIN_ALT_M",
    "MIN_ORIGIN_ALT_M",
    "MAX_SHOW_FILE_BYTES",
    "SHOW_FORMAT",
    "DroneGroups",
    "DronesByCount",
    "DronesFromGroup",
    "Formation",
    "GeoPlacement",
    "Geofence",
    "HomeCsvError",
    "HomeFromBoxes",
    "HomeFromGrid",
    "HomeFromPoints",
    "HomeGrid",
    "LaunchBoxes",
    "LightEffect",
    "Lights",
    "Motion",
    "MotionKey",
    "Settings",
    "ShowFile",
    "ShowValidationError",
    "demo_show",
    "dump_show",
    "hex_to_rgb",
    "home_points_from_csv",
    "home_points_to_csv",
    "load_demo_show",
    "load_show",
    "parse_show",
    "plain_path",
    "plain_words",
    "rgb_to_hex",
    "show_json_schema",
    "lights_problem",
    "groups_problem",
    "check_group_names",
]
