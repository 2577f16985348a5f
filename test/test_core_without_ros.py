"""The numerical core imports and runs with rclpy and every message package absent."""
import os
import subprocess
import sys
import textwrap

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CORE = ["rotation", "profiles", "sensors", "coning", "integrator", "config", "coning_analysis", "observability",
        "star_camera", "boresight", "calibrator", "integral_method", "tkachenko", "sensors.effects",
        "sensors.covariance", "streams", "buffers", "analysis.pairs", "analysis.linear_model",
        "analysis.discrepancy", "analysis.diagnostics", "analysis.hidden", "analysis.linearisation",
        "attitude_kernel", "navigation.gravity", "navigation.trajectories", "navigation.update",
        "navigation.recursion", "navigation.covariance", "navigation.alignment", "navigation.navigator",
        "navigation.channel", "navigation.system", "navigation.run", "analysis.gyrocompass",
        "analysis.steady_filter", "boresight_consistency", "gyro_calibration"]


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
        from strapdown_ros.integrator import AttitudeIntegrator
        from strapdown_ros.profiles import ConingProfile
        p = ConingProfile(0.1, 1.0)
        t = np.arange(101) * 0.01
        out = AttitudeIntegrator("2", p.attitude(0.0), 0.0).push(p.delta_theta(t[:-1], t[1:]), t[1:])
        assert len(out) == 50
        loaded = [m for m in sys.modules if m.split(".")[0] in BLOCK]
        assert not loaded, loaded
        print("core ok")
    """)
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert "core ok" in res.stdout


def test_only_node_modules_import_ros():
    """Static check: no module outside strapdown_ros/nodes imports rclpy or message packages."""
    import re
    pattern = re.compile(r"^\s*(import rclpy|from rclpy|from (sensor|geometry|std|nav|diagnostic|builtin_interfaces"
                         r"|rcl_interfaces)(_msgs)?[. ])", re.M)
    offenders = []
    for root, _, files in os.walk(os.path.join(REPO, "strapdown_ros")):
        if os.path.basename(root) == "nodes":
            continue
        for f in files:
            if f.endswith(".py") and pattern.search(open(os.path.join(root, f), encoding="utf-8").read()):
                offenders.append(os.path.join(root, f))
    assert not offenders, offenders
