"""Packaging: the package installs the way a ROS workspace and the way pip install it.

* colcon (colcon-core + colcon-ros + colcon-python-setup-py, from the venv) builds a copy of the
  repository in a temporary workspace; the install is checked the way ``ros2 run`` resolves an
  executable (ament index -> package prefix -> ``<prefix>/lib/adcs_sim/<exe>``), and each node
  executable is started with a bad parameter: exit status 2 and a message naming the key prove that
  the installed script imports the installed package and runs its ``main`` (no graph needed).
* ``pip wheel`` builds a wheel of a copy of the repository; its console scripts and data files are
  checked against setup.py and against what colcon installed.

Both builds work on a copy (without .venv, .git, build dirs) so that nothing is written into the
checkout and no stale ``build/lib`` leaks into the result. The editable install of the checkout is
on every venv interpreter's ``sys.path`` (easy-install.pth), so an installed executable could
import the *checkout* instead of what was installed; a probe checks where the modules come from.
"""
from __future__ import annotations

import configparser
import os
import shutil
import subprocess
import sys
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import yaml
from support.packaging import NODES, TOOLS

from adcs_sim.app.batch.kernels import SPECIALISATIONS, dispatcher

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = 'adcs_sim'
VENV_BIN = Path(sys.prefix) / 'bin'
SCENARIO = 'microsat_pd_slew.yaml'
# Top-level names never copied into a build: environments, VCS, build products, run outputs.
COPY_EXCLUDE = {'.venv', 'venv', '.git', 'build', 'install', 'log', 'dist', 'runs', '.pytest_cache'}
BUILD_TIMEOUT = 180.0  # a hang guard only, not a timing assertion
NODE_TIMEOUT = 60.0


CONSOLE_SCRIPTS = {**NODES, **TOOLS}


# --- helpers ------------------------------------------------------------------------------------

def _copy_source(dest: Path) -> Path:
    """Copy the checkout to ``dest`` without environments, VCS data and build products, but with
    numba's cache of the kernels (``__pycache__/*.nbi``, ``*.nbc``): the build compiles nothing then."""
    def ignore(directory, names):
        if Path(directory).name == '__pycache__':
            return {n for n in names if not n.endswith(('.nbi', '.nbc'))}
        skip = {n for n in names if n.endswith('.egg-info')}
        if Path(directory).resolve() == ROOT:
            skip |= COPY_EXCLUDE & set(names)
        return skip

    shutil.copytree(ROOT, dest, ignore=ignore, symlinks=True)
    return dest


def _tail(text: str, lines: int = 40) -> str:
    return '\n'.join(text.splitlines()[-lines:])


def _tool(name: str) -> Path:
    path = VENV_BIN / name
    if not path.exists():
        pytest.fail(f'{path} is missing: the test venv must provide {name} '
                    f'(requirements-dev.txt pins colcon-core, colcon-ros, colcon-python-setup-py)')
    return path


def _base_env() -> dict:
    env = dict(os.environ)
    env['PATH'] = f'{VENV_BIN}{os.pathsep}{env.get("PATH", "")}'
    env['PYTHONDONTWRITEBYTECODE'] = '1'
    env['PIP_NO_INDEX'] = '1'  # the builds below must never reach a registry
    env['PIP_DISABLE_PIP_VERSION_CHECK'] = '1'
    return env


def _sourced_env(install_base: Path, base: dict) -> dict:
    """The environment after sourcing the workspace's setup script, as a user would.

    colcon-bash is not installed here, so colcon writes only the POSIX ``setup.sh``; prefer
    ``setup.bash`` when it exists.
    """
    bash_setup, sh_setup = install_base / 'setup.bash', install_base / 'setup.sh'
    if bash_setup.exists():
        shell, script = 'bash', bash_setup
    elif sh_setup.exists():
        shell, script = 'sh', sh_setup
    else:
        pytest.fail(f'colcon wrote neither setup.bash nor setup.sh into {install_base}: '
                    f'{sorted(p.name for p in install_base.iterdir())}')
    proc = subprocess.run([shell, '-c', '. "$1" && env -0', shell, str(script)], env=base,
                          capture_output=True, timeout=BUILD_TIMEOUT)
    assert proc.returncode == 0, f'sourcing {script} failed:\n{proc.stderr.decode()}'
    env = {}
    for item in proc.stdout.split(b'\0'):
        if b'=' in item:
            key, _, value = item.partition(b'=')
            env[key.decode()] = value.decode()
    return env


@dataclass
class ColconBuild:
    workspace: Path
    install_base: Path
    returncode: int
    output: str
    env: dict = field(default_factory=dict)

    def require_success(self) -> None:
        if self.returncode != 0:
            pytest.fail(f'colcon build failed (exit {self.returncode}) in {self.workspace}:\n'
                        f'{_tail(self.output)}', pytrace=False)


def _python_without_blanks(tmp: Path) -> Path:
    """This venv's interpreter, by a path without blanks. colcon runs a package's build with the
    interpreter it runs on, and that path ends up in the workspace's setup scripts (colcon-core
    0.21.3 runs it unquoted: from a path with a blank they source nothing, silently) and in the
    installed executables' shebangs (which a kernel splits at the blank). The venv lives in the
    clone, so a clone under such a path would fail the build's tests for where it lives: under it,
    colcon runs on an alias of the venv in ``tmp`` (its ``pyvenv.cfg``, its ``lib``, the same
    interpreter): the same environment (README, "ROS users")."""
    python = VENV_BIN / 'python'
    if not any(c.isspace() for c in str(python)):
        return python
    alias = tmp / 'venv'
    assert not any(c.isspace() for c in str(alias)), f'the temporary directory {tmp} has a blank too'
    (alias / 'bin').mkdir(parents=True)
    shutil.copy(VENV_BIN.parent / 'pyvenv.cfg', alias / 'pyvenv.cfg')
    (alias / 'lib').symlink_to(VENV_BIN.parent / 'lib')
    (alias / 'bin' / 'python').symlink_to(python.resolve())
    return alias / 'bin' / 'python'


@pytest.fixture(scope='module')
def colcon_build(tmp_path_factory) -> ColconBuild:
    """``colcon build`` of a copy of the repository in a fresh workspace (built once per module)."""
    ws = tmp_path_factory.mktemp('colcon_ws')
    _copy_source(ws / 'src' / PACKAGE)
    colcon = [str(_python_without_blanks(ws)), str(_tool('colcon'))]
    env = _base_env()
    env['COLCON_HOME'] = str(ws / 'colcon_home')  # no user defaults / mixins leak in
    for var in ('COLCON_DEFAULTS_FILE', 'COLCON_PREFIX_PATH', 'AMENT_PREFIX_PATH', 'CMAKE_PREFIX_PATH'):
        env.pop(var, None)
    cmd = [*colcon, '--log-base', str(ws / 'log'), 'build',
           '--base-paths', str(ws / 'src'),
           '--build-base', str(ws / 'build'),
           '--install-base', str(ws / 'install'),
           '--event-handlers', 'console_direct+']
    try:
        proc = subprocess.run(cmd, cwd=ws, env=env, capture_output=True, text=True,
                              timeout=BUILD_TIMEOUT)
        returncode, output = proc.returncode, proc.stdout + proc.stderr
    except subprocess.TimeoutExpired as exc:
        returncode, output = -1, f'timed out after {BUILD_TIMEOUT} s\n{exc.stdout or ""}{exc.stderr or ""}'
    build = ColconBuild(ws, ws / 'install', returncode, output)
    if returncode == 0:
        build.env = _sourced_env(build.install_base, _base_env())
    return build


def _package_prefix(build: ColconBuild, monkeypatch) -> Path:
    """What ``ros2 run`` does first: the package's prefix from the ament index."""
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix
    ament_prefix_path = build.env.get('AMENT_PREFIX_PATH', '')
    install = str(build.install_base)
    assert any(p.startswith(install) for p in ament_prefix_path.split(os.pathsep) if p), (
        f'sourcing the workspace did not put {install} on AMENT_PREFIX_PATH ({ament_prefix_path!r})')
    # Only the workspace's own prefixes: the venv's share/ament_index must not answer for us.
    monkeypatch.setenv('AMENT_PREFIX_PATH', os.pathsep.join(
        p for p in ament_prefix_path.split(os.pathsep) if p.startswith(install)))
    try:
        prefix = Path(get_package_prefix(PACKAGE))
    except PackageNotFoundError as exc:
        pytest.fail(f'ament index does not know {PACKAGE}: {exc}')
    assert prefix.is_relative_to(build.install_base), prefix
    return prefix


def _installed_executables(prefix: Path) -> set[str]:
    """Executables ``ros2 run adcs_sim <exe>`` can start: executable files in lib/adcs_sim."""
    lib = prefix / 'lib' / PACKAGE
    assert lib.is_dir(), f'{lib} missing: setup.cfg must install scripts to $base/lib/{PACKAGE}'
    return {p.name for p in lib.iterdir() if p.is_file() and os.access(p, os.X_OK)}


def _interpreter(script: Path) -> str:
    first = script.read_text().splitlines()[0]
    assert first.startswith('#!'), f'{script} has no shebang: {first!r}'
    return first[2:].strip().split()[0]


# --- colcon: layout, ament index, executables -----------------------------------------------------

@pytest.mark.slow
def test_colcon_build_installs_a_ros_package(colcon_build, monkeypatch):
    colcon_build.require_success()
    layout_file = colcon_build.install_base / '.colcon_install_layout'
    layout = layout_file.read_text().strip() if layout_file.exists() else 'isolated'
    expected_prefix = colcon_build.install_base / (PACKAGE if layout == 'isolated' else '')
    marker = expected_prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / PACKAGE
    assert marker.is_file(), f'ament index marker {marker} not installed ({layout} layout)'

    prefix = _package_prefix(colcon_build, monkeypatch)
    assert prefix == expected_prefix

    found = _installed_executables(prefix)
    missing = sorted(set(NODES) - found)
    assert not missing, f'node executables not in {prefix / "lib" / PACKAGE}: {missing} (found {sorted(found)})'
    assert found == set(CONSOLE_SCRIPTS), (
        f'lib/{PACKAGE} holds {sorted(found)}, setup.py declares {sorted(CONSOLE_SCRIPTS)}')
    for exe in NODES:
        interpreter = _interpreter(prefix / 'lib' / PACKAGE / exe)
        assert Path(interpreter).exists(), f'{exe}: interpreter {interpreter} does not exist'

    share = prefix / 'share' / PACKAGE
    assert (share / 'package.xml').is_file()
    assert (share / 'package.xml').read_bytes() == (ROOT / 'package.xml').read_bytes()
    config = share / 'config' / SCENARIO
    assert config.is_file(), f'{config} not installed'
    assert config.read_bytes() == (ROOT / 'config' / SCENARIO).read_bytes()


@pytest.mark.slow
def test_colcon_installed_modules_are_the_installed_copies(colcon_build, monkeypatch):
    """Every executable's module imports from the install prefix, not from the checkout.

    The venv's editable install puts the checkout on sys.path, which would hide a package that
    colcon (setuptools ``find_packages``) did not install — e.g. a directory without
    ``__init__.py``.
    """
    colcon_build.require_success()
    prefix = _package_prefix(colcon_build, monkeypatch)
    site = [Path(p) for p in colcon_build.env.get('PYTHONPATH', '').split(os.pathsep)
            if p and Path(p).is_relative_to(colcon_build.install_base)]
    assert site, f'sourcing the workspace put nothing of {colcon_build.install_base} on PYTHONPATH'
    modules = sorted({target.split(':')[0] for target in NODES.values()})
    interpreter = _interpreter(prefix / 'lib' / PACKAGE / next(iter(NODES)))
    probe = ('import importlib, sys\n'
             'for name in sys.argv[1:]:\n'
             '    try:\n'
             '        print(name, importlib.import_module(name).__file__)\n'
             '    except Exception as exc:\n'
             '        print(name, "ERROR", repr(exc))\n')
    proc = subprocess.run([interpreter, '-c', probe, *modules], cwd=colcon_build.workspace,
                          env=colcon_build.env, capture_output=True, text=True, timeout=NODE_TIMEOUT)
    assert proc.returncode == 0, proc.stderr
    origins = dict(line.split(' ', 1) for line in proc.stdout.splitlines() if ' ' in line)
    wrong = {}
    for module in modules:
        origin = origins.get(module, 'not reported')
        if not Path(origin).is_relative_to(colcon_build.install_base):
            top = module.split('.')[0]
            installed = [str(s / top) for s in site if (s / top).is_dir()]
            hint = ('' if installed else
                    f'; package {top!r} was not installed at all (does {top}/ and each subpackage '
                    f'have an __init__.py? setup.py find_packages() only collects regular packages)')
            wrong[module] = origin + hint
    assert not wrong, ('installed executables would not run the installed code:\n' +
                       '\n'.join(f'  {m}: imported from {o}' for m, o in wrong.items()))


def _bad_params_file(config: Path, dest: Path) -> tuple[Path, dict]:
    """The installed scenario with one bad parameter per node section; returns file, node -> key."""
    data = yaml.safe_load(config.read_text())
    bad = {}
    for node in NODES:
        params = data.setdefault(node, {}).setdefault('ros__parameters', {})
        if node == 'dynamics':
            params['duration'] = -1.0  # non-physical value
            bad[node] = 'duration'
        else:
            params['no_such_parameter_for_test'] = 1.0  # unknown key
            bad[node] = 'no_such_parameter_for_test'
    dest.write_text(yaml.safe_dump(data))
    return dest, bad


@pytest.mark.parametrize('exe', sorted(NODES))
@pytest.mark.slow
def test_colcon_installed_executable_starts(colcon_build, exe, ros_domain, monkeypatch, tmp_path):
    """Run ``<prefix>/lib/adcs_sim/<exe>`` with a bad parameter: exit 2, message names the key."""
    colcon_build.require_success()
    prefix = _package_prefix(colcon_build, monkeypatch)
    params, bad = _bad_params_file(prefix / 'share' / PACKAGE / 'config' / SCENARIO,
                                   tmp_path / 'bad.yaml')
    script = prefix / 'lib' / PACKAGE / exe
    assert script.is_file(), f'{script} not installed'
    env = ros_domain.env(colcon_build.env)
    proc = subprocess.run([str(script), '--ros-args', '--params-file', str(params)], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=NODE_TIMEOUT)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 2, f'{exe} exited {proc.returncode}, expected 2 (bad parameters):\n{_tail(output)}'
    assert bad[exe] in output, f'{exe}: message does not name {bad[exe]!r}:\n{_tail(output)}'
    assert 'Traceback' not in output, output


# --- pip wheel ------------------------------------------------------------------------------------

@dataclass
class Wheel:
    path: Path
    names: list[str]
    entry_points: configparser.ConfigParser
    data_prefix: str


@pytest.fixture(scope='module')
def wheel(tmp_path_factory) -> Wheel:
    tmp = tmp_path_factory.mktemp('wheel')
    source = _copy_source(tmp / 'src')
    dist = tmp / 'dist'
    cmd = [sys.executable, '-m', 'pip', 'wheel', '--no-deps', '--no-build-isolation', '-w', str(dist),
           str(source)]
    try:
        proc = subprocess.run(cmd, cwd=tmp, env=_base_env(), capture_output=True, text=True,
                              timeout=BUILD_TIMEOUT)
    except subprocess.TimeoutExpired:
        pytest.fail(f'pip wheel timed out after {BUILD_TIMEOUT} s')
    if proc.returncode != 0:
        pytest.fail(f'pip wheel failed (exit {proc.returncode}):\n{_tail(proc.stdout + proc.stderr)}',
                    pytrace=False)
    wheels = sorted(dist.glob(f'{PACKAGE}-*.whl'))
    assert len(wheels) == 1, f'expected one {PACKAGE} wheel in {dist}, got {wheels}'
    with zipfile.ZipFile(wheels[0]) as zf:
        names = zf.namelist()
        dist_info = [n for n in names if n.endswith('.dist-info/entry_points.txt')]
        assert len(dist_info) == 1, f'no single entry_points.txt in the wheel: {dist_info}'
        entry_points = configparser.ConfigParser(delimiters=('=',))
        entry_points.optionxform = str  # keep names case-sensitive
        entry_points.read_string(zf.read(dist_info[0]).decode())
    data_prefix = dist_info[0].replace('.dist-info/entry_points.txt', '.data/data/')
    return Wheel(wheels[0], names, entry_points, data_prefix)


@pytest.mark.slow
def test_wheel_declares_console_scripts_and_ros_data_files(wheel):
    assert wheel.entry_points.has_section('console_scripts'), 'wheel declares no console_scripts'
    scripts = dict(wheel.entry_points['console_scripts'])
    expected = {'dynamics', 'recorder', 'pd_controller', 'adcs-run', 'adcs-analyze'}
    assert expected <= set(scripts), f'missing console scripts: {sorted(expected - set(scripts))}'
    for name, target in CONSOLE_SCRIPTS.items():
        assert scripts.get(name, '').replace(' ', '') == target.replace(' ', ''), (
            f'{name}: wheel says {scripts.get(name)!r}, setup.py says {target!r}')
    for data_file in (f'share/{PACKAGE}/config/{SCENARIO}',
                      f'share/ament_index/resource_index/packages/{PACKAGE}',
                      f'share/{PACKAGE}/package.xml'):
        assert wheel.data_prefix + data_file in wheel.names, (
            f'{data_file} not among the wheel data files '
            f'({sorted(n for n in wheel.names if ".data/" in n)})')
    # The nodes' Fast DDS profile (package data of the interface layer, beside adcs_msgs_py/node.py).
    assert 'adcs_msgs_py/fastdds_profile.xml' in wheel.names
    assert 'adcs_sim/nodes/recorder_fastdds.xml' in wheel.names   # the recorder's (its readers bounded)


@pytest.mark.parametrize('script', sorted(CONSOLE_SCRIPTS))
@pytest.mark.slow
def test_wheel_contains_each_console_script_target(wheel, script):
    """A console script whose module is not in the wheel crashes on start after ``pip install``."""
    module, _, attr = CONSOLE_SCRIPTS[script].partition(':')
    parts = module.split('.')
    candidates = ['/'.join(parts) + '.py', '/'.join(parts) + '/__init__.py']
    assert any(c in wheel.names for c in candidates), (
        f'{script} = {CONSOLE_SCRIPTS[script]}: {candidates[0]} is not in {wheel.path.name}')
    # Each enclosing package must be a regular package, or find_packages() will have skipped it.
    for i in range(1, len(parts)):
        init = '/'.join(parts[:i]) + '/__init__.py'
        assert init in wheel.names, f'{script}: {init} is not in {wheel.path.name}'


@pytest.mark.slow
def test_the_wheel_carries_numbas_cache_of_every_kernel(wheel):
    """setup.py's build compiles every listed kernel into the built copy: the wheel holds numba's index
    and machine code of each (``<module>.<function>-<line>.pyXY.nbi`` + ``.nbc`` beside its module),
    so the first run after ``pip install`` compiles nothing."""
    tag = f'py{sys.version_info.major}{sys.version_info.minor}'
    for kernel, _, _ in SPECIALISATIONS:
        module = kernel.rsplit('.', 1)[0]
        folder, name = module.rsplit('.', 1)
        function = dispatcher(kernel).py_func.__qualname__   # numba names the files after it (_rk4_runs)
        prefix = f'{folder.replace(".", "/")}/__pycache__/{name}.{function}-'
        cached = [n for n in wheel.names if n.startswith(prefix) and n.endswith(f'.{tag}.nbi')]
        assert cached, f'{kernel}: no {prefix}*.{tag}.nbi in {wheel.path.name}'
        assert any(n.startswith(prefix) and n.endswith('.nbc') for n in wheel.names), kernel


def test_setup_nodes_match_colcon_and_wheel_executables(colcon_build, wheel, monkeypatch):
    colcon_build.require_success()
    found = _installed_executables(_package_prefix(colcon_build, monkeypatch))
    scripts = set(dict(wheel.entry_points['console_scripts']))
    assert set(NODES) <= found, f'setup.py NODES {sorted(NODES)} vs colcon lib/{PACKAGE} {sorted(found)}'
    assert set(NODES) <= scripts, f'setup.py NODES {sorted(NODES)} vs wheel console scripts {sorted(scripts)}'
    assert found == scripts, f'colcon installed {sorted(found)}, the wheel declares {sorted(scripts)}'


def test_runner_registry_matches_setup_py():
    """The runner starts a section's node by the module setup.py installs for that executable."""
    from adcs_sim.app.scenario.registry import NODES as REGISTRY
    assert set(REGISTRY) == set(NODES)
    for name, info in REGISTRY.items():
        assert NODES[name].split(':')[0] == info.module, name
        assert info.schema.node == name, f'{name}: schema is for node {info.schema.node!r}'


@pytest.mark.slow
def test_wheel_requires_the_pinned_runtime_dependencies(wheel):
    """``pip install .`` installs what requirements.txt pins, pins included (issue #17)."""
    from support.packaging import requirements
    with zipfile.ZipFile(wheel.path) as zf:
        [metadata] = [n for n in zf.namelist() if n.endswith('.dist-info/METADATA')]
        lines = zf.read(metadata).decode().splitlines()
    requires = sorted(line.split(':', 1)[1].strip().replace(' ', '') for line in lines
                      if line.startswith('Requires-Dist:'))
    assert requires == sorted(r.replace(' ', '') for r in requirements().values())
