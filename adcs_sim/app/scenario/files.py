"""Scenario files: found by name, read and validated section by section (no ROS).

The one place where the application turns a scenario file into validated sections: the runner,
the batch engine's users and the Monte Carlo campaigns all call :func:`validate_scenario`.
"""
from __future__ import annotations

import sys
from pathlib import Path

from adcs_msgs_py.params import ParameterError
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


def resolve_scenario(name: str | None) -> Path:
    """A scenario path, or a bare file name looked up in the config folders."""
    name = name or DEFAULT_SCENARIO
    path = Path(name)
    if path.exists():
        return path.resolve()
    if not path.is_absolute() and len(path.parts) == 1:
        for d in config_dirs():
            if (d / name).exists():
                return (d / name).resolve()
    raise RunError(f'scenario file {name!r} not found (looked in: {", ".join(map(str, config_dirs()))})')


def validate_scenario(path: Path, duration: float | None = None) -> dict:
    """Validate every section, then that they agree and that the run's needs fit
    (:mod:`adcs_sim.app.scenario.checks`); return {section: validated params}. Raises ParameterError."""
    return validate_sections(load_params_file(str(path)), path, duration)


def validate_sections(sections: dict, path, duration: float | None = None) -> dict:
    """:func:`validate_scenario` of sections already read (``{section: {dotted.key: value}}``, as
    :func:`adcs_msgs_py.params_file.load_params_file` returns them); ``path`` names them in messages."""
    unknown = [s for s in sections if s not in NODES]
    if unknown:
        raise ParameterError(unknown[0], f'unknown node section {unknown[0]!r} in {path}; '
                             f'known nodes: {sorted(NODES)}')
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
