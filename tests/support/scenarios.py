"""Scenario files and batches for the tests: a config/ scenario with overrides, a campaign file,
a batch of a scenario with per-run overrides, a scenario's batch run computed once per session."""
from __future__ import annotations

import json
from pathlib import Path

import yaml

from support.paths import CONFIG


def _prune_empty(tree: dict) -> None:
    """Drop the mappings left empty by deletions (rcl refuses an empty mapping: ``wheels: {}``)."""
    for key in list(tree):
        if isinstance(tree[key], dict):
            _prune_empty(tree[key])
            if not tree[key]:
                del tree[key]


def make_scenario(tmp_path: Path, overrides: dict | None = None, base: str = 'microsat_pd_slew.yaml',
                  drop: tuple[str, ...] = ()) -> Path:
    """Copy of a config/ scenario with ``overrides`` ({section: {dotted.name: value}}) applied.

    A value of None deletes the parameter; sections named in ``drop`` are removed.
    """
    tree = yaml.safe_load((CONFIG / base).read_text())
    for section in drop:
        tree.pop(section, None)
    for section, params in (overrides or {}).items():
        node = tree.setdefault(section, {'ros__parameters': {}})['ros__parameters']
        for dotted, value in params.items():
            *parents, leaf = dotted.split('.')
            d = node
            for p in parents:
                d = d.setdefault(p, {})
            if value is None:
                d.pop(leaf, None)
            else:
                d[leaf] = value
        _prune_empty(node)
    path = tmp_path / f'scenario_{len(list(tmp_path.glob("scenario_*.yaml")))}.yaml'
    path.write_text(yaml.safe_dump(tree, sort_keys=False))
    return path


BASE_DISPERSIONS = {
    'dynamics.initial.attitude': {'distribution': 'euler213_uniform', 'max_deg': 30},
    'dynamics.inertia': {'distribution': 'normal', 'std': [0.6, 0.7, 0.5]},
    'pd_controller.kd': {'distribution': 'uniform', 'plus_minus': 0.01},
}


def write_campaign(tmp_path: Path, scenario: Path | None = None, **overrides) -> Path:
    """A campaign file: 7 runs (seed 11, one chunk) of a 150 s PD slew with :data:`BASE_DISPERSIONS`;
    ``overrides`` replace keys of the ``campaign`` mapping (None removes one)."""
    if scenario is None:
        scenario = make_scenario(tmp_path, {'dynamics': {'duration': 150.0}})
    body = {'scenario': str(scenario), 'runs': 7, 'seed': 11, 'chunk_size': 7,
            'dispersions': BASE_DISPERSIONS}
    body.update(overrides)
    body = {k: v for k, v in body.items() if v is not None}
    path = tmp_path / f'campaign_{len(list(tmp_path.glob("campaign_*.yaml")))}.yaml'
    path.write_text(yaml.safe_dump({'campaign': body}, sort_keys=False))
    return path


def batch_of(scenario_path, overrides_per_run: list[dict]):
    """A batch (:class:`~adcs_sim.app.batch.engine.BatchSimulation`) of the scenario with
    ``{section: {key: value}}`` overrides per run."""
    from adcs_sim.app.batch.engine import BatchSimulation
    from adcs_sim.app.scenario.registry import NODES
    from adcs_sim.app.scenario.files import validate_scenario
    nominal = validate_scenario(scenario_path)
    runs = []
    for o in overrides_per_run:
        run = {}
        for name, params in nominal.items():
            given = {**params, **o.get(name, {})}
            run[name] = NODES[name].schema.validate(given)
        runs.append(run)
    return BatchSimulation.from_runs(runs)


_BATCH_RUNS: dict = {}


def batch_run_data(validated: dict):
    """The batch engine's run of one validated scenario, as RunData, computed once per test session
    for equal scenarios (several modules check the same long runs: a bag against its batch run,
    a reading study on the same scenario). Callers must not modify what it returns."""
    from adcs_sim.app.batch.engine import BatchSimulation
    key = json.dumps(validated, sort_keys=True, default=repr)
    if key not in _BATCH_RUNS:
        _BATCH_RUNS[key] = BatchSimulation.from_runs([validated]).run().run_data(0)
    return _BATCH_RUNS[key]
