"""Metrics against a target nobody flew (issue #31): one reading of a scenario, rcl's, everywhere.

A scenario whose controller section is written twice flies to the target rcl merges in (the first
section's ``target.attitude``: the second only repeats a gain). PyYAML keeps the second section
alone, so an analysis reading the bag's embedded copy with it measured the run against the
identity: ``final_eigenaxis_error_deg`` 180 and no settling for seed 001's half turn. The runner,
the batch engine, the API and the analysis now read it the same way (rcl's parser), and each warns
about the repeated section naming both lines.
"""
from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from support.paths import ROOT

from adcs_msgs_py.params_file import RepeatedKeyWarning, load_params_file
from adcs_sim.app.analysis import analyze
from adcs_sim.app.graph import runner
from adcs_sim.app.analysis.metrics import RunData, run_metrics
from adcs_sim.app.api import Scenario
from adcs_sim.app.batch.engine import BatchSimulation
from adcs_sim.app.analysis.run_data import _scenario, target_attitude
from adcs_sim.app.scenario.files import RunError, validate_scenario
from adcs_sim.bag.reader import mcap_contents, read_metadata
from adcs_sim.bag.storage import mcap_file
from adcs_sim.bag.writer import BagWriter

BAG = ROOT / 'bags' / 'm2r_umax1'             # seed 001, M2R at 1 N m: a half turn about x
FLOWN = [1.0, 0.0, 0.0, 0.0]                  # its m2r_controller target.attitude
REPEAT = 'm2r_controller:\n  ros__parameters:\n    alpha: 0.5\n'   # the same gain again
FIRST_LINE = next(i for i, line in enumerate((BAG / 'scenario.yaml').read_text().splitlines(), 1)
                  if line.startswith('m2r_controller:'))


def _repeated_text() -> str:
    text = (BAG / 'scenario.yaml').read_text()
    return text + REPEAT


def _repeated_scenario(tmp_path):
    path = tmp_path / 'repeated.yaml'
    path.write_text(_repeated_text())
    return path, len(_repeated_text().splitlines()) - 2   # the repeated section's line


def _bag_with_scenario(tmp_path, text: str):
    """The committed bag's messages, its embedded scenario replaced by ``text``."""
    contents = mcap_contents(mcap_file(BAG / 'bag'))
    metadata = {name: values['text'] for name, values in contents.metadata if name != 'rosbag2' and 'text' in values}
    metadata['scenario'] = text
    writer = BagWriter(tmp_path / 'bag', metadata=metadata)
    names = {}
    for cid, (sid, topic, meta) in contents.channels.items():
        schema = contents.schemas[sid]
        writer.add_topic(topic, schema[0], [], (schema[1], schema[2]))
        names[cid] = topic
    for cid, log_time, data in contents.messages:
        writer.write(names[cid], data, log_time_ns=log_time)
    writer.close()
    return tmp_path / 'bag'


class TestMetricsAgainstATargetNobodyFlew:
    def test_runner_batch_api_and_analysis_agree_on_the_merged_target(self, tmp_path):
        path, _ = _repeated_scenario(tmp_path)
        with warnings.catch_warnings():
            warnings.simplefilter('ignore', RepeatedKeyWarning)
            validated = validate_scenario(path, duration=1.0)                            # adcs-run
            batch = BatchSimulation.from_runs([validated]).run().run_data(0)            # batch engine
            api = Scenario.load(path, {'dynamics.duration': 1.0})                       # Python API
            api_batch = api.run_batch()[0].data
            analysed = RunData.from_bag(_bag_with_scenario(tmp_path, _repeated_text()))  # adcs-analyze
        assert validated['m2r_controller']['target.attitude'] == FLOWN
        assert api['m2r_controller.target.attitude'] == FLOWN
        for q_ref in (batch.q_ref, api_batch.q_ref, analysed.q_ref):
            assert np.array_equal(q_ref, FLOWN)

    @pytest.mark.slow
    def test_a_recorded_run_is_measured_against_the_flown_target(self, tmp_path, capsys):
        bag = _bag_with_scenario(tmp_path, _repeated_text())
        with warnings.catch_warnings():
            warnings.simplefilter('ignore', RepeatedKeyWarning)
            metrics = run_metrics(RunData.from_bag(bag))
        flown = run_metrics(RunData.from_bag(BAG / 'bag'))   # the bag as recorded, its scenario written once
        assert json.dumps(metrics, sort_keys=True, default=str) == json.dumps(flown, sort_keys=True, default=str)
        assert metrics['final_eigenaxis_error_deg'] < 0.01 and metrics['settling_eigenaxis_0.5deg_s'] < 60
        assert analyze.main([str(bag), '--no-report', '--json']) == 0   # adcs-analyze streams the bag
        streamed = json.loads(capsys.readouterr().out)[str(bag)]
        assert streamed['final_eigenaxis_error_deg'] == pytest.approx(flown['final_eigenaxis_error_deg'], abs=1e-9)
        for bag in sorted((ROOT / 'bags').glob('*/bag')):   # every committed bag: read as its scenario file
            with warnings.catch_warnings():
                warnings.simplefilter('error', RepeatedKeyWarning)
                scenario = _scenario(read_metadata(bag)['scenario'], bag)
            given = load_params_file(str(bag.parent / 'scenario.yaml'))
            assert scenario is not None and set(scenario) == set(given), bag
            targets = {s: {'ros__parameters': {'target': {'attitude': p['target.attitude']}}}
                       for s, p in given.items() if 'target.attitude' in p}
            assert np.array_equal(target_attitude(scenario), target_attitude(targets)), bag

    def test_the_warning_names_both_lines_at_validation_and_in_the_analysis(self, tmp_path, capsys, monkeypatch):
        path, line = _repeated_scenario(tmp_path)
        expected = f"{line}: section 'm2r_controller' repeats the one at line {FIRST_LINE}"
        with pytest.warns(RepeatedKeyWarning) as caught:
            load_params_file(str(path))
        assert [str(w.message).split(':', 1)[1] for w in caught][0].startswith(expected), [str(w.message) for w in caught]

        assert runner.main([str(path), '--explain']) == 0                    # adcs-run --explain
        err = capsys.readouterr().err
        assert err.count(f'adcs-run: warning: {path}:{expected}') == 1, err    # once, though read twice
        assert f"'m2r_controller.ros__parameters.alpha' repeats line" in err, err   # the parameter too

        def no_graph(*args, **kwargs):
            raise RunError('no graph in this test')
        monkeypatch.setattr(runner, 'lease_domain', no_graph)                # the run: validated, then stopped
        assert runner.main([str(path), '--out', str(tmp_path / 'run'), '--no-progress']) == 1
        err = capsys.readouterr().err
        assert f'adcs-run: warning: {path}:{expected}' in err, err

        bag = _bag_with_scenario(tmp_path, _repeated_text())                 # adcs-analyze
        assert analyze.main([str(bag), '--no-report']) == 0
        captured = capsys.readouterr()
        assert f'adcs-analyze: warning: {bag} (embedded scenario):{expected}' in captured.err, captured.err
        assert 'a regulation run' in captured.out
