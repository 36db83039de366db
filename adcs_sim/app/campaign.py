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
* ``run_index`` (integers, e.g. ``dynamics.noise.seed``): ``offset`` + the run's index.

A scenario whose controller points a body axis (seed 003: ``sigma``, ``tau`` in its section) adds
the pointing metrics of :func:`adcs_sim.app.analysis.pointing_metrics` (first entry and settling at
1°, 0.1°, 0.01°). ``series_every: k`` keeps each run's error time series (the pointing error for
such a scenario, the eigenaxis error otherwise) every ``k`` control steps, for the figure of all
runs (``adcs-montecarlo`` writes ``series.npz`` and ``figures/error_all_runs``).

``link`` copies the drawn value to other parameters (the controller's inertia model following the
plant's, a torque limit known to both). Run ``i`` draws from its own generator
(``SeedSequence(seed, spawn_key=(i,))``), so its inputs — and, the batch engine being
batch-independent, its results — are the same bit for bit however the campaign is split.

Everything is checked before anything runs: the campaign's own keys, each dispersion (unknown
section or parameter, a parameter the batch engine cannot vary, std < 0, low > high, lengths),
and every run's drawn parameters against the node schemas (a negative inertia drawn names its
run and key). :func:`run_chunk` then simulates a list of runs with the batch engine; a run that
diverges is a failed row with its inputs, and the campaign goes on.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from adcs_core.attitude import EULER_213
from adcs_msgs_py.params import ParameterError, unflatten
from adcs_msgs_py.params_file import load_params_file
from adcs_sim.app.analysis import RunData, attitude_errors_deg, pointing_error_deg, run_metrics
from adcs_sim.app.batch import BatchSimulation
from adcs_sim.app.batch_metrics import batch_metric_columns, metric_columns
from adcs_sim.app.estimation import estimation_metric_names
from adcs_sim.app.registry import NODES
from adcs_sim.app.scenario_files import RunError, config_dirs, resolve_scenario, validate_scenario
from adcs_sim.app.seeding import run_generators

DISTRIBUTIONS = {
    'normal': ({'std'}, {'mean', 'link'}),
    'uniform': (set(), {'low', 'high', 'plus_minus', 'link'}),
    'euler213_uniform': ({'max_deg'}, {'link'}),
    'so3_uniform': (set(), {'link'}),
    'run_index': (set(), {'offset', 'link'}),
}
CAMPAIGN_KEYS = {'scenario', 'runs', 'seed', 'chunk_size', 'tolerance_deg', 'metrics', 'requirements',
                 'dispersions', 'series_every'}


class CampaignError(ValueError):
    """The campaign file is malformed or a run's drawn parameters are impossible."""


def metric_names(tol_deg: float, pointing: bool = False) -> list[str]:
    """Names of the scalar metric columns at settling band ``tol_deg`` (lists are split per axis);
    ``pointing``: with the pointing metrics of a seed 003 scenario."""
    t = np.array([0.0, 1.0])
    dummy = RunData(t=t, q=np.tile([0.0, 0.0, 0.0, 1.0], (2, 1)), w=np.zeros((2, 3)),
                    t_u=t[:1], u=np.zeros((1, 3)), missed_steps=0,
                    pointing=(np.array([1.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])) if pointing else None)
    return list(metric_columns(run_metrics(dummy, tol_deg)))


@dataclass
class Dispersion:
    """How one parameter is drawn (see the module docstring)."""

    section: str
    key: str
    distribution: str
    args: dict[str, Any]
    links: list[tuple[str, str]] = field(default_factory=list)

    @property
    def target(self) -> str:
        return f'{self.section}.{self.key}'

    def draw(self, rng: np.random.Generator, nominal: Any, index: int) -> Any:
        """One value for run ``index``, in the nominal value's form (float, int or list)."""
        raw, values = self.sampler(nominal)
        return values(np.array([raw(rng, index)])).tolist()[0]

    def sampler(self, nominal: Any):
        """``(raw, values)``, the arguments broadcast once (:meth:`Campaign.draws` makes one per
        dispersion): ``raw(rng, index)`` is what run ``index``'s generator draws for this dispersion
        (deviates uniform on [0, 1), standard normals, an SO(3) quaternion, the index), and
        ``values(raws)`` turns the raws of many runs, stacked (runs, ...), into their values at
        once (an array, one row per run; for ``euler213_uniform`` the quaternions of the 2-1-3
        angles, in degrees, by one scipy call, which converts row by row).

        The same numbers as numpy's ``rng.uniform(low, high)`` and ``rng.normal(mean, std)`` run by
        run: numpy draws those as ``low + (high - low) * u`` and ``mean + std * z`` from the same
        deviates (``random_uniform`` / ``random_normal`` of its distributions code, the range
        ``high - low`` computed first), here one multiply and one add over all the runs
        (``tests/test_campaign_draws.py`` compares them with numpy's calls)."""
        kind, a = self.distribution, self.args
        if kind == 'run_index':
            offset = int(a.get('offset', 0))
            return (lambda rng, index: offset + index), np.asarray
        if kind == 'so3_uniform':   # Rotation.random: 4 normals, then from_quat's normalisation
            return (lambda rng, index: rng.normal(size=(4,))), _unit_rows
        if kind == 'euler213_uniform':
            high = np.ascontiguousarray(np.broadcast_to(np.asarray(a['max_deg'], dtype=float), (3,)))
            low = -high
            angles = _uniform(low, high)
            return (lambda rng, index: rng.random(3)), \
                lambda raws: Rotation.from_euler(EULER_213, angles(raws), degrees=True).as_quat()
        base = np.asarray(nominal, dtype=float)
        full = lambda v: np.array(np.broadcast_to(np.asarray(v, dtype=float), base.shape))  # noqa: E731
        shape = base.shape or None
        if kind == 'normal':
            mean, std = full(a.get('mean', base)), full(a['std'])
            return (lambda rng, index: rng.standard_normal(shape)), lambda raws: mean + std * raws
        if 'plus_minus' in a:
            half = full(a['plus_minus'])
            values = _uniform(base - half, base + half)
        else:
            values = _uniform(full(a['low']), full(a['high']))
        return (lambda rng, index: rng.random(shape)), values


def _unit_rows(q: np.ndarray) -> np.ndarray:
    """Each row of ``q`` (runs, 4) divided by its norm as scipy's ``Rotation`` normalises a
    quaternion (``_normalize4``: ``sqrt((x x + y y + z z) + w w)``)."""
    norm = np.sqrt((q[:, 0] * q[:, 0] + q[:, 1] * q[:, 1] + q[:, 2] * q[:, 2]) + q[:, 3] * q[:, 3])
    return q / norm[:, None]


def _uniform(low: np.ndarray, high: np.ndarray):
    """``u -> low + (high - low) u``: numpy's ``Generator.uniform`` of deviates ``u`` (which refuses
    a range that overflows)."""
    span = high - low
    if not np.all(np.isfinite(span)):
        raise OverflowError('Range exceeds valid bounds')
    return lambda raws: low + span * raws


# --- reading a campaign file (Campaign.load) ---------------------------------------------------

def _campaign_section(path: Path) -> dict:
    """The ``campaign:`` mapping of the file at ``path``, its keys checked."""
    try:
        tree = yaml.safe_load(path.read_text(encoding='utf-8'))
    except OSError as exc:
        raise CampaignError(f'cannot read campaign {path}: {exc.strerror}') from None
    except yaml.YAMLError as exc:
        raise CampaignError(f'{path} is not valid YAML: {exc}') from None
    if not isinstance(tree, dict) or set(tree) != {'campaign'} or not isinstance(tree['campaign'], dict):
        raise CampaignError(f'{path}: expected one top-level mapping `campaign:`')
    c = tree['campaign']
    unknown = sorted(set(c) - CAMPAIGN_KEYS)
    if unknown:
        raise CampaignError(f'campaign.{unknown[0]}: unknown key; known: {sorted(CAMPAIGN_KEYS)}')
    if 'scenario' not in c:
        raise CampaignError('campaign.scenario: required (the scenario file to disperse)')
    return c


def _campaign_scenario(c: dict, path: Path) -> tuple[Path, dict, dict]:
    """(scenario path, validated sections, sections as written) of ``campaign.scenario``: relative
    to the campaign file, else a scenario name or path as ``adcs-run`` takes it."""
    scenario = Path(str(c['scenario']))
    candidate = scenario if scenario.is_absolute() else path.parent / scenario
    try:
        scenario_path = candidate.resolve() if candidate.exists() else resolve_scenario(str(scenario))
        defaults = validate_scenario(scenario_path)
        nominal = load_params_file(str(scenario_path))
    except (RunError, ParameterError) as exc:
        raise CampaignError(f'campaign.scenario: {exc}') from None
    return scenario_path, defaults, nominal


def _campaign_numbers(c: dict, runs: int | None) -> tuple[int, int, int, float, int]:
    """(runs, seed, chunk_size, tolerance_deg, series_every), checked (``runs`` overrides the file's)."""
    runs = _integer(c, 'runs', runs)
    if runs < 1:
        raise CampaignError(f'campaign.runs: must be at least 1, got {runs}')
    seed = _integer(c, 'seed', None, default=0)
    if seed < 0:
        raise CampaignError(f'campaign.seed: must be >= 0, got {seed}')
    chunk = _integer(c, 'chunk_size', None, default=100)
    if chunk < 1:
        raise CampaignError(f'campaign.chunk_size: must be at least 1, got {chunk}')
    tol = c.get('tolerance_deg', 0.5)
    if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not 0 < tol < 180:
        raise CampaignError(f'campaign.tolerance_deg: must be a number in (0, 180), got {tol!r}')
    series_every = _integer(c, 'series_every', None, default=0)
    if series_every < 0:
        raise CampaignError(f'campaign.series_every: must be >= 0 (0: no series), got {series_every}')
    return runs, seed, chunk, float(tol), series_every


def _campaign_metrics(c: dict, known: list[str]) -> list[str]:
    """``campaign.metrics`` (default: every known metric), each name expanded to its columns."""
    metrics = c.get('metrics') or known
    if not isinstance(metrics, list):
        raise CampaignError('campaign.metrics: must be a list of metric names')
    expanded = []
    for m in metrics:
        cols = [k for k in known if k == m or k.startswith(f'{m}[')]
        if not cols:
            raise CampaignError(f'campaign.metrics: unknown metric {m!r}; known: {known}')
        expanded += cols
    return list(dict.fromkeys(expanded))


def _campaign_requirements(c: dict, known: list[str]) -> dict[str, dict[str, float]]:
    """``campaign.requirements``: ``{metric: {min: x} and/or {max: x}}``, checked."""
    requirements = c.get('requirements') or {}
    for m, bound in requirements.items():
        if m not in known:
            raise CampaignError(f'campaign.requirements.{m}: unknown metric; known: {known}')
        if not isinstance(bound, dict) or not bound or set(bound) - {'min', 'max'} or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in bound.values()):
            raise CampaignError(f'campaign.requirements.{m}: expected {{min: x}} and/or {{max: x}}')
    return {m: {k: float(v) for k, v in b.items()} for m, b in requirements.items()}


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
    checked: bool = False   # every run's draw validated (check_runs): run_chunk need not repeat it
    # check_runs' draws of every run, with what they were drawn from (seed, dispersions): draws()
    # takes a chunk's rows from them instead of seeding each run's generator again
    _drawn: tuple | None = field(default=None, repr=False, compare=False)

    @classmethod
    def load(cls, path, runs: int | None = None) -> 'Campaign':
        """Read and check a campaign file (``runs`` overrides its run count). Raises CampaignError."""
        path = _resolve_campaign(Path(path))
        c = _campaign_section(path)
        scenario_path, defaults, nominal = _campaign_scenario(c, path)
        runs, seed, chunk, tol, series_every = _campaign_numbers(c, runs)
        known = metric_names(tol, pointing=_points_an_axis(defaults)) + _estimation_columns(defaults)
        metrics = _campaign_metrics(c, known)
        requirements = _campaign_requirements(c, known)
        campaign = cls(path=path.resolve(), scenario_path=scenario_path, nominal=nominal,
                       defaults=defaults, runs=runs,
                       seed=seed, chunk_size=chunk, tol_deg=tol, metrics=metrics,
                       requirements=requirements, dispersions=[], series_every=series_every)
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
            raise CampaignError(f'{where}: unknown parameter {key!r} of node {section!r}; '
                                f'known: {sorted(schema.by_name)}')
        if not param.batch:
            raise CampaignError(f'{where}: {section}.{key} cannot differ between runs of the batch '
                                'engine (dispersible: '
                                f'{sorted(p.name for p in schema.params if p.batch)})')
        return section, key, param

    def _dispersion(self, target: str, spec: Any) -> Dispersion:
        where = f'campaign.dispersions.{target}'
        section, key, param = self._target(where, target)
        if not isinstance(spec, dict) or 'distribution' not in spec:
            raise CampaignError(f'{where}: expected a mapping with `distribution:` '
                                f'(one of {sorted(DISTRIBUTIONS)})')
        kind = spec['distribution']
        if kind not in DISTRIBUTIONS:
            raise CampaignError(f'{where}.distribution: unknown {kind!r}; known: {sorted(DISTRIBUTIONS)}')
        required, optional = DISTRIBUTIONS[kind]
        args = {k: v for k, v in spec.items() if k != 'distribution'}
        extra = sorted(set(args) - required - optional)
        if extra:
            raise CampaignError(f'{where}.{extra[0]}: not a field of {kind} '
                                f'(fields: {sorted(required | optional)})')
        missing = sorted(required - set(args))
        if missing:
            raise CampaignError(f'{where}.{missing[0]}: required by {kind}')
        nominal = self._nominal_value(section, key)
        quaternion = param.kind == 'double_array' and param.length == 4
        if kind in ('euler213_uniform', 'so3_uniform') and not quaternion:
            raise CampaignError(f'{where}: {kind} draws attitudes; {target} is not a quaternion')
        if kind == 'run_index' and param.kind != 'int':
            raise CampaignError(f'{where}: run_index draws integers; {target} is a {param.kind}')
        if kind in ('normal', 'uniform') and param.kind not in ('double', 'double_array'):
            raise CampaignError(f'{where}: {kind} draws real numbers; {target} is a {param.kind}')
        shape = np.shape(nominal)
        for name in ('std', 'mean', 'low', 'high', 'plus_minus', 'max_deg', 'offset'):
            if name not in args:
                continue
            value = _numbers(f'{where}.{name}', args[name], (3,) if name == 'max_deg' else shape,
                             integer=name == 'offset')
            if name in ('std', 'plus_minus', 'max_deg') and np.any(value < 0):
                raise CampaignError(f'{where}.{name}: must be >= 0, got {args[name]!r}')
            args[name] = value
        if kind == 'uniform':
            if 'plus_minus' in args and ({'low', 'high'} & set(args)):
                raise CampaignError(f'{where}: give either low/high or plus_minus, not both')
            if 'plus_minus' not in args:
                if not {'low', 'high'} <= set(args):
                    raise CampaignError(f'{where}: uniform needs low and high (or plus_minus)')
                if np.any(args['low'] > args['high']):
                    raise CampaignError(f'{where}: low must not exceed high '
                                        f'(low {args["low"].tolist()}, high {args["high"].tolist()})')
        links = []
        for link in args.pop('link', []) or []:
            lsection, lkey, _ = self._target(f'{where}.link', link)
            if np.shape(self._nominal_value(lsection, lkey)) != shape:
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
        pending = [s for s in self.nominal if s in stacked and not NODES[s].schema.validate_stacked(
            self.defaults[s], stacked[s], first[s])]
        if pending:
            for i, row in enumerate(zip(*[c.tolist() for c in columns])):
                inputs = dict(zip(targets, row))
                changes = self._changes(inputs)
                for section in pending:
                    self._revalidate(i, inputs, section, changes.get(section, {}))
        self.checked = True

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

    A pure function of its arguments (what a Dask worker executes).
    """
    inputs = campaign.draws(indices)
    result = BatchSimulation(campaign.batch_sections(indices, inputs), len(indices)).run()
    with np.errstate(all='ignore'):  # a diverged run's metrics overflow to inf: that is the result
        metrics = batch_metric_columns(result, campaign.tol_deg)  # metric_columns(result.metrics(j, tol))
    rows = []
    for j, index in enumerate(indices):
        columns = metrics[j]
        status, reason = 'ok', ''
        if result.failure[j]:
            status, reason = 'failed', result.failure[j]
        elif violations := campaign.verdict(columns):
            status, reason = 'violated', '; '.join(violations)
        row = {'run': index, 'status': status, 'reason': reason, 'inputs': inputs[j],
               'metrics': {m: columns[m] for m in campaign.metrics}}
        if campaign.series_every:
            row['series'] = error_series(result, j, campaign.series_every)
        rows.append(row)
    return rows


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
            for name in estimation_metric_names(params['sensors'])]


def _points_an_axis(sections: dict) -> bool:
    """Whether a scenario's controller points a body axis (seed 003: ``sigma`` and ``tau``)."""
    return any('sigma' in params and 'tau' in params for params in sections.values())


def _resolve_campaign(path: Path) -> Path:
    """A campaign path, or a bare file name found in the ``campaigns`` folder of the configs."""
    if path.exists() or path.is_absolute() or len(path.parts) != 1:
        return path
    for d in config_dirs():
        if (d / 'campaigns' / path.name).exists():
            return d / 'campaigns' / path.name
    return path


def _integer(c: dict, key: str, override: int | None, default: int | None = None) -> int:
    value = override if override is not None else c.get(key, default)
    if value is None:
        raise CampaignError(f'campaign.{key}: required')
    if isinstance(value, bool) or not isinstance(value, int):
        raise CampaignError(f'campaign.{key}: expected an integer, got {value!r}')
    return value


def _numbers(where: str, value: Any, shape: tuple, integer: bool = False) -> np.ndarray:
    """A finite number or list broadcastable to ``shape``; CampaignError otherwise."""
    flat = value if isinstance(value, list) else [value]
    if not flat or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in flat):
        raise CampaignError(f'{where}: expected a number or a list of numbers, got {value!r}')
    arr = np.asarray(value, dtype=np.int64 if integer else float)
    if not np.all(np.isfinite(arr)):
        raise CampaignError(f'{where}: must be finite, got {value!r}')
    try:
        np.broadcast_to(arr, shape)
    except ValueError:
        raise CampaignError(f'{where}: {np.size(arr)} values do not fit the parameter '
                            f'({math.prod(shape) or 1} values)') from None
    return arr
