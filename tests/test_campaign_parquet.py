"""Campaign results in Parquet (adcs_sim/app/campaign/montecarlo.py: results.parquet beside results.csv).

* the Parquet table is the CSV, row for row and bit for bit (columns, order, values; failed runs
  with their reason and non-finite metrics included);
* column types: run int64, status/reason strings, inputs and metrics float64, integer inputs int64;
* read_results() reads the Parquet file, or the CSV of an output folder that has none.
(Load time of a 100 000-run table: benchmarks/parquet_load.py, not a test: no timing assertions.)
"""
from __future__ import annotations

import csv
import math

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import yaml
from support.scenarios import make_scenario

from adcs_sim.app.api import campaign_results
from adcs_sim.app.campaign.montecarlo import main, read_results, results_table


def _same(csv_text: str, value) -> bool:
    """A CSV cell (repr of a Python value) equals a Parquet value, bit for bit for floats."""
    if isinstance(value, float):
        parsed = float(csv_text)
        return (math.isnan(parsed) and math.isnan(value)) or parsed == value and \
            math.copysign(1.0, parsed) == math.copysign(1.0, value)
    if isinstance(value, int):
        return int(csv_text) == value
    return csv_text == value


@pytest.fixture(scope='module')
def campaign_out(tmp_path_factory):
    """A campaign with diverging runs (torquers without limit, kd drawn up to 6: kd * period > 2
    is unstable) and a requirement that the slower runs miss, so rows are violated and failed."""
    tmp_path = tmp_path_factory.mktemp('parquet')
    scenario = make_scenario(tmp_path, {
        'dynamics': {'duration': 200.0, 'torquers.enabled': True, 'wheels': None},
        'pd_controller': {'actuator': 'torquers', 'wheels': None}})
    campaign = tmp_path / 'campaign.yaml'
    campaign.write_text(yaml.safe_dump({'campaign': {
        'scenario': str(scenario), 'runs': 12, 'seed': 5, 'chunk_size': 5,
        'dispersions': {'pd_controller.kd': {'distribution': 'uniform', 'low': 0.05, 'high': 6.0},
                        'dynamics.inertia': {'distribution': 'normal', 'std': [0.6, 0.7, 0.5]}},
        'requirements': {'settling_euler213_0.5deg_s': {'max': 150.0}}}}))
    out = tmp_path / 'out'
    assert main([str(campaign), '--scheduler', 'none', '--out', str(out), '--quiet', '--no-figures']) == 0
    return out


def test_parquet_table_equals_the_csv_rows(campaign_out):
    with open(campaign_out / 'results.csv', newline='', encoding='utf-8') as f:
        reader = csv.reader(f)
        header = next(reader)
        rows = list(reader)
    table = pq.read_table(campaign_out / 'results.parquet')
    assert table.column_names == header
    assert table.num_rows == len(rows) == 12
    columns = table.to_pydict()
    for i, row in enumerate(rows):
        for name, cell in zip(header, row):
            assert _same(cell, columns[name][i]), (i, name, cell, columns[name][i])
    assert {'failed', 'violated'} <= set(columns['status'])
    failed = [i for i, s in enumerate(columns['status']) if s == 'failed']
    assert all('non-finite' in columns['reason'][i] for i in failed)
    assert any(math.isinf(columns['settling_euler213_0.5deg_s'][i]) for i in failed)


def test_parquet_column_types(campaign_out):
    schema = pq.read_schema(campaign_out / 'results.parquet')
    assert schema.field('run').type == pa.int64()
    assert schema.field('status').type == pa.string() and schema.field('reason').type == pa.string()
    assert schema.field('pd_controller.kd').type == pa.float64()
    assert schema.field('dynamics.inertia[2]').type == pa.float64()
    assert schema.field('integrated_torque_Nms').type == pa.float64()


def test_integer_and_list_inputs():
    rows = [{'run': i, 'status': 'ok', 'reason': '', 'inputs': {'dynamics.noise.seed': 10 + i,
                                                                'dynamics.inertia': [12.0 + i, 14.0, 10.0]},
             'metrics': {'m': 0.1 * i, 'n': math.inf}} for i in range(3)]
    table = results_table(rows)
    assert table.column_names == ['run', 'status', 'reason', 'dynamics.noise.seed', 'dynamics.inertia[0]',
                                  'dynamics.inertia[1]', 'dynamics.inertia[2]', 'm', 'n']
    assert table.schema.field('dynamics.noise.seed').type == pa.int64()
    assert table['dynamics.noise.seed'].to_pylist() == [10, 11, 12]
    assert table['dynamics.inertia[0]'].to_pylist() == [12.0, 13.0, 14.0]
    assert np.all(np.isinf(table['n'].to_numpy()))


def test_read_results_prefers_parquet_and_falls_back_to_csv(campaign_out, tmp_path):
    table = read_results(campaign_out)
    direct = pq.read_table(campaign_out / 'results.parquet')
    assert table.schema == direct.schema
    for name in table.column_names:   # (Table.equals: NaN != NaN, and failed runs have NaN metrics)
        a, b = table[name].to_pylist(), direct[name].to_pylist()
        assert all(_same(repr(x), y) for x, y in zip(a, b)) if table.schema.field(name).type == pa.float64() \
            else a == b, name
    old = tmp_path / 'old'
    old.mkdir()
    (old / 'results.csv').write_bytes((campaign_out / 'results.csv').read_bytes())
    from_csv = read_results(old)
    assert from_csv.column_names == table.column_names
    for name in ('run', 'pd_controller.kd', 'integrated_torque_Nms', 'settling_euler213_0.5deg_s'):
        a, b = np.asarray(from_csv[name].to_pylist(), float), np.asarray(table[name].to_pylist(), float)
        assert np.array_equal(a, b, equal_nan=True), name


def test_the_api_reads_a_campaign(campaign_out):
    table = campaign_results(campaign_out)
    assert table.num_rows == 12 and table.column('run').to_pylist() == list(range(12))
    pytest.importorskip('pandas')
    frame = campaign_results(campaign_out, pandas=True)
    assert list(frame.columns) == table.column_names
    assert np.array_equal(frame['pd_controller.kd'].to_numpy(), table.column('pd_controller.kd').to_numpy())
