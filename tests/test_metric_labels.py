"""Campaign histograms and the reports name a metric by a readable name and unit taken from its
note (the metric declarations), never by its raw key (``settling_euler213_0.5deg_s``)."""
from __future__ import annotations

from types import SimpleNamespace

import pytest
import yaml
from support.paths import CONFIG

from adcs_sim.app.campaign import montecarlo
from adcs_sim.app.report import figures
from adcs_sim.app.report.markdown import metric_label


def _campaign_metrics() -> list[str]:
    keys = set()
    for path in sorted((CONFIG / 'campaigns').glob('*.yaml')):
        keys.update(yaml.safe_load(path.read_text())['campaign'].get('metrics') or [])
    return sorted(keys)


@pytest.mark.parametrize('key', _campaign_metrics())
def test_every_shipped_campaign_metric_has_a_readable_label(key):
    label = metric_label(key)
    assert label != key and ' ' in label and key not in label, label


@pytest.mark.parametrize('column, expected', [
    ('settling_euler213_0.5deg_s', 'settling time, all three 2-1-3 Euler angles inside the 0.5° band (s)'),
    ('settling_eigenaxis_1deg_s', 'time after which the eigenaxis error stays inside the 1° band (s)'),
    ('integrated_torque_Nms', '∫‖u‖dt of the applied torque (N·m·s)'),
    ('peak_torque_Nm[1]', 'max |u_i| about body axis y (N·m)'),
    ('peak_wheel_speed_rad_s', 'max |Ω| over all wheels (rad/s)'),
    ('nis_star_tracker_inside_95', 'NIS of the star tracker, fraction of steps inside the 95 % χ² bounds'),
    ('not_a_metric', 'not_a_metric'),
])
def test_a_label_is_the_notes_name_and_unit(column, expected):
    assert metric_label(column) == expected


def test_the_histograms_are_labelled_with_the_readable_name(tmp_path, monkeypatch):
    drawn = {}
    monkeypatch.setattr(figures, 'save_figure', lambda fig, out, name: drawn.setdefault(name, fig) and [])
    keys = ['settling_euler213_0.5deg_s', 'peak_torque_Nm[0]']
    campaign = SimpleNamespace(metrics=keys, requirements={})
    rows = [{'status': 'ok', 'metrics': {k: float(i + j) for j, k in enumerate(keys)}} for i in range(20)]
    montecarlo.write_histograms(campaign, rows, tmp_path)
    ax = drawn['hist_settling_euler213_0.5deg_s'].axes[0]
    assert ax.get_xlabel() == metric_label('settling_euler213_0.5deg_s')
    assert drawn['hist_peak_torque_Nm_0'].axes[0].get_xlabel() == 'max |u_i| about body axis x (N·m)'
