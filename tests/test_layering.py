"""The layering rule, computed from the sources: every import of every module (at module level and
inside functions alike) runs from the application down to the kernel, never up or sideways.

    application      adcs_sim.app          registry, batch, runner, campaigns, analysis, report
    nodes            adcs_sim.nodes, adcs_controllers.nodes    thin ROS adapters
    truth model | flight software | storage
                     adcs_sim.truth | adcs_controllers.laws, .families, .estimators | adcs_sim.bag
    interface        adcs_msgs_py          topics, QoS, conversions, validation, schemas, node base
    kernel           adcs_core             attitude, orbit, inertia, faults

A module may import the layers below its own and its own layer; the three layers side by side
never import each other (flight software never sees the truth model). ROS (rclpy and the message
packages) is imported only by the interface's ROS side, the nodes and the runner's process
modules: the rest runs without ROS (Monte Carlo, offline analysis), which a fresh interpreter
checks too.
"""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest
from support.paths import ROOT

PACKAGES = ('adcs_core', 'adcs_msgs_py', 'adcs_controllers', 'adcs_sim')
# (layer, rank, module prefixes): the most specific prefix wins.
LAYERS = [
    ('kernel', 0, ('adcs_core',)),
    ('interface', 1, ('adcs_msgs_py',)),
    ('truth model', 2, ('adcs_sim.truth',)),
    ('flight software', 2, ('adcs_controllers.laws', 'adcs_controllers.families', 'adcs_controllers.estimators',
                            'adcs_controllers.step')),
    ('storage', 2, ('adcs_sim.bag',)),
    ('nodes', 3, ('adcs_sim.nodes', 'adcs_controllers.nodes')),
    ('application', 4, ('adcs_sim.app',)),
]
PACKAGE_DOCS = {'adcs_sim', 'adcs_controllers'}   # package __init__ modules: a docstring, no imports
ROS_ROOTS = {'rclpy', 'rosgraph_msgs', 'nav_msgs', 'sensor_msgs', 'geometry_msgs', 'std_msgs',
             'diagnostic_msgs', 'builtin_interfaces', 'rcl_interfaces', 'visualization_msgs'}
# ament_index_python (a file lookup, no middleware) is allowed anywhere: scenario_files uses it.
# The modules that may import ROS besides the nodes: the interface's ROS side and the runner's
# process handling.
# adcs_msgs_py.visual builds the viewer messages (TransformStamped, MarkerArray, Vector3Stamped) of
# the dynamics node: message construction, like conversions, belongs to the interface's ROS side.
# adcs_msgs_py.cdr (the hot messages' serialized fast path) too: it (de)serializes those messages.
# adcs_msgs_py.executor is the nodes' executor (part of adcs_msgs_py.node's process plumbing).
ROS_ALLOWED = {'adcs_msgs_py.topics', 'adcs_msgs_py.node', 'adcs_msgs_py.executor', 'adcs_msgs_py.conversions',
               'adcs_msgs_py.cdr',
               'adcs_msgs_py.conversions_determination',
               'adcs_msgs_py.rcl_params', 'adcs_msgs_py.visual', 'adcs_msgs_py.recorded_topics', 'adcs_sim.app.graph.processes', 'adcs_sim.app.graph.runner'}
# rcl's own params-file parser (through rclpy's C extension: no participant, no DDS). Scenario files
# are read with it so that the runner sees what the nodes get; the pure modules reach it only
# when they read a file (a function-level import, which the run-time check below confirms).
RCL_PARSER = 'adcs_msgs_py.rcl_params'


def _modules() -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob('*.py')):
            parts = path.relative_to(ROOT).with_suffix('').parts
            name = '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)
            out[name] = path
    return out


MODULES = _modules()


def _imports(name: str, path: Path) -> set[str]:
    """Every module ``name`` imports, resolved to the longest known module name (project modules)
    or the top-level package (others); imports inside functions included."""
    tree = ast.parse(path.read_text(), str(path))
    is_pkg = path.name == '__init__.py'
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split('.') if is_pkg else name.split('.')[:-1]
                base = base[:len(base) - node.level + 1]
                mod = '.'.join(base + ([node.module] if node.module else []))
            else:
                mod = node.module
            found.add(mod)
            found.update(f'{mod}.{a.name}' for a in node.names if f'{mod}.{a.name}' in MODULES)
    out = set()
    for mod in found:
        probe = mod
        while probe and probe not in MODULES:
            probe = probe.rpartition('.')[0]
        out.add(probe if probe else mod.split('.')[0])
    return out - {name}


IMPORTS = {name: _imports(name, path) for name, path in MODULES.items()}


def layer_of(module: str) -> tuple[str, int] | None:
    best = None
    for layer, rank, prefixes in LAYERS:
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + '.')) and (best is None or len(prefix) > best[0]):
                best = (len(prefix), layer, rank)
    return None if best is None else best[1:]


def test_every_module_has_a_layer():
    missing = [m for m in MODULES if m not in PACKAGE_DOCS and layer_of(m) is None]
    assert not missing, f'modules outside every layer (add them to a layer folder): {missing}'
    assert len(MODULES) > 60   # the walk found the packages


@pytest.mark.parametrize('package', sorted(PACKAGE_DOCS))
def test_package_docs_import_nothing(package):
    assert not {m for m in IMPORTS[package] if m.split('.')[0] in PACKAGES}, IMPORTS[package]


def test_imports_run_down_the_layers():
    wrong = []
    for module, deps in IMPORTS.items():
        if module in PACKAGE_DOCS:
            continue
        layer, rank = layer_of(module)
        for dep in deps:
            if dep.split('.')[0] not in PACKAGES or dep in PACKAGE_DOCS:
                continue
            dep_layer, dep_rank = layer_of(dep)
            if dep_rank > rank or (dep_rank == rank and dep_layer != layer):
                wrong.append(f'{module} ({layer}) imports {dep} ({dep_layer})')
    assert not wrong, '\n'.join(wrong)


def test_package_graph_is_acyclic():
    """adcs_sim -> adcs_controllers -> adcs_msgs_py -> adcs_core, never back."""
    edges = {p: set() for p in PACKAGES}
    for module, deps in IMPORTS.items():
        for dep in deps:
            if dep.split('.')[0] in PACKAGES and dep.split('.')[0] != module.split('.')[0]:
                edges[module.split('.')[0]].add(dep.split('.')[0])
    order, state = [], {}

    def visit(p, path):
        if state.get(p) == 'open':
            raise AssertionError(f'package import cycle: {" -> ".join(path + [p])}')
        if state.get(p) != 'done':
            state[p] = 'open'
            for q in sorted(edges[p]):
                visit(q, path + [p])
            state[p] = 'done'
            order.append(p)
    for p in PACKAGES:
        visit(p, [])
    assert 'adcs_sim' not in edges['adcs_controllers'] and not edges['adcs_core'], edges


def module_cycles(imports: dict[str, set[str]]) -> list[list[str]]:
    """The import circles among project modules: each strongly connected component of more than one
    module (Tarjan), its modules sorted. Function-level imports count: a lazy import that closes a
    circle only hides it."""
    graph = {m: sorted(d for d in deps if d in imports) for m, deps in imports.items()}
    index, low, on_stack, stack, found = {}, {}, set(), [], []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(graph[root]))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:   # iterative depth-first walk (no recursion limit on a long chain)
            node, children = work[-1]
            child = next(children, None)
            if child is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        found.append(sorted(component))
            elif child not in index:
                index[child] = low[child] = len(index)
                stack.append(child)
                on_stack.add(child)
                work.append((child, iter(graph[child])))
            elif child in on_stack:
                low[node] = min(low[node], index[child])
    return found


def test_module_cycles_finds_a_circle_and_only_that():
    imports = {'a': {'b'}, 'b': {'c'}, 'c': {'a', 'd'}, 'd': set(), 'e': {'e2'}, 'e2': {'e'}, 'f': {'a'}}
    assert sorted(module_cycles(imports)) == [['a', 'b', 'c'], ['e', 'e2']]
    assert module_cycles({'a': {'b'}, 'b': {'c'}, 'c': set()}) == []


def test_no_module_imports_itself_back():
    """No import circle between modules, however indirect, lazy imports included."""
    assert module_cycles(IMPORTS) == []


def lazy_imports_without_reason(source: str) -> list[int]:
    """Lines of the imports made inside a function that give no ``# lazy: <reason>`` (on their
    line, or on the comment lines right above their block of imports)."""
    lines = source.split('\n')
    found = set()
    for fn in ast.walk(ast.parse(source)):
        if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            found |= {n.lineno for n in ast.walk(fn) if isinstance(n, (ast.Import, ast.ImportFrom))}
    wrong = []
    for line in sorted(found):
        i = line - 1
        while i > 0 and (lines[i - 1].strip().startswith(('import ', 'from ')) or not lines[i - 1].strip()):
            i -= 1   # the block: its imports and the blank lines that group them
        above = []
        while i > 0 and lines[i - 1].strip().startswith('#'):
            i -= 1
            above.append(lines[i])
        if not any('# lazy:' in text for text in (lines[line - 1], *above)):
            wrong.append(line)
    return wrong


def test_lazy_imports_are_recognised():
    ok = 'def f():\n    # lazy: 1 s\n    import a\n\n    from b import c\n'
    bare = 'def f():\n    x = 1\n    import a\n'
    assert lazy_imports_without_reason(ok) == []
    assert lazy_imports_without_reason(bare) == [3]
    assert lazy_imports_without_reason('import a\n') == []


def test_the_application_imports_inside_a_function_only_with_its_reason():
    """adcs_sim.app imports at module level; an import inside a function is there for a measured
    start-up time (or an optional dependency) and says so: ``# lazy: <reason>``."""
    app = ROOT / 'adcs_sim' / 'app'
    wrong = [f'{path.relative_to(ROOT)}:{line}' for path in sorted(app.rglob('*.py'))
             for line in lazy_imports_without_reason(path.read_text())]
    assert not wrong, 'an import inside a function without "# lazy: <reason>":\n' + '\n'.join(wrong)


def test_ros_stays_in_the_nodes_and_the_interface():
    wrong = []
    for module, deps in IMPORTS.items():
        layer = (layer_of(module) or ('', 0))[0]
        if layer == 'nodes' or module in ROS_ALLOWED:
            continue
        ros = sorted(d for d in deps if d.split('.')[0] in ROS_ROOTS)
        if ros:
            wrong.append(f'{module} imports {ros}')
    assert not wrong, '\n'.join(wrong)


def _closure(module: str) -> set[str]:
    seen, todo = set(), [module]
    while todo:
        m = todo.pop()
        if m in seen or m not in IMPORTS:
            continue
        seen.add(m)
        todo.extend(IMPORTS[m])
    return seen


PURE = sorted(m for m in MODULES if m not in PACKAGE_DOCS and layer_of(m)[0] != 'nodes'
              and not (_closure(m) & (ROS_ALLOWED - {RCL_PARSER})) and m != RCL_PARSER)


def test_the_pure_modules_are_most_of_the_code():
    for must in ('adcs_core.attitude', 'adcs_sim.truth.plant', 'adcs_controllers.families',
                 'adcs_sim.app.batch.engine', 'adcs_sim.app.campaign.plan', 'adcs_sim.app.analysis.metrics',
                 'adcs_msgs_py.params', 'adcs_sim.bag'):
        assert must in PURE, f'{must} reaches a ROS module: {sorted(_closure(must) & ROS_ALLOWED)}'


@pytest.mark.slow
@pytest.mark.parametrize('module', PURE)
def test_pure_module_imports_no_ros_at_run_time(module):
    """The static rule, checked in a fresh interpreter (nothing else pre-imports rclpy)."""
    code = f'import sys, {module}; print(sorted(m for m in sys.modules if m.split(".")[0] in {sorted(ROS_ROOTS)!r}))'
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == '[]', f'{module} pulls in {out.stdout.strip()}'


HEAVY_AT_FIRST_USE = ('scipy.spatial', 'scipy.linalg', 'pandas', 'ppigrf')


def test_node_processes_do_not_import_what_they_only_need_at_first_use():
    """Every node module, imported as its process starts: scipy.spatial (0.4-1.1 s), scipy.linalg and
    pandas/ppigrf (0.5-1.3 s) are imported where they are used (Euler angles, the pseudo-inverse and
    ARE at law construction, an IGRF model), not by every node at start (issue #18)."""
    from adcs_sim.app.scenario.registry import NODES
    modules = sorted({n.module for n in NODES.values()})
    code = (f'import sys, importlib; [importlib.import_module(m) for m in {modules!r}]; '
            f'print(sorted(m for m in sys.modules if m in {HEAVY_AT_FIRST_USE!r}))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == '[]', f'imported at start: {out.stdout.strip()}'


def test_validating_a_scenario_does_not_import_numba():
    """``adcs-run`` validates the scenario before it starts any node: that needs the schemas, not the
    compiled plant kernel, so numba (0.4-0.7 s) is imported by the first plant built, not by the runner
    (issue #18, start-up: adcs_sim/truth/kernel_kinds.py)."""
    code = ('import sys; import adcs_sim.app.graph.runner; from adcs_sim.app.scenario.files import validate_scenario; '
            'validate_scenario("config/uosat12_gsmn.yaml"); print("numba" in sys.modules); '
            'from adcs_sim.truth.plant import Plant; import numpy; Plant(numpy.eye(3)); print("numba" in sys.modules)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.split() == ['False', 'True']
