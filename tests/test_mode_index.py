"""The controller status carries each mode's number beside its name (``mode_index``, ``phase_index``).

Status values travel as text (diagnostic_msgs/KeyValue); a viewer plots a value that parses as a
number (PlotJuggler's ROS 2 parser, Lichtblick's Plot panel) and cannot plot a mode's name. Each
shipped controller publishes, after its ``mode`` (and a reconfiguration's ``phase``), the law's
integer code of that name, and the message carries it as a number's text.
"""
from __future__ import annotations

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.serialization import deserialize_message
from support.paths import CONFIG

from adcs_controllers.families import FAMILIES
from adcs_controllers.laws.pd import MODE_PD, PdLaw
from adcs_controllers.laws.reconfiguration import PHASE_CODES, THREE_WHEEL, TWO_WHEEL
from adcs_msgs_py import cdr
from adcs_msgs_py.conversions import status_values
from adcs_sim.app.scenario.files import validate_scenario

SCENARIOS = sorted(p.name for p in CONFIG.glob('*.yaml'))


def _law(name: str):
    sections = validate_scenario(CONFIG / name)
    (node,) = [s for s in sections if s in FAMILIES]
    return FAMILIES[node].build(sections[node])[0]


def _published(law, q=(0.1, -0.2, 0.3, 0.9), w=(0.01, -0.02, 0.005)):
    q = np.asarray(q) / np.linalg.norm(q)
    h = (np.zeros(3),) if getattr(law, 'needs_wheel_momentum', False) else ()   # the pointing laws
    _, status = law.control(0.0, q, np.asarray(w), *h)
    return law.with_mode_index(law.published_status(status))


@pytest.mark.parametrize('name', SCENARIOS)
def test_every_controller_publishes_its_modes_number_beside_the_name(name):
    law = _law(name)
    published = _published(law)
    keys = list(published)
    assert 'mode' in published and isinstance(published['mode'], str)
    assert keys[keys.index('mode') + 1] == 'mode_index'            # right beside the name
    assert law.mode_names[published['mode_index']] == published['mode']
    if 'phase' in published:
        assert keys[keys.index('phase') + 1] == 'phase_index'
        assert PHASE_CODES[published['phase']] == published['phase_index']


def test_the_index_is_a_number_in_the_message_and_the_name_stays():
    law = PdLaw(validate_scenario(CONFIG / 'microsat_pd_slew.yaml')['pd_controller'])
    published = _published(law)
    assert published['mode'] == 'pd' and published['mode_index'] == MODE_PD
    msg = deserialize_message(bytes(cdr.status_bytes(5, 'pd_controller', published)), DiagnosticArray)
    texts = {kv.key: kv.value for kv in msg.status[0].values}
    assert texts['mode'] == 'pd' and float(texts['mode_index']) == MODE_PD
    assert status_values(msg.status[0])['mode_index'] == MODE_PD


def test_a_reconfiguration_numbers_its_phase_by_the_wheels_its_law_uses():
    law = _law('uosat12_gsmn.yaml')
    law.phase = THREE_WHEEL
    three = _published(law)
    law.phase = TWO_WHEEL
    two = _published(law)
    assert (three['phase_index'], two['phase_index']) == (3, 2)
    assert three['mode'] == 'pd' and three['mode_index'] == MODE_PD
    assert two['mode_index'] != MODE_PD   # PD's code is apart from the two-wheel laws'


def test_a_name_the_law_does_not_number_gets_no_index():
    law = PdLaw(validate_scenario(CONFIG / 'microsat_pd_slew.yaml')['pd_controller'])
    assert law.with_mode_index({'mode': 'unknown', 'V': 1.0}) == {'mode': 'unknown', 'V': 1.0}
    assert law.with_mode_index({'mode_x': 'pd'}) == {'mode_x': 'pd'}
