"""The numerical core imports and runs with rclpy and every message package absent."""
import os
import subprocess
import sys
import textwrap


REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ROS_ROOMS = ('nodes', 'bench/ros', 'demo.py')   # the only places that may import ROS


def core_modules():
    """Every module of the package outside the ROS rooms, as dotted names under strapdown_ros."""
    pkg = os.path.join(REPO, 'strapdown_ros')
    mods = []
    for root, _, files in os.walk(pkg):
        for f in sorted(files):
            rel = os.path.relpath(os.path.join(root, f), pkg)
            if not f.endswith('.py') or rel.startswith(ROS_ROOMS):
                continue
            name = rel[:-3].replace(os.sep, '.')
            mods.append(name[: -len('.__init__')] if name.endswith('__init__') else name)
    return sorted(m for m in mods if m and m != '__init__')


CORE = core_modules()


def test_core_imports_with_rclpy_absent():
    code = textwrap.dedent(f"""
        import importlib.abc, sys
        BLOCK = ("rclpy", "rcl_interfaces", "builtin_interfaces", "std_msgs", "geometry_msgs",
                 "sensor_msgs", "diagnostic_msgs", "nav_msgs", "rosidl_runtime_py")
        class Blocker(importlib.abc.MetaPathFinder):
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] in BLOCK:
                    raise ImportError("blocked for this test: " + name)
        sys.meta_path.insert(0, Blocker())
        sys.path.insert(0, {REPO!r})
        import numpy as np
        for m in {CORE!r}:
            importlib = __import__("importlib")
            importlib.import_module("strapdown_ros." + m)
        from strapdown_ros.attitude.integrator import AttitudeIntegrator
        from strapdown_ros.motion.profiles import ConingProfile
        p = ConingProfile(0.1, 1.0)
        t = np.arange(101) * 0.01
        integrator = AttitudeIntegrator("2", p.attitude(0.0), 0.0)
        out = integrator.push(p.delta_theta(t[:-1], t[1:]), t[1:])
        assert len(out) == 50
        loaded = [m for m in sys.modules if m.split(".")[0] in BLOCK]
        assert not loaded, loaded
        print("core ok")
    """)
    res = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert 'core ok' in res.stdout


def test_only_node_modules_import_ros():
    """No module outside the ROS rooms (nodes/, bench/ros/, demo.py) imports ROS (static check)."""
    import re
    pattern = re.compile(r'^\s*(import rclpy|from rclpy|from (sensor|geometry|std|nav|diagnostic'
                         r'|builtin_interfaces|rcl_interfaces)(_msgs)?[. ])', re.M)
    offenders = []
    for root, _, files in os.walk(os.path.join(REPO, 'strapdown_ros')):
        for f in files:
            rel = os.path.relpath(os.path.join(root, f), os.path.join(REPO, 'strapdown_ros'))
            if rel.startswith(ROS_ROOMS):
                continue
            if f.endswith('.py') and pattern.search(open(os.path.join(root, f),
                                                         encoding='utf-8').read()):
                offenders.append(os.path.join(root, f))
    assert not offenders, offenders
