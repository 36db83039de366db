"""Scenario files: found by name, read and validated section by section (no ROS).

The one place where the application turns a scenario file into validated sections: the runner,
the batch engine's users and the Monte Carlo campaigns all call :func:`validate_scenario`.
"""
from __future__ import annotations

import difflib
import sys
from pathlib import Path

from adcs_msgs_py.params import ParameterError, did_you_mean
from adcs_msgs_py.params_file import load_params_file
from adcs_sim.app.scenario.registry import NODES
from adcs_sim.app.scenario.checks import check_agreement, check_resources, check_whole_run

DEFAULT_SCENARIO = 'uosat12_gsmn.yaml'  # seed 000: a wheel fails, two-wheel GSMN recovers (the showcase)


class RunError(RuntimeError):
    """The run could not be started or did not complete."""


def config_dirs() -> list[Path]:
    """Where scenario files are looked up by bare name: installed share folder, then the source tree."""
    dirs = [Path(sys.prefix) / 'share' / 'adcs_sim' / 'config']
    try:
        # lazy: ament_index_python: only present in a ROS install (optional)
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
        try:
            dirs.insert(0, Path(get_package_share_directory('adcs_sim')) / 'config')
        except (PackageNotFoundError, KeyError, ValueError, OSError):  # OSError: no AMENT_PREFIX_PATH
            pass
    except ImportError:
        pass
    dirs.append(Path(__file__).resolve().parents[3] / 'config')
    return dirs


def shipped_files(sub: str = '') -> dict[str, Path]:
    """``{file name: path}`` of the YAML files shipped in ``config/<sub>`` (the first config folder
    of :func:`config_dirs` holding a name wins)."""
    found: dict[str, Path] = {}
    for d in config_dirs():
        folder = d / sub if sub else d
        if folder.is_dir():
            for path in sorted(folder.glob('*.yaml')):
                found.setdefault(path.name, path)
    return found


def find_shipped(name: str, sub: str = '', what: str = 'scenario') -> Path:
    """A path as given if it exists, else a file shipped in ``config/<sub>`` named as a user of the
    clone would write it: ``uosat12_gsmn.yaml``, ``uosat12_gsmn`` or ``config/uosat12_gsmn.yaml``
    (``config/campaigns/x.yaml`` for a campaign), from any folder, installed or not. Raises
    :class:`RunError`, one line naming the close matches, when it is neither."""
    path = Path(name)
    if path.exists():
        return path.resolve()
    parts = list(path.parts)
    prefix = ['config', *([sub] if sub else [])]
    if not path.is_absolute() and parts[:len(prefix)] == prefix and len(parts) == len(prefix) + 1:
        parts = parts[len(prefix):]   # the clone's relative path, from another folder or after pip install
    shipped = shipped_files(sub)
    if not path.is_absolute() and len(parts) == 1:
        for candidate in (parts[0], f'{parts[0]}.yaml'):
            if candidate in shipped:
                return shipped[candidate].resolve()
    stems = {Path(n).stem: n for n in shipped}
    close = difflib.get_close_matches(Path(parts[-1]).stem, list(stems), n=5, cutoff=0.6)
    hint = f"did you mean {', '.join(repr(stems[c]) for c in close)}?" if close else \
        f'the {len(shipped)} shipped ones are in {next(iter(shipped.values())).parent}' if shipped else \
        f'none is shipped (looked in: {", ".join(str(d / sub) for d in config_dirs())})'
    raise RunError(f'{what} {name!r} not found: no such file, nor a shipped {what} of that name; {hint}')


def resolve_scenario(name: str | None) -> Path:
    """A scenario path, or the name of a shipped one (:func:`find_shipped`); default the showcase."""
    return find_shipped(name or DEFAULT_SCENARIO)


def validate_scenario(path: Path, duration: float | None = None) -> dict:
    """Validate every section, then that they agree and that the run's needs fit
    (:mod:`adcs_sim.app.scenario.checks`); return {section: validated params}. Raises ParameterError."""
    return validate_sections(load_params_file(str(path)), path, duration)


def validate_sections(sections: dict, path, duration: float | None = None) -> dict:
    """:func:`validate_scenario` of sections already read (``{section: {dotted.key: value}}``, as
    :func:`adcs_msgs_py.params_file.load_params_file` returns them); ``path`` names them in messages."""
    unknown = [s for s in sections if s not in NODES]
    if unknown:
        hint = did_you_mean(unknown[0], NODES)
        raise ParameterError(unknown[0], f'unknown node section {unknown[0]!r} in {path}'
                             + (f' ({hint})' if hint else '') + f'; known nodes: {sorted(NODES)}')
    if 'dynamics' not in sections:
        raise ParameterError('dynamics', f'{path} has no dynamics section: nothing would simulate')
    controllers = [s for s in sections if NODES[s].role == 'controller']
    if len(controllers) > 1:
        raise ParameterError(controllers[1], f'more than one controller section ({controllers}): '
                             'the dynamics node would receive competing commands')
    estimators = [s for s in sections if NODES[s].role == 'estimator']
    if len(estimators) > 1:
        raise ParameterError(estimators[1], f'more than one estimator section ({estimators}): both would '
                             'publish estimate/state')
    validated = {}
    for name, given in sections.items():
        if name == 'dynamics' and duration is not None:
            given = {**given, 'duration': float(duration)}
        validated[name] = NODES[name].schema.validate(given)
    for name in controllers:
        if validated[name]['feedback'] == 'estimate' and not estimators:
            raise ParameterError('feedback', "'estimate' needs an estimator section (mekf_estimator, "
                                 f'quest_estimator) in {path}', name)
    check_agreement(validated)
    check_resources(validated['dynamics'])
    check_whole_run(validated)
    return validated
