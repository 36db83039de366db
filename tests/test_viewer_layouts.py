"""What a viewer makes of our layouts and messages, checked against the viewers' own code.

Lichtblick (the open-source Foxglove Studio) reads a panel's title from ``foxglovePanelTitle``
(``util/layout.ts`` ``PANEL_TITLE_CONFIG_KEY``), places a plot's legend by ``legendDisplay``
(``floating`` draws it over the data), and flags a LINE_LIST marker without points as an error
on its topic (``TopicMarkers.ts``). PlotJuggler's ROS 2 parser (``plotjuggler_plugins/ParserROS``)
names an Odometry's fields by their full path (``/state/twist/twist/angular/x``) and turns a
DiagnosticStatus value that parses as a number into a numeric series. The committed recordings
used here: ``eseo_backstepping_slew`` (thrusters, orbit frame), ``m2s_nonprincipal_vagc_0p02``
(torquers, six torque series), ``uosat12_gsmn`` (a mode and a phase).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from support.paths import ROOT

from adcs_sim.app.analysis.metrics import RunData
from adcs_sim.app.graph.layouts import (
    LEGEND_MAX_PX,
    ORBIT_AXES_OFFSET,
    PANEL_TITLE,
    foxglove_layout,
    layout_for,
    load_layout,
    plotjuggler_layout,
)

ROW_PX, TOOLBAR_PX = 30, 30        # Lichtblick: PlotLegendRow ROW_HEIGHT, PANEL_TOOLBAR_MIN_HEIGHT
PANELS_PX = 800 - 44 - 76          # a 1280 x 800 window less the app bar and the playback bar
WORKSPACE_PX = 1280 - 320          # less the app's left sidebar (open by default)
CHAR_PX = 7                        # a legend label's width per character (Inter at 12 px, at most)


def _leaves(node, share=1.0, out=None) -> dict:
    """{panel id: (width share, height share)} of a Foxglove layout tree."""
    out = {} if out is None else out
    if isinstance(node, str):
        out[node] = share if isinstance(share, tuple) else (1.0, 1.0)
        return out
    w, h = share if isinstance(share, tuple) else (1.0, 1.0)
    first = node['splitPercentage'] / 100.0
    for part, frac in ((node['first'], first), (node['second'], 1.0 - first)):
        _leaves(part, (w * frac, h) if node['direction'] == 'row' else (w, h * frac), out)
    return out


@pytest.fixture(scope='module', params=['eseo_backstepping_slew', 'm2s_nonprincipal_vagc_0p02', 'uosat12_gsmn'])
def layout(request):
    return load_layout(ROOT / 'bags' / request.param / 'bag')


@pytest.mark.slow
def test_every_panel_has_its_title_under_lichtblicks_key(layout):
    panels = foxglove_layout(layout)['configById']
    titles = {k: c.get(PANEL_TITLE) for k, c in panels.items() if not k.startswith('3D!')}
    assert PANEL_TITLE == 'foxglovePanelTitle'
    assert sorted(t for k, t in titles.items() if k.startswith('Plot!')) == sorted(t for t, _ in layout.plots)
    assert titles.get('StateTransitions!adcsmode') == 'controller mode'
    assert not any('title' in c for c in panels.values())   # the key Lichtblick ignores


@pytest.mark.slow
def test_legends_sit_beside_the_data_and_every_series_row_fits(layout):
    """No floating legend (it covers the transient); at 1280 x 800 each plot panel is tall enough
    for one legend row per series, and its legend wide enough for the longest label: the legend's
    grid gives the label half of what the swatch and the remove button leave (Lichtblick's
    PlotLegend.tsx), with room left for the plot."""
    fox = foxglove_layout(layout)
    sizes = _leaves(fox['layout'])
    assert sorted(sizes) == sorted(fox['configById'])
    for pid, config in fox['configById'].items():
        if not pid.startswith('Plot!'):
            continue
        assert config['legendDisplay'] == 'left' and config['showLegend'] is True
        rows = len(config['paths'])
        height = sizes[pid][1] * PANELS_PX
        assert height - TOOLBAR_PX >= rows * ROW_PX, (config[PANEL_TITLE], height, rows)
        longest = max(len(p['label']) for p in config['paths'])
        assert config['sidebarDimension'] >= min(LEGEND_MAX_PX, 2 * CHAR_PX * longest + 30)
        assert sizes[pid][0] * WORKSPACE_PX - config['sidebarDimension'] >= 150   # room left for the plot


@pytest.mark.slow
def test_the_3d_view_does_not_pile_the_frame_labels_at_the_origin():
    fox = foxglove_layout(load_layout(ROOT / 'bags' / 'eseo_backstepping_slew' / 'bag'))
    scene = fox['configById']['3D!adcsscene']
    frames = scene['transforms']
    visible = [f for f, s in frames.items() if s.get('visible', True)]
    assert sorted(visible) == ['frame:body', 'frame:orbit'] and frames['frame:inertial'] == {'visible': False}
    # the orbit frame's axes and label drawn away from the body's (offsets apply when editable)
    assert frames['frame:orbit']['xyzOffset'] == list(ORBIT_AXES_OFFSET) and np.linalg.norm(ORBIT_AXES_OFFSET) >= 1.5
    assert scene['scene']['transforms']['editable'] is True and scene['scene']['transforms']['showLabel'] is True
    assert 'frame:body' not in frames or 'xyzOffset' not in frames['frame:body']   # the markers ride on body


@pytest.mark.slow
def test_plotjuggler_names_the_rates_by_the_full_odometry_path(layout):
    curves = [c.get('name') for c in plotjuggler_layout(layout).getroot().iter('curve')]
    rates = [c for c in curves if '/angular/' in c]
    assert rates == [f'/state/twist/twist/angular/{a}' for a in 'xyz']
    assert not any(c.startswith('/state/twist/angular') or c.startswith('/state/pose/orientation') for c in curves)


def _status_layout(records):
    data = RunData(t=np.zeros(1), q=np.array([[0.0, 0.0, 0.0, 1.0]]), w=np.zeros((1, 3)))
    data.topic_counts = {'state': 1, 'controller/status': len(records)}
    data.controller_status = records
    return layout_for(SimpleNamespace(name='x', data=data), {'/state': 'nav_msgs/msg/Odometry'})


def test_the_mode_is_plotted_by_its_number_and_named_in_state_transitions():
    layout = _status_layout([(0.0, 'snlc_gsmn_controller', {'mode': 'pd', 'mode_index': '10', 'phase': 'three_wheel',
                                                            'phase_index': '3', 'V': '0.5'}),
                             (0.1, 'pointing_a_controller', {'mode': 'A1_momentum', 'stage': '1.0'})])
    curves = [(c.get('name')) for c in plotjuggler_layout(layout).getroot().iter('curve')]
    assert curves[-3:] == ['/controller/status/snlc_gsmn_controller/mode_index',
                           '/controller/status/snlc_gsmn_controller/phase_index',
                           '/controller/status/pointing_a_controller/stage']
    states = foxglove_layout(layout)['configById']['StateTransitions!adcsmode']['paths']
    assert [p['value'].rsplit('{key==', 1)[1] for p in states] == ['"mode"}.value', '"phase"}.value',
                                                                   '"mode"}.value', '"stage"}.value']


def test_a_bag_without_mode_numbers_says_why_plotjuggler_has_no_mode_plot():
    layout = _status_layout([(0.0, 'pd_controller', {'mode': 'pd'})])
    assert layout.modes and not layout.mode_numbers
    assert any('mode as a number' in w for w in layout.left_out)
    curves = [c.get('name') for c in plotjuggler_layout(layout).getroot().iter('curve')]
    assert not any('controller/status' in c for c in curves)   # a text series a plot cannot draw
