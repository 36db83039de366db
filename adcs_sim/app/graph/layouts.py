"""Viewer layouts for a bag: ``adcs-analyze BAG --foxglove-layout OUT.json --plotjuggler-layout OUT.xml``.

One layout per bag, made from what the bag holds (its topics, wheel and thruster names, the
controller's status keys) and its scenario kind (the actuators: wheels, torquers, thrusters and
wheels; pointing): the 3D view (``/tf`` and ``markers``, recorded since the viewer topics,
:mod:`adcs_msgs_py.visual`), attitude error (``error/*``; the quaternion where a bag has no error
topics), body rates, wheel speeds and torques, the applied (and commanded) torque, thruster
on-times and the controller mode (``mode``, ``phase``, ``stage`` of ``controller/status``).
A panel whose topics the bag lacks is left out and named in :attr:`Layout.left_out`.

Each plotted line is a :class:`Series`: topic, message type and the field path in message terms
(``('twist', 'twist', 'angular', 'x')``, ``('velocity', 0)``, a status key); the two writers turn
it into the viewer's own naming:

* **Foxglove / Lichtblick** (JSON, the layout file "Import from file..." reads: ``configById``
  panel configs keyed ``<Type>!<id>``, ``layout`` a binary tree of ``first`` / ``second`` /
  ``direction`` / ``splitPercentage``): message paths ``/topic.field.sub[0]`` for Plot panels, a
  ``{key=="mode"}`` filter for the State Transitions panel. A panel's title is its
  ``foxglovePanelTitle``; each plot's legend sits at its left (``legendDisplay: 'left'``, one row
  of 30 px per series), never over the data, and the plots are laid out in two columns so that
  every row of a legend fits at 1280 x 800. The 3D panel follows the ``inertial`` frame and shows
  the markers; every frame shares one origin (attitude only), so the inertial frame's axes are
  hidden (the grid and the target's axes show it) and the orbit frame's axes and label are drawn
  :data:`ORBIT_AXES_OFFSET` beside the origin (the panel's frame offset), not on the body's.
* **PlotJuggler** (XML ``<root><tabbed_widget>``, tabs of ``DockSplitter`` / ``DockArea`` /
  ``plot`` / ``curve name=...``): the series names of PlotJuggler's ROS 2 parser
  (``plotjuggler_plugins/ParserROS``), which flattens fields with ``/`` (``/error/euler_213/vector/x``,
  an Odometry's rates ``/state/twist/twist/angular/x``), names a JointState's values by joint
  (``/wheels/state/rw_x/velocity``) and a DiagnosticArray's values by status and key
  (``/controller/status/<name>/mode``), a value that parses as a number becoming a numeric series.
  The mode is plotted by its number: ``mode_index`` (and ``phase_index``) beside the name in the
  status (:meth:`adcs_controllers.laws.base.Law.with_mode_index`), or a mode key whose values are
  numbers (``stage``); a bag recorded before the indices gets no mode plot (named in ``left_out``).

A bag that is not a bag of the graph (not a bag, damaged beyond use, no ``state``) is a
:class:`LayoutError` with a one-line message, as is an output that cannot be written. The outputs
are checked before the bag is read (:mod:`adcs_sim.app.outputs`): never the bag or inside it, a
folder, a FIFO, in a read-only folder, nor an existing file that is not a layout this tool wrote
of that kind (recognised from its content: :func:`is_foxglove_layout`, :func:`is_plotjuggler_layout`).
"""
from __future__ import annotations

import json
import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

from adcs_msgs_py import names
from adcs_sim.app.analysis.metrics import ODOMETRY, VECTOR3_STAMPED, pointing_request
from adcs_sim.app.outputs import OutputError, check_file
from adcs_sim.app.report.loading import BagError, load_run
from adcs_sim.bag.batches import ColumnReader
from adcs_sim.bag.tf import TF_TYPE

JOINT_STATE = 'sensor_msgs/msg/JointState'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
MARKER_ARRAY = 'visualization_msgs/msg/MarkerArray'
MODE_KEYS = ('mode', 'phase', 'stage')   # controller status keys that name a law's mode
INDEX_SUFFIX = '_index'   # beside a mode key: its number (adcs_controllers.laws.base.Law.with_mode_index)
ROS_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_/]{0,200}')   # node names (what a controller's status is named)
AXES = ('x', 'y', 'z')
# Foxglove / Lichtblick: the panel title's config key (Lichtblick's util/layout.ts PANEL_TITLE_CONFIG_KEY)
PANEL_TITLE = 'foxglovePanelTitle'
# A left legend's width: its grid gives the label and the (hidden) value column equal shares, beside
# the swatch and the remove button; a label is ~7 px a character
LEGEND_BASE_PX, LEGEND_CHAR_PX, LEGEND_MIN_PX, LEGEND_MAX_PX = 40, 14, 80, 200
ORBIT_AXES_OFFSET = (0.0, 0.0, -2.5)   # m, inertial: where the orbit frame's axes are drawn (module doc)
# The frames' axes: Lichtblick's 0.2 m scaled to 0.4 m, inside the body-axes markers (1 m at the
# default visualization.axis_length) and thin enough not to hide them
AXIS_SCALE = 2.0
COLORS = ('#1f77b4', '#d62728', '#2ca02c', '#ff7f0e', '#9467bd', '#8c564b', '#e377c2', '#17becf')


class LayoutError(Exception):
    """A bag a layout cannot be made for, or an output that cannot be written (one-line message)."""


@dataclass(frozen=True)
class Series:
    """One plotted line: ``topic`` (absolute), its type, the field path in message terms (names,
    list indices, or ``('status', name, key)`` for a DiagnosticArray value) and a label."""

    topic: str
    type_name: str
    path: tuple
    label: str


@dataclass
class Layout:
    """What a bag's layout shows: the 3D view's topics and frames, the plots, the mode panel."""

    title: str
    kind: str
    frames: list[str] = field(default_factory=list)         # child frames of /tf
    scene_topics: list[str] = field(default_factory=list)   # /tf, markers
    plots: list[tuple[str, list[Series]]] = field(default_factory=list)
    modes: list[Series] = field(default_factory=list)          # the mode names (State Transitions)
    mode_numbers: list[Series] = field(default_factory=list)   # the modes as numbers (a plot)
    left_out: list[str] = field(default_factory=list)


# --- what the bag holds -> a Layout ------------------------------------------------------------

def bag_types(path) -> dict[str, str]:
    """Topic -> type of every channel of a bag (a pass that decodes nothing)."""
    reader = ColumnReader(path, lambda topic, type_name: False)
    for _ in reader:
        pass
    return dict(reader.topics)


def _vector(topic: str, type_name: str, prefix: tuple, label: str = '') -> list[Series]:
    """x, y, z of a vector field; labelled by the axis (the panel's title says what), after ``label``
    where a panel shows two vectors."""
    return [Series(topic, type_name, (*prefix, a), f'{label} {a}'.strip()) for a in AXES]


def _joint(topic: str, names_: list[str], field_name: str) -> list[Series]:
    return [Series(topic, JOINT_STATE, (field_name, i, name), name) for i, name in enumerate(names_)]


def _scene(layout: Layout, ns: str, types: dict, counts: dict) -> None:
    tf = ns + names.TF
    if types.get(tf) == TF_TYPE and counts.get(names.TF):
        layout.scene_topics.append(tf)
        layout.frames = ['body'] + (['orbit'] if counts.get(names.FRAMES_ORBIT) else [])
        for rel in (names.MARKERS, names.MARKERS_STATIC):
            if types.get(ns + rel) == MARKER_ARRAY and counts.get(rel):
                layout.scene_topics.append(ns + rel)
    else:
        layout.left_out.append(f'3D view (no {tf} of type {TF_TYPE}: recorded before the viewer topics)')


def _error_plots(layout: Layout, ns: str, types: dict, counts: dict, truth: bool) -> None:
    eig, eul = ns + names.ERROR_EIGENAXIS, ns + names.ERROR_EULER_213
    if types.get(eig) == VECTOR3_STAMPED and counts.get(names.ERROR_EIGENAXIS):
        layout.plots.append(('eigenaxis error (deg)', [Series(eig, VECTOR3_STAMPED, ('vector', 'x'), 'angle')]))
    if types.get(eul) == VECTOR3_STAMPED and counts.get(names.ERROR_EULER_213):
        layout.plots.append(('2-1-3 Euler errors (deg)', _vector(eul, VECTOR3_STAMPED, ('vector',))))
    if not counts.get(names.ERROR_EIGENAXIS) and not counts.get(names.ERROR_EULER_213):
        state = ns + (names.TRUTH_STATE if truth else names.STATE)
        layout.plots.append(('attitude quaternion (body in inertial)',
                             [Series(state, ODOMETRY, ('pose', 'pose', 'orientation', c), c) for c in 'xyzw']))
        layout.left_out.append(f'attitude error (no {eig} / {eul}): the quaternion instead')


def _is_number(text) -> bool:
    try:
        float(text)
    except (TypeError, ValueError):
        return False
    return True


def _modes(layout: Layout, ns: str, records) -> None:
    """The controller's mode keys (:data:`MODE_KEYS`) by name, and by number where the status has one:
    ``<key>_index``, or the key itself when its values are numbers."""
    keys, numbers = {}, {}
    for _, status_name, values in records:
        if not ROS_NAME.fullmatch(status_name):   # a foreign bag's status name goes into a path filter
            continue
        for key in MODE_KEYS:
            if key in values:
                keys.setdefault((status_name, key), None)
                index = key + INDEX_SUFFIX
                number = index if index in values else key if _is_number(values[key]) else None
                if number is not None:
                    numbers.setdefault((status_name, key), number)
    topic = ns + names.CONTROLLER_STATUS
    one = len({status for status, _ in keys}) == 1   # the usual: one controller (then the key names the row)
    label = {(status, key): key if one else f'{status} {key}' for status, key in keys}
    layout.modes = [Series(topic, DIAGNOSTIC_ARRAY, ('status', status, key), label[status, key]) for status, key in keys]
    layout.mode_numbers = [Series(topic, DIAGNOSTIC_ARRAY, ('status', status, numbers[status, key]), label[status, key])
                           for status, key in keys if (status, key) in numbers]
    if not layout.modes:
        layout.left_out.append(f'controller mode (no {"/".join(MODE_KEYS)} on {topic})')
    elif len(layout.mode_numbers) < len(layout.modes):
        layout.left_out.append(f'the mode as a number for PlotJuggler (no mode{INDEX_SUFFIX} on {topic}: '
                               'a recording older than the mode numbers)')


def layout_for(run, types: dict[str, str]) -> Layout:
    """The :class:`Layout` of a loaded run (:func:`adcs_sim.app.report.loading.load_run`) whose bag
    has the channels ``types``."""
    data = run.data
    ns, counts = data.namespace, data.topic_counts
    truth = bool(counts.get(names.TRUTH_STATE))
    kinds = [k for k, topic in (('wheels', names.WHEELS_STATE), ('torquers', names.TORQUE_CMD),
                                ('thrusters', names.THRUSTERS_STATE)) if counts.get(topic)]
    if data.pointing is not None or pointing_request(data.scenario or {}) is not None:
        kinds.append('pointing')
    layout = Layout(title=f'adcs_sim: {run.name}', kind=' + '.join(kinds) or 'free flight')
    _scene(layout, ns, types, counts)
    _error_plots(layout, ns, types, counts, truth)
    state = ns + (names.TRUTH_STATE if truth else names.STATE)
    layout.plots.append(('body rate (rad/s)', _vector(state, ODOMETRY, ('twist', 'twist', 'angular'))))
    if data.wheel_names:
        wheels = ns + names.WHEELS_STATE
        layout.plots.append(('wheel speed (rad/s, relative to the body)',
                             _joint(wheels, data.wheel_names, 'velocity')))
        layout.plots.append(('wheel motor torque (N m)', _joint(wheels, data.wheel_names, 'effort')))
    both = bool(counts.get(names.APPLIED_TORQUE) and counts.get(names.TORQUE_CMD))
    torques = []
    if counts.get(names.APPLIED_TORQUE):
        torques += _vector(ns + names.APPLIED_TORQUE, VECTOR3_STAMPED, ('vector',), 'applied' if both else '')
    if counts.get(names.TORQUE_CMD):
        torques += _vector(ns + names.TORQUE_CMD, VECTOR3_STAMPED, ('vector',), 'cmd')
    if torques:
        layout.plots.append(('body torque (N m)', torques))
    else:
        layout.left_out.append(f'torques (no {ns + names.APPLIED_TORQUE})')
    if data.thruster_names:
        layout.plots.append(('thruster on-time per step (s)',
                             _joint(ns + names.THRUSTERS_STATE, data.thruster_names, 'velocity')))
    _modes(layout, ns, data.controller_status)
    return layout


def load_layout(bag) -> Layout:
    """Read a bag and make its layout; :class:`LayoutError` (one line) when it is no bag of the graph."""
    try:
        run = load_run(bag)
        types = bag_types(bag)
    except BagError as exc:
        raise LayoutError(f'{bag}: {exc}') from None
    except (OSError, ValueError) as exc:
        raise LayoutError(f'{bag}: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}') from None
    return layout_for(run, types)


# --- Foxglove ---------------------------------------------------------------------------------

def foxglove_path(s: Series) -> str:
    """A Foxglove message path: ``/topic.a.b[0]``; a status value by a filter on its key."""
    if s.type_name == DIAGNOSTIC_ARRAY:
        _, status, key = s.path
        return f'{s.topic}.status[:]{{name=="{status}"}}.values[:]{{key=="{key}"}}.value'
    out = s.topic
    for part in s.path[:2] if s.type_name == JOINT_STATE else s.path:
        out += f'[{part}]' if isinstance(part, int) else f'.{part}'
    return out


def _split(ids: list[str], direction: str):
    """A Foxglove layout tree holding ``ids`` in equal parts along ``direction``."""
    if len(ids) == 1:
        return ids[0]
    half = len(ids) // 2
    return {'first': _split(ids[:half], direction), 'second': _split(ids[half:], direction),
            'direction': direction, 'splitPercentage': round(100.0 * half / len(ids), 3)}


def _grid(ids: list[str]):
    """The panels in two columns (the first the longer), each split in equal rows: at 1280 x 800
    a panel of a column of four is about 170 px high, room for a legend of four rows."""
    if len(ids) < 3:
        return _split(ids, 'column')
    half = (len(ids) + 1) // 2
    return {'first': _split(ids[:half], 'column'), 'second': _split(ids[half:], 'column'),
            'direction': 'row', 'splitPercentage': 50}


def _three_d(layout: Layout) -> dict:
    transforms = {'frame:inertial': {'visible': False}, 'frame:body': {'visible': True}}
    if 'orbit' in layout.frames:
        transforms['frame:orbit'] = {'visible': True, 'xyzOffset': list(ORBIT_AXES_OFFSET)}
    return {
        'cameraState': {'distance': 7.0, 'perspective': True, 'phi': 60.0, 'thetaOffset': 45.0,
                        'target': [0, 0, 0], 'targetOffset': [0, 0, 0], 'targetOrientation': [0, 0, 0, 1],
                        'fovy': 45, 'near': 0.01, 'far': 1000},
        'followMode': 'follow-pose', 'followTf': 'inertial',
        # editable: the frames' offsets apply (the orbit frame's axes beside the body's, module doc)
        'scene': {'enableStats': False, 'backgroundColor': '#15181c',
                  'transforms': {'showLabel': True, 'editable': True, 'labelSize': 0.15, 'axisScale': AXIS_SCALE}},
        'transforms': transforms,
        'topics': {t: {'visible': True} for t in layout.scene_topics if not t.endswith('/' + names.TF)},
        'layers': {'grid': {'layerId': 'foxglove.Grid', 'visible': True, 'frameId': 'inertial', 'size': 4,
                            'divisions': 8, 'lineWidth': 1, 'color': '#248eff40', 'position': [0, 0, 0],
                            'rotation': [0, 0, 0], 'order': 1}},
    }


def _legend_width(series: list[Series]) -> int:
    """The left legend's width (px): the longest label, the colour swatch and the value column."""
    return min(LEGEND_MAX_PX, max(LEGEND_MIN_PX, LEGEND_BASE_PX + LEGEND_CHAR_PX * max(len(s.label) for s in series)))


def foxglove_layout(layout: Layout) -> dict:
    """The Foxglove layout (a JSON-able dict) of ``layout``."""
    config, plots = {}, []
    for i, (title, series) in enumerate(layout.plots):
        pid = f'Plot!adcs{i}'
        config[pid] = {PANEL_TITLE: title,
                       'paths': [{'value': foxglove_path(s), 'enabled': True, 'label': s.label,
                                  'timestampMethod': 'receiveTime'} for s in series],
                       'showLegend': True, 'legendDisplay': 'left', 'sidebarDimension': _legend_width(series),
                       'showPlotValuesInLegend': False, 'showXAxisLabels': True,
                       'showYAxisLabels': True, 'isSynced': True, 'xAxisVal': 'timestamp'}
        plots.append(pid)
    if layout.modes:
        config['StateTransitions!adcsmode'] = {
            PANEL_TITLE: 'controller mode', 'isSynced': True,
            'paths': [{'value': foxglove_path(s), 'label': s.label, 'timestampMethod': 'receiveTime'}
                      for s in layout.modes]}
        plots.append('StateTransitions!adcsmode')
    right = _grid(plots)
    if layout.scene_topics:
        config['3D!adcsscene'] = _three_d(layout)
        tree = {'first': '3D!adcsscene', 'second': right, 'direction': 'row', 'splitPercentage': 34}
    else:
        tree = right
    return {'configById': config, 'globalVariables': {}, 'userNodes': {}, 'linkedGlobalVariables': [],
            'playbackConfig': {'speed': 1.0}, 'layout': tree}


# --- PlotJuggler ----------------------------------------------------------------------------------

def plotjuggler_name(s: Series) -> str:
    """The series name PlotJuggler's ROS 2 parser gives the field (module doc)."""
    if s.type_name == JOINT_STATE:
        field_name, _, joint = s.path
        return f'{s.topic}/{joint}/{field_name}'
    if s.type_name == DIAGNOSTIC_ARRAY:
        _, status, key = s.path
        return f'{s.topic}/{status}/{key}'
    return '/'.join((s.topic, *map(str, s.path)))


def _dock(title: str, series: list[Series]) -> ET.Element:
    area = ET.Element('DockArea', name=title)
    plot = ET.SubElement(area, 'plot', style='Lines', mode='TimeSeries', flip_x='false', flip_y='false')
    ET.SubElement(plot, 'limitY')
    for i, s in enumerate(series):
        ET.SubElement(plot, 'curve', name=plotjuggler_name(s), color=COLORS[i % len(COLORS)])
    return area


def _tab(widget: ET.Element, name: str, docks: list[tuple[str, list[Series]]]) -> None:
    tab = ET.SubElement(widget, 'Tab', tab_name=name, containers='1')
    splitter = ET.SubElement(ET.SubElement(tab, 'Container'), 'DockSplitter', orientation='-',
                             count=str(len(docks)), sizes=';'.join([f'{1 / len(docks):.6f}'] * len(docks)))
    for title, series in docks:
        splitter.append(_dock(title, series))


def plotjuggler_layout(layout: Layout) -> ET.ElementTree:
    """The PlotJuggler layout (XML) of ``layout``: a tab of attitude plots, one of actuators."""
    root = ET.Element('root')
    widget = ET.SubElement(root, 'tabbed_widget', name='Main Window', parent='main_window')
    attitude = [p for p in layout.plots if 'torque' not in p[0] and 'wheel' not in p[0] and 'thruster' not in p[0]]
    actuators = [p for p in layout.plots if p not in attitude]
    if layout.mode_numbers:
        actuators.append(('controller mode (number)', layout.mode_numbers))
    for name, docks in (('attitude', attitude), ('actuators', actuators)):
        if docks:
            _tab(widget, name, docks)
    ET.SubElement(widget, 'currentTabIndex', index='0')
    ET.SubElement(root, 'use_relative_time_offset', enabled='1')
    ET.indent(root)
    return ET.ElementTree(root)


# --- writing --------------------------------------------------------------------------------------

FOXGLOVE_KEYS = {'configById', 'globalVariables', 'userNodes', 'linkedGlobalVariables', 'playbackConfig', 'layout'}
FOXGLOVE_PANEL = re.compile(r'(Plot|StateTransitions|3D)!adcs\w*')   # the panel ids foxglove_layout gives
MAX_LAYOUT_BYTES = 1 << 20   # a layout of ours is a few kB: a larger file is not one


def _read_small(path: Path) -> bytes | None:
    with open(path, 'rb') as f:
        data = f.read(MAX_LAYOUT_BYTES + 1)
    return data if len(data) <= MAX_LAYOUT_BYTES else None


def is_foxglove_layout(path: Path) -> bool:
    """A Foxglove layout this tool wrote: the JSON :func:`foxglove_layout` makes (its top-level
    keys exactly, every panel id one of ours: ``Plot!adcs0``, ``3D!adcsscene``...). A layout
    exported from Foxglove, or any other file, is not (never overwritten)."""
    try:
        data = _read_small(path)
        tree = json.loads(data) if data is not None else None
    except (OSError, ValueError, RecursionError):
        return False
    return (isinstance(tree, dict) and set(tree) == FOXGLOVE_KEYS and isinstance(tree['configById'], dict)
            and all(FOXGLOVE_PANEL.fullmatch(k) for k in tree['configById']))


def is_plotjuggler_layout(path: Path) -> bool:
    """A PlotJuggler layout this tool wrote: the XML :func:`plotjuggler_layout` makes (``<root>``
    holding only ``tabbed_widget`` and ``use_relative_time_offset``, tabs named ``attitude`` /
    ``actuators``). One saved by PlotJuggler (plugins, data files...) is not."""
    try:
        data = _read_small(path)
        root = ET.fromstring(data) if data is not None else None
    except (OSError, ET.ParseError, ValueError):
        return False
    if root is None or root.tag != 'root' or {c.tag for c in root} != {'tabbed_widget', 'use_relative_time_offset'}:
        return False
    return all(tab.tag in ('Tab', 'currentTabIndex') and tab.get('tab_name', 'attitude') in ('attitude', 'actuators')
               for widget in root.iter('tabbed_widget') for tab in widget)


def check_outputs(foxglove: Path | None, plotjuggler: Path | None, inputs=()) -> None:
    """Before the bag is read: each output a writable file path, absent or a layout of ours of its
    kind (:func:`adcs_sim.app.outputs.check_file`), not an input (the bag) nor inside one, not both
    the same file. :class:`LayoutError` (one line) otherwise."""
    wanted = [(p, owned) for p, owned in ((foxglove, is_foxglove_layout), (plotjuggler, is_plotjuggler_layout))
              if p is not None]
    try:
        for path, owned in wanted:
            check_file(path, inputs, owned=owned)
    except OutputError as exc:
        raise LayoutError(f'cannot write the layout: {exc}') from None
    if len(wanted) == 2 and os.path.realpath(foxglove) == os.path.realpath(plotjuggler):
        raise LayoutError(f'cannot write the layout: {plotjuggler}: given for both layouts')


def write_layouts(bag, foxglove: Path | None = None, plotjuggler: Path | None = None, inputs=None) -> Layout:
    """Write the layout(s) of ``bag``; :class:`LayoutError` with one line on any failure. The
    outputs are checked before the bag is read (:func:`check_outputs`; ``inputs``: what the tool
    reads, default the bag)."""
    check_outputs(foxglove, plotjuggler, [bag] if inputs is None else inputs)
    layout = load_layout(bag)
    try:
        if foxglove is not None:
            Path(foxglove).write_text(json.dumps(foxglove_layout(layout), indent=2) + '\n')
        if plotjuggler is not None:
            plotjuggler_layout(layout).write(Path(plotjuggler), encoding='UTF-8', xml_declaration=True)
    except OSError as exc:
        raise LayoutError(f'cannot write the layout: {exc.strerror or exc}: {exc.filename or ""}') from None
    return layout
