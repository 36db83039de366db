"""A campaign's dispersions (no ROS): each one's distribution and arguments checked against the
parameter it draws, and how a run's generator draws its values.

The distributions are documented in :mod:`adcs_sim.app.campaign.plan`, which checks the dispersed
parameter and its links against the scenario (:meth:`adcs_sim.app.campaign.plan.Campaign._target`) and
draws every run (:meth:`adcs_sim.app.campaign.plan.Campaign.draws`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from adcs_core.attitude import EULER_213
from adcs_sim.app.campaign.checks import CampaignError

# distribution: (required fields, optional fields)
DISTRIBUTIONS = {
    'normal': ({'std'}, {'mean', 'link'}),
    'uniform': (set(), {'low', 'high', 'plus_minus', 'link'}),
    'euler213_uniform': ({'max_deg'}, {'link'}),
    'so3_uniform': (set(), {'link'}),
    'run_index': (set(), {'offset', 'link'}),
    'bernoulli': ({'p'}, {'link'}),
}
# Offsets and drawn integers are ROS integer parameters: 64-bit.
INT64_MIN, INT64_MAX = -(2**63), 2**63 - 1


@dataclass
class Dispersion:
    """How one parameter is drawn (see :mod:`adcs_sim.app.campaign.plan`)."""

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
        with np.errstate(over='ignore', invalid='ignore'):   # a draw that overflows: the schema refuses it
            return values(np.array([raw(rng, index)])).tolist()[0]

    def sampler(self, nominal: Any):
        """``(raw, values)``, the arguments broadcast once
        (:meth:`adcs_sim.app.campaign.plan.Campaign.draws` makes one per dispersion): ``raw(rng, index)``
        is what run ``index``'s generator draws for this dispersion (deviates uniform on [0, 1),
        standard normals, an SO(3) quaternion, the index), and ``values(raws)`` turns the raws of
        many runs, stacked (runs, ...), into their values at once (an array, one row per run; for
        ``euler213_uniform`` the quaternions of the 2-1-3 angles, in degrees, by one scipy call,
        which converts row by row).

        The same numbers as numpy's ``rng.uniform(low, high)`` and ``rng.normal(mean, std)`` run by
        run: numpy draws those as ``low + (high - low) * u`` and ``mean + std * z`` from the same
        deviates (``random_uniform`` / ``random_normal`` of its distributions code, the range
        ``high - low`` computed first), here one multiply and one add over all the runs
        (``tests/test_campaign_draws.py`` compares them with numpy's calls)."""
        kind, a = self.distribution, self.args
        if kind == 'run_index':
            offset = int(a.get('offset', 0))
            return (lambda rng, index: offset + index), np.asarray
        if kind == 'bernoulli':
            p = float(a['p'])
            return (lambda rng, index: rng.random()), lambda raws: raws < p
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


# --- checking a dispersion (Campaign.load) -----------------------------------------------------

def dispersion_args(where: str, target: str, spec: Any, param, nominal: Any, runs: int) -> tuple[str, dict]:
    """The distribution of ``spec``, the dispersion of parameter ``target`` (its schema ``param``,
    its scenario value ``nominal``) in a campaign of ``runs`` runs, and its arguments checked
    (numbers as arrays, ``link`` as written); CampaignError naming the key under ``where``."""
    kind, args = _distribution(where, spec)
    quaternion = param.kind == 'double_array' and param.length == 4
    if kind in ('euler213_uniform', 'so3_uniform') and not quaternion:
        raise CampaignError(f'{where}: {kind} draws attitudes; {target} is not a quaternion')
    if kind == 'run_index' and param.kind != 'int':
        raise CampaignError(f'{where}: run_index draws integers; {target} is a {param.kind}')
    if kind in ('normal', 'uniform') and param.kind not in ('double', 'double_array'):
        raise CampaignError(f'{where}: {kind} draws real numbers; {target} is a {param.kind}')
    if kind == 'bernoulli' and param.kind != 'bool':
        raise CampaignError(f'{where}: bernoulli draws booleans; {target} is a {param.kind}')
    if not np.size(nominal):
        raise CampaignError(f'{where}: the scenario sets no value of {target} (an empty list): nothing to '
                            'draw (is its actuator or sensor in this scenario?)')
    _check_numbers(where, kind, args, np.shape(nominal), runs)
    _check_range(where, kind, args, nominal)
    return kind, args


def _distribution(where: str, spec: Any) -> tuple[str, dict]:
    """(distribution, its fields as written) of ``spec``: a known distribution, its fields known and
    the required ones given."""
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
    return kind, args


def _check_numbers(where: str, kind: str, args: dict, shape: tuple, runs: int) -> None:
    """Each numeric field of ``args`` checked (in place: as an array) for a parameter of ``shape``:
    signs, a probability, an offset whose runs' values fit 64-bit integers."""
    for name in ('std', 'mean', 'low', 'high', 'plus_minus', 'max_deg', 'offset', 'p'):
        if name not in args:
            continue
        value = _numbers(f'{where}.{name}', args[name], (3,) if name == 'max_deg' else shape,
                         integer=name == 'offset')
        if name in ('std', 'plus_minus', 'max_deg') and np.any(value < 0):
            raise CampaignError(f'{where}.{name}: must be >= 0, got {args[name]!r}')
        if name == 'p' and not 0 <= value <= 1:
            raise CampaignError(f'{where}.p: a probability, in [0, 1], got {args[name]!r}')
        args[name] = value
    if kind == 'run_index' and int(args.get('offset', 0)) + runs - 1 > INT64_MAX:
        raise CampaignError(f'{where}.offset: offset + run index must fit a 64-bit integer (a ROS '
                            f'integer parameter): at most {INT64_MAX - runs + 1} for {runs} runs')


def _check_range(where: str, kind: str, args: dict, nominal: Any) -> None:
    """A draw around the scenario's value needs a finite one; a uniform range is given once, in order,
    and does not overflow."""
    around_nominal = (kind == 'normal' and 'mean' not in args) or (kind == 'uniform' and 'plus_minus' in args)
    if around_nominal and not np.all(np.isfinite(np.asarray(nominal, dtype=float))):
        raise CampaignError(f'{where}: the scenario\'s value {nominal} is not finite: draw around '
                            f'{"a `mean`" if kind == "normal" else "`low` and `high`"} instead')
    if kind != 'uniform':
        return
    if 'plus_minus' in args and ({'low', 'high'} & set(args)):
        raise CampaignError(f'{where}: give either low/high or plus_minus, not both')
    if 'plus_minus' not in args:
        if not {'low', 'high'} <= set(args):
            raise CampaignError(f'{where}: uniform needs low and high (or plus_minus)')
        if np.any(args['low'] > args['high']):
            raise CampaignError(f'{where}: low must not exceed high '
                                f'(low {args["low"].tolist()}, high {args["high"].tolist()})')
        low, high = args['low'], args['high']
    else:
        low, high = (np.asarray(nominal, dtype=float) + sign * args['plus_minus'] for sign in (-1, 1))
    with np.errstate(over='ignore', invalid='ignore'):
        if not np.all(np.isfinite(np.asarray(high) - low)):
            raise CampaignError(f'{where}: the range overflows (high - low is not a finite number)')


def _numbers(where: str, value: Any, shape: tuple, integer: bool = False) -> np.ndarray:
    """A finite number or list broadcastable to ``shape`` (``integer``: 64-bit integers); CampaignError
    otherwise."""
    flat = value if isinstance(value, list) else [value]
    if not flat or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in flat):
        raise CampaignError(f'{where}: expected a number or a list of numbers, got {value!r}')
    if integer and not all(isinstance(v, int) and INT64_MIN <= v <= INT64_MAX for v in flat):
        raise CampaignError(f'{where}: expected 64-bit integers, got {value!r}')
    if not integer and not all(abs(v) <= 1.7976931348623157e308 for v in flat if isinstance(v, int)):
        raise CampaignError(f'{where}: must be finite, got {value!r}')
    arr = np.asarray(value, dtype=np.int64 if integer else float)
    if not np.all(np.isfinite(arr)):
        raise CampaignError(f'{where}: must be finite, got {value!r}')
    try:
        np.broadcast_to(arr, shape)
    except ValueError:
        raise CampaignError(f'{where}: {np.size(arr)} values do not fit the parameter '
                            f'({math.prod(shape) or 1} values)') from None
    return arr
