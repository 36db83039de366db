"""A campaign file read and checked against its bounds (no ROS): its keys, its scenario, its counts
(runs, seed, chunk size, settling band, series), its metrics and requirements, and the memory its
runs take on this machine.

What the file may say is documented in :mod:`adcs_sim.app.campaign.plan`; each dispersion is checked by
:mod:`adcs_sim.app.campaign.draws`. Every refusal is a :class:`CampaignError` naming its key.
"""
from __future__ import annotations

import math
from pathlib import Path

from adcs_msgs_py.params import ParameterError
from adcs_msgs_py.params_file import YamlError, load_params_file, load_yaml
from adcs_sim.app.scenario.checks import MEMORY_SHARE, physical_memory_bytes
from adcs_sim.app.scenario.files import RunError, find_shipped, resolve_scenario, validate_scenario
from adcs_sim.app.scenario.seeding import MAX_RUN_INDEX

CAMPAIGN_KEYS = {'scenario', 'runs', 'seed', 'chunk_size', 'tolerance_deg', 'metrics', 'requirements',
                 'dispersions', 'series_every'}

# The counts a campaign may ask for, and why. A run's index is the one 32-bit word of its generator's
# spawn key (adcs_sim.app.scenario.seeding): at most 2^32 runs.
MAX_RUNS = MAX_RUN_INDEX + 1
# SeedSequence mixes a seed into a pool of 128 bits: a larger seed draws nothing more random, and its
# words are mixed in Python at load (a 4000-digit seed takes seconds).
MAX_SEED = 2**128 - 1
# What a campaign holds per run besides its chunk's batch (measured 2026-12-06 on 100 000 runs): ~0.8 kB
# while the draws are checked at load (each run's generator state and raw deviates), then its row until
# the tables are written, ~80 B per metric or input value (Python floats in dicts: 1.2 kB for 17 values),
# and with series_every its error series (a float32 error and a float64 time per sample).
LOAD_BYTES_PER_RUN = 1024
ROW_BYTES_PER_VALUE = 80
SERIES_BYTES_PER_SAMPLE = 12
# A batch's peak memory over its recorded series (batch.run_bytes): the metrics' temporaries (measured
# 1.43 for the PD slew, 1.17 with the MEKF, 600 steps).
BATCH_MEMORY_FACTOR = 2


class CampaignError(ValueError):
    """The campaign file is malformed or a run's drawn parameters are impossible."""


def resolve_campaign(path: Path) -> Path:
    """A campaign path, or the name of a shipped campaign (``pd_slew_30deg.yaml``, ``pd_slew_30deg``
    or ``config/campaigns/pd_slew_30deg.yaml``, from any folder). Raises CampaignError, one line
    with the close matches, when it is neither."""
    try:
        return find_shipped(str(path), 'campaigns', what='campaign')
    except RunError as exc:
        raise CampaignError(str(exc)) from None


def campaign_section(path: Path) -> dict:
    """The ``campaign:`` mapping of the file at ``path``, its keys checked."""
    try:
        tree = load_yaml(path)   # the limits of every YAML reader: size, depth, keys, aliases, UTF-8
    except YamlError as exc:
        raise CampaignError(str(exc)) from None
    if not isinstance(tree, dict) or set(tree) != {'campaign'} or not isinstance(tree['campaign'], dict):
        raise CampaignError(f'{path}: expected one top-level mapping `campaign:`')
    c = tree['campaign']
    unknown = sorted(set(c) - CAMPAIGN_KEYS)
    if unknown:
        raise CampaignError(f'campaign.{unknown[0]}: unknown key; known: {sorted(CAMPAIGN_KEYS)}')
    if 'scenario' not in c:
        raise CampaignError('campaign.scenario: required (the scenario file to disperse)')
    return c


def campaign_scenario(c: dict, path: Path) -> tuple[Path, dict, dict]:
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


def campaign_numbers(c: dict, runs: int | None) -> tuple[int, int, int, float, int]:
    """(runs, seed, chunk_size, tolerance_deg, series_every), checked (``runs`` overrides the file's:
    ``--runs``); the runs' draws fit in memory (what
    :meth:`adcs_sim.app.campaign.plan.Campaign.check_runs` allocates)."""
    key = runs_key(runs)
    runs = _integer(c, 'runs', runs)
    if runs < 1:
        raise CampaignError(f'{key}: must be at least 1, got {runs}')
    if runs > MAX_RUNS:
        raise CampaignError(f'{key}: at most {MAX_RUNS} runs (a run\'s index is the one 32-bit word of its '
                            f'seed\'s spawn key), got {runs}')
    _fits_memory(key, f'{runs} runs', runs * LOAD_BYTES_PER_RUN, 'to draw and check at load, ~1 kB a run')
    seed = _integer(c, 'seed', None, default=0)
    if seed < 0:
        raise CampaignError(f'campaign.seed: must be >= 0, got {seed}')
    if seed > MAX_SEED:
        raise CampaignError(f'campaign.seed: at most 2^128 - 1 (the entropy pool of numpy\'s SeedSequence: '
                            f'a larger seed is no more random), got a {seed.bit_length()}-bit seed')
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


def runs_key(override: int | None) -> str:
    """Where a campaign's run count comes from: the command line's ``--runs``, else the file."""
    return 'campaign.runs' if override is None else '--runs'


def _integer(c: dict, key: str, override: int | None, default: int | None = None) -> int:
    value = override if override is not None else c.get(key, default)
    if value is None:
        raise CampaignError(f'campaign.{key}: required')
    if isinstance(value, bool) or not isinstance(value, int):
        raise CampaignError(f'campaign.{key}: expected an integer, got {value!r}')
    return value


def campaign_metrics(c: dict, known: list[str]) -> list[str]:
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


def campaign_requirements(c: dict, known: list[str]) -> dict[str, dict[str, float]]:
    """``campaign.requirements``: ``{metric: {min: x} and/or {max: x}}``, checked: finite bounds (a
    NaN bound would mark every run violated), ``min <= max``."""
    requirements = c.get('requirements') or {}
    if not isinstance(requirements, dict):
        raise CampaignError('campaign.requirements: must be a mapping <metric>: {min: x, max: y}')
    out = {}
    for m, bound in requirements.items():
        if m not in known:
            raise CampaignError(f'campaign.requirements.{m}: unknown metric; known: {known}')
        if not isinstance(bound, dict) or not bound or set(bound) - {'min', 'max'} or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in bound.values()):
            raise CampaignError(f'campaign.requirements.{m}: expected {{min: x}} and/or {{max: x}}')
        out[m] = {}
        for k, v in bound.items():
            try:
                out[m][k] = float(v)
            except OverflowError:
                out[m][k] = math.inf
            if not math.isfinite(out[m][k]):
                raise CampaignError(f'campaign.requirements.{m}.{k}: must be finite, got {v!r}')
        if out[m].get('min', -math.inf) > out[m].get('max', math.inf):
            raise CampaignError(f'campaign.requirements.{m}: min {out[m]["min"]:g} exceeds max {out[m]["max"]:g} '
                                '(every run would violate it)')
    return out


def check_campaign_memory(where_runs: str, runs: int, chunk_size: int, steps: int, run_bytes: int,
                          values: int, series_every: int) -> None:
    """A campaign of ``runs`` runs of ``steps`` control steps (the longest run's) fits this machine's
    memory (CampaignError naming the key otherwise): a chunk's batch, its runs recorded (``run_bytes``
    each: :func:`adcs_sim.app.batch.engine.run_bytes`) and their metrics computed (x
    :data:`BATCH_MEMORY_FACTOR`), and every run's row of ``values`` metrics and inputs (and its error
    series every ``series_every`` steps) until the tables are written. ``where_runs``: where the run
    count comes from (:func:`runs_key`)."""
    chunk = min(chunk_size, runs)
    per_run = BATCH_MEMORY_FACTOR * run_bytes
    _fits_memory('campaign.chunk_size', f'{chunk} runs a batch', chunk * per_run,
                 f'{per_run / 2**10:.3g} kB a run of {steps} steps; at most '
                 f'{max(1, int(MEMORY_SHARE * physical_memory_bytes() // per_run))} runs a chunk')
    series = (steps // series_every + 1) * SERIES_BYTES_PER_SAMPLE if series_every else 0
    row = LOAD_BYTES_PER_RUN + ROW_BYTES_PER_VALUE * values + series
    _fits_memory(where_runs, f'{runs} runs', runs * row,
                 f'{row / 2**10:.3g} kB a run for its draw and its row of {values} values'
                 + (f' and {steps // series_every + 1} series samples' if series else ''))


def _fits_memory(key: str, what: str, need: float, why: str) -> None:
    """CampaignError naming ``key`` if ``need`` bytes exceed the share of this machine's memory a
    campaign may take (:data:`adcs_sim.app.scenario.checks.MEMORY_SHARE`, as a run's dynamics node)."""
    memory = physical_memory_bytes()
    if need > MEMORY_SHARE * memory:
        raise CampaignError(f'{key}: {what} need {need / 2**30:.3g} GiB ({why}), more than '
                            f'{MEMORY_SHARE:.0%} of this machine\'s {memory / 2**30:.3g} GiB')
