"""Python API for scripts and notebooks: load a scenario, override parameters, run it, analyse it.

The same code as the command-line tools, without them: :class:`Scenario` reads and validates a
scenario file (:mod:`adcs_sim.app.scenario.files`), :meth:`Scenario.run_graph` runs it through the
ROS 2 node graph as ``adcs-run`` does (:func:`adcs_sim.app.graph.runner.run_scenario`: one process per
node, lockstep, recorded to a bag), :meth:`Scenario.run_batch` through the batch engine
(:class:`adcs_sim.app.batch.engine.BatchSimulation`: no ROS, N runs at once). Either gives
:class:`RunResult` objects: the run's time series as numpy arrays (:class:`RunData`, the analysis
library's), as a pandas DataFrame, the metrics
(:func:`adcs_sim.app.analysis.metrics.run_metrics`) and the report's figures
(:data:`adcs_sim.app.report.figures.FIGURES`).

Examples
--------
>>> from adcs_sim.app.api import Scenario
>>> slew = Scenario.load('microsat_pd_slew.yaml').override({'dynamics.duration': 120.0})
>>> batch = slew.run_batch()
>>> batch[0].metrics()['integrated_torque_Nms']  # doctest: +SKIP
>>> graph = slew.run_graph()  # ROS 2 processes, loopback only, into a new runs/ folder  # doctest: +SKIP

See ``docs/examples/pd_slew.py`` for a complete script.
"""
from __future__ import annotations

import copy
import functools
import logging
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from adcs_msgs_py.params import BUILTIN_PARAMETERS, ParameterError, unflatten
from adcs_msgs_py.params_file import dump_params, load_params_file, ros_value_problem
from adcs_sim.app.analysis.metrics import RunData, attitude_errors, run_metrics
from adcs_sim.app.batch.engine import BatchResult, BatchSimulation
from adcs_sim.app.campaign.montecarlo import read_results
from adcs_sim.app.scenario.parameters import explain_sections
from adcs_sim.app.report.loading import Run, run_name
from adcs_sim.app.report.single_run import run_figures, write_report
from adcs_sim.app.graph.domains import MAX_DOMAIN_ID
from adcs_sim.app.graph.runner import run_scenario
from adcs_sim.app.outputs import fresh_folder
from adcs_sim.app.scenario.files import resolve_scenario, validate_sections

__all__ = ['Scenario', 'RunResult', 'BatchRuns', 'RunData', 'ParameterError', 'load_run', 'campaign_results']


def _plain(value: Any) -> Any:
    """numpy scalars and arrays -> Python numbers and lists (what a params file can hold)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _split_overrides(overrides: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """``{'section.dotted.key': value}`` or ``{'section': {'dotted.key': value}}`` -> per section,
    each value one a params file gives a node (:func:`ros_value_problem`): the batch engine and the
    graph (which reads the params file :meth:`Scenario.write` makes) then take the same values."""
    out: dict[str, dict[str, Any]] = {}
    for key, value in overrides.items():
        if isinstance(value, Mapping):
            section, values = str(key), {str(k): v for k, v in value.items()}
        else:
            section, _, name = str(key).partition('.')
            if not name:
                raise ParameterError(str(key), "an override is 'section.key' (e.g. 'dynamics.duration') "
                                     'or {section: {key: value}}')
            values = {name: value}
        out.setdefault(section, {})   # an empty section added is a section (e.g. a fault_injector's defaults)
        for name, v in values.items():
            v = _plain(v)
            problem = ros_value_problem(v)
            if problem:
                raise ParameterError(name, problem, section)
            out[section][name] = v
    return out


@dataclass
class Scenario:
    """A validated scenario: the parameters as given (per section) and as validated.

    Build one with :meth:`load`; :meth:`override` returns a new, validated copy. The scenario is
    never changed in place.

    Attributes
    ----------
    source : pathlib.Path
        The file it was read from (overrides are not written back to it).
    given : dict
        ``{section: {dotted.key: value}}``: what the file (and the overrides) set.
    validated : dict
        ``{section: {dotted.key: value}}``: every parameter of every section, defaults included,
        as the nodes and the batch engine receive them.
    """

    source: Path
    given: dict[str, dict[str, Any]]
    validated: dict[str, dict[str, Any]] = field(repr=False)

    @classmethod
    def load(cls, scenario: str | Path, overrides: Mapping[str, Any] | None = None) -> 'Scenario':
        """Read and validate a scenario file.

        Parameters
        ----------
        scenario : str or pathlib.Path
            A path, or the bare name of a file in ``config/`` (e.g. ``'microsat_pd_slew.yaml'``).
        overrides : mapping, optional
            Parameters to change, as in :meth:`override`.

        Returns
        -------
        Scenario

        Raises
        ------
        adcs_sim.app.scenario.files.RunError
            No such file.
        ParameterError
            A section or key is unknown, a value has the wrong type or is refused by its check
            (the message names the key, as ``adcs-run`` prints it).
        """
        path = resolve_scenario(str(scenario))
        given = load_params_file(str(path))
        loaded = cls(path, given, validate_sections(given, path))
        return loaded.override(overrides) if overrides else loaded

    def override(self, overrides: Mapping[str, Any]) -> 'Scenario':
        """A copy with some parameters changed, validated whole.

        Parameters
        ----------
        overrides : mapping
            Dotted keys prefixed by their section, ``{'dynamics.duration': 60.0, 'pd_controller.kp':
            0.003}``, or nested per section, ``{'dynamics': {'duration': 60.0}}``. A section the
            scenario does not have is added (e.g. a ``fault_injector``).

        Returns
        -------
        Scenario

        Raises
        ------
        ParameterError
            An unknown section or key, or a value its check refuses.
        """
        given = copy.deepcopy(self.given)
        for section, values in _split_overrides(overrides).items():
            given.setdefault(section, {}).update(values)
        return Scenario(self.source, given, validate_sections(given, self.source))

    def __getitem__(self, key: str) -> Any:
        """The validated value of ``'section.dotted.key'`` (e.g. ``scenario['dynamics.duration']``)."""
        section, _, name = key.partition('.')
        return self.validated[section][name]

    def to_yaml(self) -> str:
        """The scenario as a ROS 2 params file.

        Returns
        -------
        str
            YAML, one ``ros__parameters`` section per node: the given parameters, overrides
            included (the defaults are left to the schemas, as in a hand-written file).
        """
        tree = {section: {'ros__parameters': unflatten({k: _plain(v) for k, v in values.items()
                                                        if k not in BUILTIN_PARAMETERS})}
                for section, values in self.given.items()}
        return dump_params(tree)

    def write(self, path: str | Path) -> Path:
        """Write the scenario as a params file that ``adcs-run`` runs.

        Parameters
        ----------
        path : str or pathlib.Path
            The file to write (:meth:`to_yaml`'s text).

        Returns
        -------
        pathlib.Path
        """
        path = Path(path)
        path.write_text(self.to_yaml(), encoding='utf-8')
        return path

    def explain(self) -> str:
        """What ``adcs-run --explain`` prints for this scenario.

        Returns
        -------
        str
            Section by section, every resolved value (defaults included) with its unit and its
            source (``file``: given, overrides included; ``default``: the schema's).
        """
        return explain_sections(self.validated, self.given, f'{self.source} (overrides included)')

    def run_batch(self, variants: Sequence[Mapping[str, Any]] | None = None, progress=None) -> 'BatchRuns':
        """Run the scenario on the batch engine (numpy, no ROS): one run, or one per variant.

        Parameters
        ----------
        variants : sequence of mappings, optional
            One run per entry, each the overrides of :meth:`override` applied to this scenario
            (e.g. ``[{'dynamics.inertia': [12, 14, 10]}, {'dynamics.inertia': [13, 14, 10]}]``).
            Default: one run of the scenario as it is. Only parameters declared batch-dispersible
            (``docs/parameters.md``, column *batch*) may differ between variants.
        progress : callable, optional
            ``progress(steps_done)`` after each control step.

        Returns
        -------
        BatchRuns
            ``batch[i]`` is run ``i`` as a :class:`RunResult`; ``batch.result`` the raw arrays.
        """
        # Each variant's sections are already its own (override validates a copy); the scenario's
        # own are copied before the simulation: nothing is copied after it, where a copy of a
        # large batch could fail for memory and lose the computed runs (issue #31).
        runs = [copy.deepcopy(self.validated)] if not variants else [self.override(v).validated for v in variants]
        result = BatchSimulation.from_runs(runs).run(progress=progress)
        return BatchRuns(result, runs)

    def run_graph(self, out: str | Path | None = None, progress: bool = False, tol_deg: float = 0.5,
                  restarts: int = 0, domain_id: int | None = None, verbose: bool = False,
                  overwrite: bool = False) -> 'RunResult':
        """Run the scenario through the ROS 2 node graph, as ``adcs-run`` does, and read its bag.

        Each node is its own process on a freshly leased ``ROS_DOMAIN_ID`` (or ``domain_id``),
        discovery limited to this machine; the recorder writes ``<out>/bag``. Quiet by default:
        what ``adcs-run`` prints goes to the ``adcs_sim.api`` logger (level INFO).

        Parameters
        ----------
        out : str or pathlib.Path, optional
            Output folder: ``bag/``, ``logs/``, ``metrics.json``, ``scenario.yaml``. It must not
            exist or be empty (or, with ``overwrite``, hold an earlier run's output). Default: a new
            folder ``runs/<scenario>-<date>-<time>`` (numbered if taken), so that running the
            same lines twice gives two runs.
        progress : bool, optional
            Show the progress bar in simulated time (on stderr).
        tol_deg : float, optional
            Settling band of ``metrics.json`` (deg).
        restarts : int, optional
            How many times a controller that dies mid-run is started again.
        domain_id : int, optional
            The ``ROS_DOMAIN_ID`` to run on (0..232), e.g. to watch the run with ``ros2 topic``;
            default: a free one in 1..99.
        verbose : bool, optional
            Print the runner's lines (domain, discovery) on stdout instead of logging them.
        overwrite : bool, optional
            Replace ``out`` if it holds an earlier run's output and nothing else (a folder holding
            anything else is refused, never written over).

        Returns
        -------
        RunResult
            The recorded run (:attr:`RunResult.bag` is the bag folder).

        Raises
        ------
        ValueError
            ``domain_id`` is not an integer in 0..232 (before anything starts).
        adcs_sim.app.scenario.files.RunError
            A node failed, the domain id is held by another run, or the output folder is not empty.
        """
        check_domain_id(domain_id)
        out = fresh_folder(self.source.stem) if out is None else Path(out)
        log = functools.partial(print, flush=True) if verbose else logging.getLogger('adcs_sim.api').info
        with tempfile.TemporaryDirectory(prefix='adcs_api_') as tmp:
            path = self.write(Path(tmp) / self.source.name)
            run_scenario(path, out, progress=progress, tol_deg=tol_deg, restarts=restarts, domain_id=domain_id,
                         log=log, overwrite=overwrite)
        return load_run(out / 'bag')


def check_domain_id(domain_id) -> None:
    """``domain_id`` is None or an integer in 0..232 (a ROS_DOMAIN_ID whose DDS ports are valid),
    else a one-line ValueError naming it."""
    if domain_id is None:
        return
    if isinstance(domain_id, bool) or not isinstance(domain_id, (int, np.integer)) \
            or not 0 <= int(domain_id) <= MAX_DOMAIN_ID:
        raise ValueError(f'domain_id: must be an integer in 0..{MAX_DOMAIN_ID} (a ROS_DOMAIN_ID), '
                         f'got {domain_id!r}')


@dataclass
class RunResult:
    """One run's time series and what can be computed from them.

    Attributes
    ----------
    data : RunData
        The arrays (SI units, seconds): ``t``, ``q`` (N, 4) ``[x, y, z, w]``, ``w`` (N, 3) rad/s,
        ``t_u`` and ``u`` (applied body torque, N m, held from each ``t_u``), ``wheel_names``,
        ``t_wheels``, ``wheel_speed`` (rad/s), ``q_ref`` and the rest of
        :class:`adcs_sim.app.analysis.metrics.RunData`.
    bag : pathlib.Path or None
        The bag it was read from (graph runs), None for a batch run.
    """

    data: RunData
    bag: Path | None = None

    def metrics(self, tol_deg: float = 0.5, eigen_tol_deg: float | None = None) -> dict:
        """The metrics ``adcs-run`` and ``adcs-analyze`` print (:func:`adcs_sim.app.analysis.metrics.run_metrics`).

        Parameters
        ----------
        tol_deg : float, optional
            Settling band of the 2-1-3 Euler errors (deg).
        eigen_tol_deg : float, optional
            Settling band of the eigenaxis error (deg; default ``tol_deg``).

        Returns
        -------
        dict
            ``{metric name: value}``, e.g. ``settling_euler213_0.5deg_s``, ``integrated_torque_Nms``.
        """
        return run_metrics(self.data, tol_deg, eigen_tol_deg)

    def dataframe(self):
        """The time series as one pandas DataFrame indexed by time ``t`` (s).

        Columns: ``q_x q_y q_z q_w`` (true attitude), ``w_x w_y w_z`` (rad/s), ``eigenaxis_error_deg``,
        ``euler213_y_deg euler213_x_deg euler213_z_deg`` (signed 2-1-3 errors, sequence order),
        ``u_x u_y u_z`` (applied torque, N m; NaN at the last state, after the last command) and
        ``wheel_speed.<name>`` (rad/s) per wheel.

        Returns
        -------
        pandas.DataFrame

        """
        # lazy: pandas (a dependency: ppigrf reads the IGRF coefficients with it) costs 0.5-1.3 s to
        # import: only when a DataFrame is asked for
        import pandas as pd
        run = self.data
        _, eigen, euler = attitude_errors(run)
        state = {**{f'q_{a}': run.q[:, i] for i, a in enumerate('xyzw')},
                 **{f'w_{a}': run.w[:, i] for i, a in enumerate('xyz')},
                 'eigenaxis_error_deg': eigen,
                 **{f'euler213_{a}_deg': euler[:, i] for i, a in enumerate('yxz')}}
        frames = [pd.DataFrame(state, index=pd.Index(run.t, name='t'))]
        if run.u.size:
            frames.append(pd.DataFrame({f'u_{a}': run.u[:, i] for i, a in enumerate('xyz')},
                                       index=pd.Index(run.t_u, name='t')))
        if run.wheel_speed.size:
            frames.append(pd.DataFrame({f'wheel_speed.{n}': run.wheel_speed[:, i]
                                        for i, n in enumerate(run.wheel_names)},
                                       index=pd.Index(run.t_wheels, name='t')))
        return pd.concat(frames, axis=1).sort_index()

    def figures(self, tol_deg: float = 0.5, eigen_tol_deg: float | None = None) -> dict[str, Figure]:
        """The report's figures of this run (those it has data for), as matplotlib Figures.

        Parameters
        ----------
        tol_deg, eigen_tol_deg : float, optional
            Settling bands drawn on the figures, as in :meth:`metrics`.

        Returns
        -------
        dict
            ``{name: matplotlib.figure.Figure}`` in the report's order: the figures of the run's kind
            first (:mod:`adcs_sim.app.report.kind_figures`), then the others
            (``attitude_error``, ``euler_213``, ``body_rates``, ``torque``, ``wheels``, ...). Save
            one with ``fig.savefig('x.png')``; in a notebook, display it as the cell's value.
        """
        return run_figures(self.data, run_name(self.bag) if self.bag is not None else '', tol_deg, eigen_tol_deg)

    def write_report(self, out: str | Path, tol_deg: float = 0.5) -> Path:
        """``adcs-analyze``'s report (``report.md`` and figures) of a graph run.

        Parameters
        ----------
        out : str or pathlib.Path
            The folder to write into.
        tol_deg : float, optional
            Settling band of the metrics (deg).

        Returns
        -------
        pathlib.Path
            The ``report.md`` written.

        Raises
        ------
        ValueError
            The run has no bag (a batch run): use :meth:`figures`.
        """
        if self.bag is None:
            raise ValueError('a batch run has no bag to report on; use figures() and metrics()')
        return write_report(Run(self.bag, run_name(self.bag), self.data), out, tol_deg)


@dataclass
class BatchRuns(Sequence):
    """The runs of one batch: ``batch[i]`` is a :class:`RunResult`.

    Attributes
    ----------
    result : adcs_sim.app.batch.engine.BatchResult
        The raw arrays with a leading run axis: ``t`` (K + 1,), ``q`` (N, K + 1, 4), ``w``,
        ``u`` (N, K, 3), ``wheel_speed``, ``n_steps`` and ``failure`` (why a run stopped early).
    sections : list of dict
        The validated sections of each run.
    """

    result: BatchResult
    sections: list

    def __len__(self) -> int:
        return self.result.n_runs

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        if not -len(self) <= i < len(self):
            raise IndexError(f'run {i} of a batch of {len(self)}')
        return RunResult(self.result.run_data(i % len(self)))


def load_run(bag: str | Path) -> RunResult:
    """A recorded run (any bag of the graph) as a :class:`RunResult`.

    Parameters
    ----------
    bag : str or pathlib.Path
        A bag folder (``runs/<run>/bag``, ``bags/<name>/bag``) or an ``.mcap`` file.

    Returns
    -------
    RunResult
    """
    return RunResult(RunData.from_bag(bag), Path(bag))


def campaign_results(folder: str | Path, pandas: bool = False):
    """An ``adcs-montecarlo`` output folder's results table (one row per run).

    Parameters
    ----------
    folder : str or pathlib.Path
        The campaign's output folder (``--out``): ``results.parquet`` is read, or ``results.csv``
        if the folder has none.
    pandas : bool, optional
        Return a pandas DataFrame (needs pandas) instead of a pyarrow Table.

    Returns
    -------
    pyarrow.Table or pandas.DataFrame
        Columns ``run``, ``status``, ``reason``, the dispersed inputs (``dynamics.inertia[0]``, ...)
        and the metrics; ``table.column('integrated_torque_Nms').to_numpy()`` gives one as an array.
    """
    table = read_results(folder)
    return table.to_pandas() if pandas else table
