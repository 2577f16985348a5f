"""
The layout of the package: rooms by role, then by subject, imported only downwards.

Static checks over the source (no imports run): no import cycle between modules, no room
importing a room above it, ROS imported only in the ROS rooms, no private name used outside
its module (tests included), and package imports at the top of a module.  The room order is
the one doc/architecture.md draws.
"""
import ast
import importlib
from pathlib import Path
import re

import pytest

REPO = Path(__file__).resolve().parents[2]
PACKAGE = REPO / 'strapdown_ros'

#: rooms from the bottom up; a room may import its own modules and the rooms of lower ranks
RANK = {
    'rotation': 0, 'text': 0, 'files': 0,
    'cli': 1, 'figures': 1, 'earth': 1, 'streams': 1,
    'motion': 2,
    'sensors': 3,
    'attitude': 4,
    'estimation': 5,
    'calibration': 6, 'navigation': 6, 'recording': 6,
    'discrepancy': 7,
    'params': 8,
    'sins': 9,
    'runs': 10,
    'fleet': 11,
    'nodes': 12, 'tools': 12, 'reproductions': 12,
    'bench': 13, 'demo': 13,
}
#: the only places that may import rclpy or message packages
ROS_ROOMS = ('nodes', 'bench/ros', 'demo.py')
ROS_PACKAGES = ('rclpy', 'rcl_interfaces', 'builtin_interfaces', 'std_msgs', 'geometry_msgs',
                'sensor_msgs', 'nav_msgs', 'diagnostic_msgs', 'rosidl_runtime_py')
#: optional extras, imported where they are used (the core needs numpy only)
OPTIONAL = ('numba', 'matplotlib', 'cv2', 'scipy', 'rosbags', 'yaml', 'allantools', 'pyins',
            'hypothesis', 'pandas', 'resource', 'dask', 'distributed', 'pyarrow',
            'psutil') + ROS_PACKAGES


def modules():
    """Map dotted module name -> path, for every module of the package."""
    out = {}
    for path in sorted(PACKAGE.rglob('*.py')):
        parts = path.relative_to(REPO).with_suffix('').parts
        name = '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)
        out[name] = path
    return out


MODULES = modules()


def room(name):
    """Return the room of a dotted module name (its first package level under strapdown_ros)."""
    parts = name.split('.')
    return parts[1] if len(parts) > 1 else '<package>'


def imports(path, top_only=False):
    """Return (module imported, lineno, at top level) for every strapdown_ros import in a file."""
    tree = ast.parse(path.read_text(encoding='utf-8'))
    top = {id(n) for n in tree.body}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and not node.level \
                and node.module.split('.')[0] == 'strapdown_ros':
            for alias in node.names:
                sub = f'{node.module}.{alias.name}'
                out.append((sub if sub in MODULES else node.module, node.lineno, id(node) in top))
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split('.')[0] == 'strapdown_ros':
                    out.append((alias.name, node.lineno, id(node) in top))
    return out


def test_no_relative_imports():
    """Every package import is absolute (as in demo_nodes_py)."""
    offenders = []
    for name, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.ImportFrom) and node.level:
                offenders.append(f'{path.relative_to(REPO)}:{node.lineno}')
    assert not offenders, offenders


def test_no_import_cycles():
    """The module import graph (imports anywhere in a module) has no cycle."""
    graph = {m: {t for t, _, _ in imports(p) if t in MODULES and t != m}
             for m, p in MODULES.items()}
    # a package's __init__ importing its own modules is the package's public face, not a cycle
    for m in graph:
        graph[m] = {t for t in graph[m] if not (t == m.rsplit('.', 1)[0] and m in MODULES)}
    state, stack, cycles = {}, [], []

    def visit(m):
        state[m] = 'open'
        stack.append(m)
        for t in sorted(graph[m]):
            if state.get(t) == 'open':
                cycles.append(stack[stack.index(t):] + [t])
            elif t not in state:
                visit(t)
        stack.pop()
        state[m] = 'done'

    for m in sorted(graph):
        if m not in state:
            visit(m)
    assert not cycles, cycles


def test_rooms_import_only_downwards():
    """A room imports only itself and the rooms below it in RANK."""
    assert {room(m) for m in MODULES} - {'<package>'} <= set(RANK), 'a room without a rank'
    offenders = []
    for m, path in MODULES.items():
        a = room(m)
        for t, line, _ in imports(path):
            b = room(t)
            if a == '<package>' or b == '<package>' or a == b:
                continue
            if RANK[b] >= RANK[a] and not (a == 'bench' and b in ('nodes', 'tools')):
                offenders.append(f'{path.relative_to(REPO)}:{line} imports {t}')
    assert not offenders, offenders


def test_only_the_ros_rooms_import_ros():
    """Rclpy and message packages are imported in nodes/, bench/ros/ and demo.py only."""
    offenders = []
    for m, path in MODULES.items():
        rel = str(path.relative_to(PACKAGE))
        if rel.startswith(ROS_ROOMS):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ''] if isinstance(node, ast.ImportFrom) else [])
            if any(n.split('.')[0] in ROS_PACKAGES for n in names):
                offenders.append(f'{rel}:{node.lineno}')
    assert not offenders, offenders


def test_package_imports_sit_at_the_top():
    """
    Package modules are imported at module level, never inside a function.

    The exceptions: the entry points of nodes/launch.py (signal handlers first), and a module
    outside the ROS rooms reaching a ROS room, which it may do only where ROS is needed.
    """
    def ros_room(t):
        return t.startswith(('strapdown_ros.nodes', 'strapdown_ros.bench.ros',
                             'strapdown_ros.demo'))

    offenders = [f'{p.relative_to(REPO)}:{line} {t}' for m, p in MODULES.items()
                 if m != 'strapdown_ros.nodes.launch'
                 for t, line, at_top in imports(p) if not at_top and not ros_room(t)]
    assert not offenders, offenders


def test_standard_library_imports_sit_at_the_top():
    """Inside a function only optional extras are imported (numba, matplotlib, opencv, ...)."""
    offenders = []
    for m, path in MODULES.items():
        if m == 'strapdown_ros.nodes.launch':
            continue
        tree = ast.parse(path.read_text(encoding='utf-8'))
        top = {id(n) for n in tree.body}
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)) and id(node) not in top:
                names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                         else [node.module or ''])
                if not all(n.split('.')[0] in OPTIONAL
                           or n.startswith(('strapdown_ros.nodes', 'strapdown_ros.bench.ros'))
                           for n in names):
                    offenders.append(f'{path.relative_to(REPO)}:{node.lineno} {names}')
    assert not offenders, offenders


def private_uses(path):
    """Return the private names a file takes from other modules, or from other objects."""
    tree = ast.parse(path.read_text(encoding='utf-8'))
    aliases, out = {}, []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module \
                and node.module.split('.')[0] == 'strapdown_ros':
            for a in node.names:
                sub = f'{node.module}.{a.name}'
                if sub in MODULES:
                    aliases[a.asname or a.name] = sub
                elif a.name.startswith('_') and not a.name.startswith('__'):
                    out.append(f'{node.lineno} {node.module}.{a.name}')
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split('.')[0] == 'strapdown_ros' and a.asname:
                    aliases[a.asname] = a.name
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and node.attr.startswith('_') \
                and not node.attr.startswith('__'):
            owner = node.value.id if isinstance(node.value, ast.Name) else None
            if owner in aliases:
                out.append(f'{node.lineno} {aliases[owner]}.{node.attr}')
            elif owner not in ('self', 'cls'):
                # another object's private attribute (obj._x, obj.part._x)
                out.append(f'{node.lineno} {ast.unparse(node)}')
    return out


def test_no_private_name_is_used_outside_its_module():
    """Neither a module nor a test reaches into another module's private names."""
    files = list(MODULES.values()) + sorted((REPO / 'test').rglob('*.py'))
    offenders = [f'{p.relative_to(REPO)}:{u}' for p in files for u in private_uses(p)]
    assert not offenders, offenders


def test_every_console_script_resolves_to_a_main():
    """Each console script of setup.py, and each module a node entry point runs, has a main."""
    pytest.importorskip('rclpy')
    setup = (REPO / 'setup.py').read_text(encoding='utf-8')
    scripts = dict(re.findall(r"'(\w+) = ([\w.]+:\w+)'", setup))
    assert len(scripts) >= 20, scripts
    for name, target in scripts.items():
        module, func = target.split(':')
        assert callable(getattr(importlib.import_module(module), func)), name
    launch = (PACKAGE / 'nodes' / 'launch.py').read_text(encoding='utf-8')
    targets = re.findall(r"_run\('([\w.]+)'\)", launch)
    assert len(targets) == 6, targets
    for t in targets:
        module = t if '.' in t else f'strapdown_ros.nodes.{t}'
        assert callable(importlib.import_module(module).main), t
