"""Monte Carlo campaigns: a scenario, its dispersions, and their reproducible draws (no ROS).

A campaign file (YAML) names a scenario file and how to disperse it::

    campaign:
      scenario: ../microsat_pd_slew.yaml   # relative to this file, or a bare name in config/
      runs: 1000
      seed: 20261123
      chunk_size: 100                      # runs per batch / per Dask task
      tolerance_deg: 0.5                   # settling band of the metrics
      metrics: [settling_euler213_0.5deg_s, integrated_torque_Nms]   # default: all
      series_every: 5                      # optional: keep each run's error every 5 control steps
      requirements:                        # optional: runs outside are listed with their inputs
        settling_euler213_0.5deg_s: {max: 400}
      dispersions:                         # <section>.<parameter>: how to draw it, in this order
        dynamics.initial.attitude: {distribution: euler213_uniform, max_deg: 30}
        dynamics.inertia: {distribution: normal, std: [0.5, 0.5, 0.5], link: [pd_controller.inertia]}
        pd_controller.kp: {distribution: uniform, low: 0.0015, high: 0.0025}

Distributions (``shape`` is the nominal value's: a scalar or a list):

* ``normal``: ``mean`` (default: the scenario's value) and ``std`` (>= 0), scalars or per element;
* ``uniform``: ``low`` and ``high`` (``low <= high``), or ``plus_minus`` around the scenario's value;
* ``euler213_uniform`` (quaternions): 2-1-3 Euler angles each uniform in ``[-max_deg, max_deg]``
  (``max_deg``: one value or three in sequence order y, x, z), as seed 004 states its slews;
* ``so3_uniform`` (quaternions): uniformly distributed on SO(3) (:meth:`Rotation.random`);
* ``run_index`` (integers, e.g. ``dynamics.noise.seed``): ``offset`` + the run's index;
* ``bernoulli`` (booleans, e.g. ``m2s_controller.vag``): true with probability ``p``.

A scenario whose controller points a body axis (seed 003: ``sigma``, ``tau`` in its section) adds
the pointing metrics of :func:`adcs_sim.app.analysis.metrics.pointing_metrics` (first entry and settling at
1°, 0.1°, 0.01°). ``series_every: k`` keeps each run's error time series (the pointing error for
such a scenario, the eigenaxis error otherwise) every ``k`` control steps, for the figure of all
runs (``adcs-montecarlo`` writes ``series.npz`` and ``figures/error_all_runs``).

``link`` copies the drawn value to other parameters (the controller's inertia model following the
plant's, a torque limit known to both). Run ``i`` draws from its own generator
(``SeedSequence(seed, spawn_key=(i,))``), so its inputs — and, the batch engine being
batch-independent, its results — are the same bit for bit however the campaign is split.

Everything is checked before anything runs: the campaign's own keys, each dispersion (unknown
section or parameter, a parameter the batch engine cannot vary, std < 0, low > high, lengths, a
range that overflows, an offset past 64-bit integers), the requirements (finite, min <= max), and
every run's drawn parameters against the node schemas (a negative inertia drawn names its run and
key); the counts against what the seeding and this machine can take
(:data:`adcs_sim.app.campaign.checks.MAX_RUNS`, the memory of a chunk's batch and of every run's
row: :meth:`Campaign.check_memory`). :func:`run_chunk` then simulates a list of runs with the batch
engine; a run that diverges, or whose model raises (an SGP4 failure, a law or an estimator that
cannot answer), is a failed row with its inputs and its reason, the other runs of its batch are
unchanged, and the campaign goes on.

The file's keys, counts, metrics, requirements and memory are checked by
:mod:`adcs_sim.app.campaign.checks`; each dispersion's arguments, and how it draws, by
:mod:`adcs_sim.app.campaign.draws`.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from adcs_msgs_py.params import PARAMETER_REFERENCE, ParameterError, did_you_mean, unflatten
from adcs_sim.app.analysis.metrics import RunData, attitude_errors_deg, pointing_error_deg, run_metrics
from adcs_sim.app.batch.engine import BatchSimulation, run_bytes
from adcs_sim.app.analysis.batch_metrics import batch_metric_columns, metric_columns
from adcs_sim.app.campaign.checks import (CampaignError, campaign_metrics, campaign_numbers,
                                          campaign_requirements, campaign_scenario, campaign_section,
                                          check_campaign_memory, resolve_campaign, runs_key)
from adcs_sim.app.campaign.draws import Dispersion, dispersion_args
from adcs_sim.app.analysis.estimation import estimation_metric_names
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.app.scenario.seeding import run_generators
from adcs_sim.truth.schema import step_timing

log = logging.getLogger(__name__)


def metric_names(tol_deg: float, pointing: bool = False, wheels: int = 0) -> list[str]:
    """Names of the scalar metric columns at settling band ``tol_deg`` (lists are split per axis or
    per wheel); ``pointing``: with the pointing metrics of a seed 003 scenario; ``wheels``: the
    truth model's wheel count (the per-wheel metrics of :data:`adcs_sim.app.analysis.metric_defs.DEFINED`)."""
    t = np.array([0.0, 1.0])
    dummy = RunData(t=t, q=np.tile([0.0, 0.0, 0.0, 1.0], (2, 1)), w=np.zeros((2, 3)),
                    t_u=t[:1], u=np.zeros((1, 3)), missed_steps=0,
                    t_wheels=t, wheel_names=[f'w{i}' for i in range(wheels)], wheel_speed=np.zeros((2, wheels)),
                    wheel_max_speed=np.full(wheels, np.inf),
                    pointing=(np.array([1.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])) if pointing else None)
    return list(metric_columns(run_metrics(dummy, tol_deg)))


@dataclass
class Campaign:
    """A loaded, checked campaign: the nominal scenario (flat params per section) and dispersions."""

    path: Path
    scenario_path: Path
    nominal: dict[str, dict[str, Any]]   # section -> {dotted key: value} as written in the scenario
    defaults: dict[str, dict[str, Any]]  # section -> every parameter's validated nominal value
    runs: int
    seed: int
    chunk_size: int
    tol_deg: float
    metrics: list[str]
    requirements: dict[str, dict[str, float]]
    dispersions: list[Dispersion]
    series_every: int = 0   # keep each run's error series every this many steps (0: none)
    runs_key: str = 'campaign.runs'   # where the run count comes from (the file, or --runs)
    checked: bool = False   # every run's draw validated (check_runs): run_chunk need not repeat it
    # check_runs' draws of every run, with what they were drawn from (seed, dispersions): draws()
    # takes a chunk's rows from them instead of seeding each run's generator again
    _drawn: tuple | None = field(default=None, repr=False, compare=False)

    @classmethod
    def load(cls, path, runs: int | None = None) -> 'Campaign':
        """Read and check a campaign file (``runs`` overrides its run count). Raises CampaignError."""
        path = resolve_campaign(Path(path))
        c = campaign_section(path)
        scenario_path, defaults, nominal = campaign_scenario(c, path)
        where_runs = runs_key(runs)
        runs, seed, chunk, tol, series_every = campaign_numbers(c, runs)
        known = (metric_names(tol, pointing=_points_an_axis(defaults), wheels=_wheel_count(defaults))
                 + _estimation_columns(defaults))
        metrics = campaign_metrics(c, known)
        requirements = campaign_requirements(c, known)
        campaign = cls(path=path.resolve(), scenario_path=scenario_path, nominal=nominal,
                       defaults=defaults, runs=runs,
                       seed=seed, chunk_size=chunk, tol_deg=tol, metrics=metrics,
                       requirements=requirements, dispersions=[], series_every=series_every,
                       runs_key=where_runs)
        dispersions = c.get('dispersions') or {}
        if not isinstance(dispersions, dict):
            raise CampaignError('campaign.dispersions: must be a mapping <section>.<parameter>: {...}')
        campaign.dispersions = [campaign._dispersion(t, spec) for t, spec in dispersions.items()]
        campaign.check_runs()
        return campaign

    # --- dispersions ---------------------------------------------------------------------------

    def _target(self, where: str, target: str) -> tuple[str, str, Any]:
        section, _, key = str(target).partition('.')
        if section not in self.nominal or section not in NODES:
            raise CampaignError(f'{where}: no section {section!r} in {self.scenario_path.name} '
                                f'(sections: {sorted(self.nominal)})')
        schema = NODES[section].schema
        param = schema.by_name.get(key)
        if param is None:
            hint = did_you_mean(key, schema.by_name)
            raise CampaignError(f'{where}: unknown parameter {key!r} of node {section!r}'
                                + (f' ({hint})' if hint else '')
                                + f'; every parameter of the node is in {PARAMETER_REFERENCE}')
        if not param.batch:
            raise CampaignError(f'{where}: {section}.{key} cannot differ between runs of the batch '
                                'engine (dispersible: '
                                f'{sorted(p.name for p in schema.params if p.batch)})')
        return section, key, param

    def _dispersion(self, target: str, spec: Any) -> Dispersion:
        where = f'campaign.dispersions.{target}'
        section, key, param = self._target(where, target)
        nominal = self._nominal_value(section, key)
        kind, args = dispersion_args(where, target, spec, param, nominal, self.runs)
        links = []
        link_spec = args.pop('link', None) or []
        if not isinstance(link_spec, list):
            raise CampaignError(f'{where}.link: expected a list of <section>.<parameter>, got {link_spec!r}')
        for link in link_spec:
            lsection, lkey, _ = self._target(f'{where}.link', link)
            if np.shape(self._nominal_value(lsection, lkey)) != np.shape(nominal):
                raise CampaignError(f'{where}.link: {link} does not have the shape of {target}')
            links.append((lsection, lkey))
        return Dispersion(section, key, kind, args, links)

    def _nominal_value(self, section: str, key: str) -> Any:
        """The scenario's value of ``section.key`` (its default when the file does not set it)."""
        return self.defaults[section][key]

    def draw(self, index: int) -> dict[str, Any]:
        """The dispersed inputs of run ``index``: ``{'section.key': value}`` in file order."""
        rng = np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=(index,)))
        return {d.target: d.draw(rng, self._nominal_value(d.section, d.key), index)
                for d in self.dispersions}

    def draws(self, indices: list[int]) -> list[dict[str, Any]]:
        """``[self.draw(i) for i in indices]`` (:meth:`draw_columns`, one row per run; the rows of
        :meth:`check_runs`' draws of every run when they are of this seed and these dispersions)."""
        drawn = self._drawn
        if drawn is not None and drawn[0] == self._draw_key() and all(0 <= i < self.runs for i in indices):
            rows = np.asarray(indices, dtype=np.int64)
            columns = [c[rows].tolist() for c in drawn[1]]
        else:
            columns = [c.tolist() for c in self.draw_columns(indices)]
        if not columns:
            return [{} for _ in indices]
        targets = [d.target for d in self.dispersions]
        return [dict(zip(targets, row)) for row in zip(*columns)]

    def draw_columns(self, indices: list[int]) -> list[np.ndarray]:
        """Each dispersion's values of runs ``indices`` (an array, one row per run): each run's
        generator draws its raw numbers in the same order as :meth:`draw`, then each dispersion
        turns the raws of all the runs into values at once (:meth:`Dispersion.sampler`: the same
        bits as drawing run by run)."""
        samplers = [d.sampler(self._nominal_value(d.section, d.key)) for d in self.dispersions]
        raws: list[list] = [[] for _ in samplers]
        for index, rng in zip(indices, run_generators(self.seed, indices)):   # default_rng(SeedSequence)'s
            for (raw, _), out in zip(samplers, raws):
                out.append(raw(rng, index))
        if not indices:
            return [np.zeros(0) for _ in samplers]
        with np.errstate(over='ignore', invalid='ignore'):   # a draw that overflows: the schema refuses it
            return [values(np.array(r)) for (_, values), r in zip(samplers, raws)]

    def _draw_key(self) -> tuple:
        """What the draws depend on besides the run index (seed, dispersions, run count)."""
        return self.seed, self.runs, repr(self.dispersions)

    def run_given(self, index: int, inputs: dict[str, Any] | None = None) -> dict[str, dict[str, Any]]:
        """The scenario of run ``index`` as written parameters: nominal + draws (+ links).
        ``inputs``: the run's draws if already made (:meth:`draw`)."""
        given = {section: dict(values) for section, values in self.nominal.items()}
        inputs = self.draw(index) if inputs is None else inputs
        for d, value in zip(self.dispersions, inputs.values()):
            given[d.section][d.key] = value
            for section, key in d.links:
                given[section][key] = list(value) if isinstance(value, list) else value
        return given

    def run_sections(self, index: int, inputs: dict[str, Any] | None = None) -> dict[str, dict[str, Any]]:
        """Validated sections of run ``index``; CampaignError naming the run and the key if the
        draw is impossible (e.g. a negative inertia). ``inputs`` as for :meth:`run_given`."""
        inputs = self.draw(index) if inputs is None else inputs
        changes = self._changes(inputs)
        # the nominal sections are validated (defaults): check the changes
        return {section: self._revalidate(index, inputs, section, changes.get(section, {}))
                for section in self.nominal}

    def _revalidate(self, index: int, inputs: dict, section: str, changes: dict) -> dict[str, Any]:
        """Run ``index``'s ``section`` with its ``changes``; CampaignError naming the run and the key."""
        try:
            return NODES[section].schema.revalidate(self.defaults[section], changes)
        except ParameterError as exc:
            raise CampaignError(f'run {index}: drawn {exc} (inputs: {inputs})') from None

    def _changes(self, inputs: dict[str, Any], per_run: bool = False) -> dict[str, dict[str, Any]]:
        """``{section: {key: value}}`` a run's draws (and links) set, in :meth:`run_given`'s order.
        ``per_run``: each input is a list of the runs' values (a link gets its own copy of each)."""
        def own(value):
            return list(value) if isinstance(value, list) else value
        changes: dict[str, dict[str, Any]] = {}
        for d, value in zip(self.dispersions, inputs.values()):
            changes.setdefault(d.section, {})[d.key] = value
            for section, key in d.links:
                changes.setdefault(section, {})[key] = [own(v) for v in value] if per_run else own(value)
        return changes

    def check_runs(self) -> None:
        """Validate every run's drawn parameters (before anything runs); :attr:`checked` then.

        A section whose changed values the schema validates over all the runs at once
        (:meth:`Schema.validate_stacked`: it proves that each run passes) is not validated run by
        run; the others are, run after run, so that an impossible draw raises the same error
        (:meth:`run_sections`': the first bad run, its section and key) either way."""
        columns = self.draw_columns(list(range(self.runs)))
        self._drawn = (self._draw_key(), columns)
        targets = [d.target for d in self.dispersions]
        first = self._changes(dict(zip(targets, [c[0].tolist() for c in columns])))
        stacked = self._changes(dict(zip(targets, columns)))
        duration = np.max(stacked.get('dynamics', {}).get('duration', self.defaults['dynamics']['duration']))
        self.check_memory(int(step_timing({**self.defaults['dynamics'], 'duration': duration})[1]))
        pending = [s for s in self.nominal if s in stacked and not NODES[s].schema.validate_stacked(
            self.defaults[s], stacked[s], first[s])]
        if pending:
            for i, row in enumerate(zip(*[c.tolist() for c in columns])):
                inputs = dict(zip(targets, row))
                changes = self._changes(inputs)
                for section in pending:
                    self._revalidate(i, inputs, section, changes.get(section, {}))
        self.checked = True

    def check_memory(self, steps: int) -> None:
        """The campaign fits this machine's memory (CampaignError naming the key otherwise): a chunk's
        batch, its runs of ``steps`` control steps (the longest run's) recorded and their metrics
        computed, and every run's row (and error series) until the tables are written
        (:func:`adcs_sim.app.campaign.checks.check_campaign_memory`)."""
        values = len(self.metrics) + sum(int(np.size(self._nominal_value(d.section, d.key))) for d in self.dispersions)
        check_campaign_memory(self.runs_key, self.runs, self.chunk_size, steps, run_bytes(self.defaults, steps),
                              values, self.series_every)

    def batch_sections(self, indices: list[int], inputs: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
        """The sections of runs ``indices`` (their draws ``inputs``) stacked for the batch engine:
        ``BatchSimulation.from_runs([run_sections(i) ...])``'s sections (:meth:`Schema.stack`: a value
        equal in every run as it is, else an array over the runs). A :attr:`checked` campaign's draws
        were validated at load (the draws are a pure function of the run index), so the sections
        are assembled from the validated nominal values and the draws without validating each run
        again (a draw is already in its validated form: floats, lists of floats, ints)."""
        if not self.checked:
            runs = [self.run_sections(i, d) for i, d in zip(indices, inputs)]
            return {name: NODES[name].schema.stack([r[name] for r in runs]) for name in runs[0]
                    if NODES[name].role != 'recorder'}
        targets = [d.target for d in self.dispersions]   # _changes of every run, a list over the runs per key
        stacked = self._changes(dict(zip(targets, map(list, zip(*[list(d.values()) for d in inputs])))), per_run=True)
        out = {}
        for section in self.nominal:
            if NODES[section].role == 'recorder':
                continue
            out[section] = values = dict(self.defaults[section])
            for key, column in stacked.get(section, {}).items():
                values[key] = NODES[section].schema.stack_values(key, column)
        return out

    def scenario_text(self, index: int) -> str:
        """A complete scenario file for run ``index`` alone: replay it with ``adcs-run``."""
        tree = {section: {'ros__parameters': unflatten(given)}
                for section, given in self.run_given(index).items()}
        header = (f'# Run {index} of campaign {self.path.name} (seed {self.seed}), scenario '
                  f'{self.scenario_path.name} with its drawn inputs:\n')
        header += ''.join(f'#   {k} = {v}\n' for k, v in self.draw(index).items())
        return header + yaml.safe_dump(tree, sort_keys=False, default_flow_style=None)

    def chunks(self) -> list[list[int]]:
        return [list(range(i, min(i + self.chunk_size, self.runs))) for i in range(0, self.runs, self.chunk_size)]

    def verdict(self, columns: dict[str, float]) -> list[str]:
        """Requirements a run's metric columns violate (NaN violates)."""
        out = []
        for m, bound in self.requirements.items():
            v = columns.get(m, math.nan)
            if 'max' in bound and not v <= bound['max']:
                out.append(f'{m} = {v:g} > {bound["max"]:g}')
            if 'min' in bound and not v >= bound['min']:
                out.append(f'{m} = {v:g} < {bound["min"]:g}')
        return out


def run_chunk(campaign: Campaign, indices: list[int]) -> list[dict]:
    """Simulate runs ``indices`` as one batch; one row per run: ``run``, ``status`` (``ok``,
    ``failed`` or ``violated``), ``reason``, the dispersed inputs and the metric columns.

    A pure function of its arguments (what a Dask worker executes). A run whose model raises (its
    SGP4 fails, a law or an estimator cannot answer: :class:`adcs_controllers.laws.failure.FlightSoftwareError`,
    or any other error of its simulation) is a ``failed`` row with the error as its reason and NaN
    metrics; the batch is split in halves until that run is alone, so the others' rows are those
    they get without it (a run's numbers do not depend on the runs sharing its batch).
    """
    return _rows(campaign, indices, campaign.draws(indices))[0]


def _rows(campaign: Campaign, indices: list[int], inputs: list[dict]) -> tuple[list[dict], int]:
    """:func:`run_chunk`'s rows of runs ``indices`` (their draws ``inputs``): one batch, or its halves
    if it raises; and how many of them raised alone."""
    try:
        result = BatchSimulation(campaign.batch_sections(indices, inputs), len(indices)).run()
        with np.errstate(all='ignore'):  # a diverged run's metrics overflow to inf: that is the result
            metrics = batch_metric_columns(result, campaign.tol_deg)  # metric_columns(result.metrics(j, tol))
    except Exception as exc:  # noqa: BLE001 - any error of a run's model is its failure, in its row
        if len(indices) == 1:
            return [_failed_row(campaign, indices[0], inputs[0], exc)], 1
        half = len(indices) // 2
        (first, a), (second, b) = (_rows(campaign, indices[:half], inputs[:half]),
                                   _rows(campaign, indices[half:], inputs[half:]))
        if not a + b:   # no run fails alone: the batch engine's own fault
            log.warning('runs %d..%d raised %s as one batch but each ran alone: their rows are the runs '
                        "alone's (a batch engine bug)", indices[0], indices[-1], _one_line(exc))
        return first + second, a + b
    rows = []
    for j, index in enumerate(indices):
        columns = metrics[j]
        status, reason = 'ok', ''
        if result.failure[j]:
            status, reason = 'failed', result.failure[j]
        elif violations := campaign.verdict(columns):
            status, reason = 'violated', '; '.join(violations)
        # a metric this run has none of (a sensor it never used, a NEES of other degrees of freedom): NaN
        row = {'run': index, 'status': status, 'reason': reason, 'inputs': inputs[j],
               'metrics': {m: columns.get(m, math.nan) for m in campaign.metrics}}
        if campaign.series_every:
            row['series'] = error_series(result, j, campaign.series_every)
        rows.append(row)
    return rows, 0


def _one_line(exc: BaseException) -> str:
    return f'{type(exc).__name__}: {" ".join(str(exc).split())}'


def _failed_row(campaign: Campaign, index: int, inputs: dict, exc: Exception) -> dict:
    """The row of run ``index`` whose simulation raised ``exc``: failed, the error as its reason, no
    metric (NaN) and no series."""
    row = {'run': index, 'status': 'failed', 'reason': _one_line(exc), 'inputs': inputs,
           'metrics': {m: math.nan for m in campaign.metrics}}
    if campaign.series_every:
        row['series'] = {'t': np.zeros(0), 'error_deg': np.zeros(0, dtype=np.float32), 'kind': 'none'}
    return row


def error_series(result, j: int, every: int) -> dict:
    """Run ``j``'s error every ``every`` samples (deg, float32): the pointing error of a pointing
    run, else the eigenaxis attitude error; with its times (s)."""
    run = result.run_data(j)
    with np.errstate(all='ignore'):
        error = pointing_error_deg(run) if run.pointing is not None else attitude_errors_deg(run)[0]
    return {'t': run.t[::every], 'error_deg': error[::every].astype(np.float32),
            'kind': 'pointing' if run.pointing is not None else 'eigenaxis'}


def _estimation_columns(sections: dict) -> list[str]:
    """The estimation metrics of a scenario with an estimator section (each run's row gets them)."""
    return [name for section, params in sections.items() if section in NODES and NODES[section].role == 'estimator'
            # a filter with bias states models their random walk (gyro.sigma_u): its NEES has 6 dof
            for name in estimation_metric_names(params['sensors'], bias_states='gyro.sigma_u' in params)]


def _wheel_count(sections: dict) -> int:
    """The truth model's wheels (the ``dynamics`` section's ``wheels.names``)."""
    return len(sections.get('dynamics', {}).get('wheels.names') or [])


def _points_an_axis(sections: dict) -> bool:
    """Whether a scenario's controller points a body axis (seed 003: ``sigma`` and ``tau``)."""
    return any('sigma' in params and 'tau' in params for params in sections.values())
