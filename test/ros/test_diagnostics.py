"""
Node reliability: logging, /diagnostics and the runtime parameter rules.

Logging that survives any sequence of severities, /diagnostics that list every current condition
at the worst level (the accelerometer stall included), and the runtime parameter rules.

Nodes are constructed in-process and fed through their message entry points; their real rclpy
loggers are used (a severity change at one call site used to raise inside rclpy's logger).
"""
import ast
import pathlib

from geometry_msgs.msg import Vector3Stamped
import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter

from strapdown_ros.motion.earth_profiles import static_profile
from strapdown_ros.nodes import ros_params, ros_status
from strapdown_ros.nodes.calibrator_node import CalibratorNode
from strapdown_ros.nodes.sins_node import SinsNode
from strapdown_ros.sins import accel_stall_limits


IDEAL = [Parameter(f'{s}_{k}', value=0.0) for s in ('gyro', 'accel')
         for k in ('bias_sigma', 'scale_sigma', 'misalignment_sigma', 'random_walk')]
NODES = pathlib.Path(__file__).resolve().parents[2] / 'strapdown_ros' / 'nodes'


def _msg(stamp_ns, v, frame=''):
    m = Vector3Stamped()
    m.header.stamp.sec, m.header.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
    m.header.frame_id = frame
    m.vector.x, m.vector.y, m.vector.z = (float(x) for x in v)
    return m


class Diagnostics:
    """What a node publishes on /diagnostics, as (level, message, values)."""

    def __init__(self, node, monkeypatch):
        self.got = []
        self.node = node
        monkeypatch.setattr(node.pub_diag, 'publish', self._take)

    def _take(self, arr):
        st = arr.status[0]
        self.got.append((st.level[0], st.message, {kv.key: kv.value for kv in st.values}))

    def now(self):
        """Publish the status now and return it."""
        self.node.publish_diagnostics()
        return self.got[-1]


def _feed(node, t0_ns, seconds, gyro_rate=100.0, accel_rate=300.0, accel=True, skip=(),
          frame_accel='', profile=None):
    """
    Feed interleaved Δθ and Δv of a body at rest.

    Interleaved Δθ and Δv of a body at rest (static profile: Earth rate and gravity exact), stamped
    from ``t0_ns`` on; gyro sample indices in ``skip`` are not sent.
    """
    prof = profile or static_profile(np.radians(50.45), np.radians(30.52), 150.0)
    tg = np.arange(1, int(round(seconds * gyro_rate)) + 1) / gyro_rate
    ta = np.arange(1, int(round(seconds * accel_rate)) + 1) / accel_rate if accel else np.zeros(0)
    dth = prof.delta_theta(tg - 1 / gyro_rate, tg)
    dv = prof.delta_v(ta - 1 / accel_rate, ta) if accel else np.zeros((0, 3))
    events = [(t, 0, k) for k, t in enumerate(tg) if k not in skip]
    events += [(t, 1, k) for k, t in enumerate(ta)]
    for t, kind, k in sorted(events):
        ns = t0_ns + int(round(t * 1e9))
        if kind == 0:
            node.on_gyro(_msg(ns, dth[k]))
        else:
            node.on_accel(_msg(ns, dv[k], frame_accel))
    node.process()
    return t0_ns + int(round(seconds * 1e9))


def test_node_log_takes_any_sequence_of_severities_and_throttles(ros):
    """Logging, the class: one helper call site, every severity, changing throttles."""
    node = rclpy.create_node('log_probe')
    try:
        log = ros_status.NodeLog(node.get_logger())
        for level in ('error', 'warn', 'info', 'warning', 'debug', 'error', 'info'):
            assert log(level, f'probe at {level}')
        assert log('warn', 'throttled', throttle=60.0)
        assert not log('error', 'throttled', throttle=60.0)                 # same key, within 60 s
        assert log('error', 'x' * 5000, throttle=1.0, key='other')          # echoed text bounded
        with pytest.raises(ValueError, match='valid: debug, info, warn, error'):
            log('fatalish', 'no such level')
    finally:
        node.destroy_node()


def test_no_node_selects_a_logger_method_at_run_time():
    """
    Check: no node selects a logger method at run time.

    Logging, the guard: rclpy's logger keeps one context per call site, so a call site must not
    choose its severity (``(lg.error if … else lg.info)(text)``) or pass a throttle that is not a
    constant.  Every node module is scanned; ros_status.NodeLog is the way to log at a level chosen
    at run time.
    """
    methods = {'debug', 'info', 'warn', 'warning', 'error', 'fatal'}
    bad = []
    for path in sorted(NODES.glob('*.py')):
        tree = ast.parse(path.read_text(encoding='utf-8'))
        for call in (n for n in ast.walk(tree) if isinstance(n, ast.Call)):
            f = call.func
            chosen = [n for n in ast.walk(f) if isinstance(n, ast.Attribute) and n.attr in methods]
            if chosen and not isinstance(f, ast.Attribute):
                bad.append(f'{path.name}:{call.lineno}: severity chosen at run time')
            if isinstance(f, ast.Attribute) and f.attr in methods:
                for kw in call.keywords:
                    if kw.arg == 'throttle_duration_sec' \
                            and not isinstance(kw.value, ast.Constant):
                        bad.append(f'{path.name}:{call.lineno}: variable rclpy throttle')
    assert not bad, bad


def test_every_node_logs_through_nodelog():
    """
    Check: every node logs through nodelog.

    Every node logs through ros_status.NodeLog (one call site per severity, its own throttle,
    bounded texts).  Outside ros_io.py, ``get_logger()`` appears only as the argument of
    ``NodeLog(...)``; no rclpy severity method is called on a logger, and no rclpy throttle is
    passed.
    """
    methods = {'debug', 'info', 'warn', 'warning', 'error', 'fatal'}
    bad = []
    for path in sorted(NODES.glob('*.py')):
        if path.name == 'ros_io.py':
            continue
        tree = ast.parse(path.read_text(encoding='utf-8'))
        wrapped = set()
        for call in (n for n in ast.walk(tree) if isinstance(n, ast.Call)):
            f = call.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, 'id', None)
            if name == 'NodeLog':
                wrapped.update(id(a) for a in call.args)
        for call in (n for n in ast.walk(tree) if isinstance(n, ast.Call)):
            f = call.func
            if isinstance(f, ast.Attribute) and f.attr == 'get_logger' and id(call) not in wrapped:
                bad.append(f'{path.name}:{call.lineno}: get_logger() outside NodeLog(...)')
            if isinstance(f, ast.Attribute) and f.attr in methods \
                    and isinstance(f.value, ast.Call) \
                    and getattr(f.value.func, 'attr', None) == 'get_logger':
                bad.append(f'{path.name}:{call.lineno}: rclpy logger called directly')
            if any(kw.arg == 'throttle_duration_sec' for kw in call.keywords):
                bad.append(f'{path.name}:{call.lineno}: rclpy throttle (NodeLog throttles)')
    assert not bad, bad


def test_static_alignment_then_stamps_step_back_and_foreign_frames_keep_it_alive(ros, monkeypatch):
    """
    Check: static alignment then stamps step back and foreign frames keep it alive.

    Logging, the repro: navigation with a static alignment; after it (info), the stamps step back
    10 s (errors: jump, resynchronisation) and Δv arrive in another frame (warn).  Before the fix
    the second severity at sins_node's one log call site raised inside the callback.
    """
    sins = SinsNode(namespace='/t_diag_align', parameter_overrides=[
        Parameter('navigation', value=True), Parameter('initial_alignment', value='static'),
        Parameter('alignment_time', value=1.0), Parameter('accel_rate', value=300.0),
        Parameter('batch_period', value=0.0), *IDEAL])
    diag = Diagnostics(sins, monkeypatch)
    try:
        t = _feed(sins, 100_000_000_000, 1.5)
        assert sins.nav.alignment is not None and sins.nav.alignment.ok
        assert sins.nav.navigator is not None
        level, message, values = diag.now()
        assert level == ros_status.OK and values['navigation_state'] == 'navigating', message
        _feed(sins, t - 10_000_000_000, 0.5)                        # 10 s back, and it stays there
        _feed(sins, t - 9_500_000_000, 0.3, frame_accel='elsewhere')
        level, message, values = diag.now()
        assert level == ros_status.ERROR, message
        assert 'jumped' in message and 'another frame' in message, message
        assert sins.frame_mismatch['accel'] > 0 and sins.gyro_check.resyncs >= 1
    finally:
        sins.destroy_node()


def test_every_diagnostic_transition_of_sins_node(ros, monkeypatch):
    """
    Check: every diagnostic transition of sins node.

    Each level change of sins_node's status, with every condition listed. OK → WARN (Δv stopped for
    more than accel_wait) → OK (Δv back) → WARN (undecodable) → ERROR (a gyro gap: not masked by
    the undecodable messages, both listed) → ERROR (Δv stalled beyond max(1 s, 10 accel_wait),
    named).
    """
    sins = SinsNode(namespace='/t_diag_all', parameter_overrides=[
        Parameter('accel_rate', value=300.0), Parameter('accel_wait', value=0.1), *IDEAL])
    diag = Diagnostics(sins, monkeypatch)
    try:
        level, message, _ = diag.now()
        assert (level, message) == (ros_status.WARN, 'no gyro increments received')
        t = _feed(sins, 50_000_000_000, 0.5)
        assert diag.now()[:2] == (ros_status.OK, 'ok')
        warn_s, error_s = accel_stall_limits(sins.p['accel_wait'])     # the core's rule
        assert (warn_s, error_s) == (0.1, 1.0)
        t = _feed(sins, t, 0.3, accel=False)                          # Δv stop, Δθ runs on 0.3 s
        level, message, values = diag.now()
        assert level == ros_status.WARN, message
        assert 'accelerometer increments (imu/delta_velocity) stopped' in message
        assert 'WARN beyond 0.1 s, ERROR beyond 1 s' in message
        assert float(values['accel_stall_s']) == pytest.approx(0.3, abs=0.011)
        t = _feed(sins, t, 0.3)                             # Δv back (within max_stamp_jump)
        assert diag.now()[:2] == (ros_status.OK, 'ok')
        for _ in range(3):
            sins.on_gyro_raw(b'\x00\x01garbage')
        level, message, _ = diag.now()
        assert level == ros_status.WARN
        assert message == '3 input message(s) could not be decoded: dropped'
        t = _feed(sins, t, 1.0, skip=range(20, 70))                   # 50 gyro increments missing
        level, message, _ = diag.now()
        assert level == ros_status.ERROR, message
        assert message.startswith('50 gyro increments missing in 1 gaps')
        assert 'could not be decoded' in message
        t = _feed(sins, t, 1.5, accel=False)                          # Δv stalled beyond 1 s
        level, message, values = diag.now()
        assert level == ros_status.ERROR and 'stopped' in message and 'missing' in message
        assert float(values['accel_stall_s']) == pytest.approx(1.5, abs=0.011)
        assert all(len(m) <= ros_status.MAX_TEXT for _, m, _ in diag.got)
    finally:
        sins.destroy_node()


def test_navigation_without_any_accelerometer_data_is_reported(ros, monkeypatch):
    """
    Check: navigation without any accelerometer data is reported.

    With navigation on and no Δv at all, sins/odometry never starts: WARN, then ERROR, naming the
    missing stream.
    """
    sins = SinsNode(namespace='/t_diag_noacc', parameter_overrides=[
        Parameter('navigation', value=True), Parameter('accel_rate', value=300.0), *IDEAL])
    diag = Diagnostics(sins, monkeypatch)
    try:
        t = _feed(sins, 10_000_000_000, 0.5, accel=False)
        level, message, _ = diag.now()
        assert level == ros_status.WARN and 'no accelerometer increments received' in message
        assert 'sins/odometry stalls' in message
        _feed(sins, t, 1.0, accel=False)
        assert diag.now()[0] == ros_status.ERROR
    finally:
        sins.destroy_node()


def test_calibrator_lists_every_condition_at_the_worst_level(ros, monkeypatch):
    """
    Check: calibrator lists every condition at the worst level.

    In calibrator_node, a frame mismatch and undecodable messages are listed beside the WARN of a
    missing solution, and a gyro gap makes it ERROR without hiding them.
    """
    cal = CalibratorNode(namespace='/t_diag_cal', parameter_overrides=list(IDEAL[:4]))
    diag = Diagnostics(cal, monkeypatch)
    try:
        for k in range(1, 21):                  # the gap rule's period: 16 steps of stamps
            cal.on_gyro(_msg(1_000_000_000 + k * 10_000_000, (1e-4, 0.0, 0.0)))
        cal.on_gyro(_msg(1_000_000_000 + 21 * 10_000_000, (1e-4, 0.0, 0.0), frame='camera'))
        cal.on_gyro_raw(b'garbage')
        level, message, _ = diag.now()
        assert level == ros_status.WARN and 'waiting' in message and 'unexpected frame' in message
        assert 'could not be decoded' in message, message
        cal.on_gyro(_msg(1_000_000_000 + 40 * 10_000_000, (1e-4, 0.0, 0.0)))   # 18 missing
        level, message, _ = diag.now()
        assert (level == ros_status.ERROR and 'missing' in message
                and 'could not be decoded' in message)
    finally:
        cal.destroy_node()


def test_runtime_parameters(ros):
    """
    Check: runtime parameters.

    An array parameter set to its current value (rclpy hands back array('d')) is no change, so
    `ros2 param load` of the shipped config/coning.yaml succeeds; coning_algorithm 2.0 is refused
    (no name), as an integer given a fraction is; with navigation on no parameter changes, and the
    message says so; -p numbers that YAML leaves as text (1.0e9) get the range error, and the
    printed velocity update needs 003's layout.
    """
    import yaml
    shipped = pathlib.Path(__file__).resolve().parents[2] / 'config' / 'coning.yaml'
    doc = yaml.safe_load(shipped.read_text())
    block = {**doc['/**']['ros__parameters'], **doc['sins_node']['ros__parameters']}
    sins = SinsNode(namespace='/t_rt',
                    parameter_overrides=[Parameter(k, value=v) for k, v in block.items()])
    try:
        def over_the_wire(name, value):       # what the SetParameters service hands the node
            return Parameter.from_parameter_msg(Parameter(name, value=value).to_parameter_msg())

        # ros2 param load: the file's values arrive again, arrays as array('d')
        same = [over_the_wire(k, v) for k, v in block.items() if sins.has_parameter(k)]
        orientation = next(p for p in same if p.name == 'initial_orientation')
        assert type(orientation.value).__name__ == 'array'
        res = sins.set_parameters(same)
        assert all(r.successful for r in res), [r.reason for r in res]
        for name in ('initial_orientation', 'initial_position', 'gyro_bias'):
            value = over_the_wire(name, list(sins.get_parameter(name).value))
            assert sins.set_parameters([value])[0].successful, name
        res = sins.set_parameters([Parameter('coning_algorithm', value=2.0)])[0]
        assert not res.successful and "'2.0' is not valid" in res.reason
        assert sins.get_parameter('coning_algorithm').value == '2'
    finally:
        sins.destroy_node()
    nav = SinsNode(namespace='/t_rt_nav',
                   parameter_overrides=[Parameter('navigation', value=True), *IDEAL])
    try:
        res = nav.set_parameters([Parameter('coning_algorithm', value='1')])[0]
        assert not res.successful
        assert 'no parameter can change at runtime while navigation is on' in res.reason
        assert 'only coning_algorithm' not in res.reason
        res = nav.set_parameters([Parameter('velocity_update', value='printed')])[0]
        assert not res.successful
    finally:
        nav.destroy_node()
    refused = ros_params.InvalidParameter
    with pytest.raises(refused, match=r'batch_period=1000000000.0 is out of range'):
        SinsNode(namespace='/t_rt_b',
                 parameter_overrides=[Parameter('batch_period', value='1.0e9')])
    with pytest.raises(ros_params.InvalidParameter, match=r'latitude ° in \[-90, 90\]'):
        SinsNode(namespace='/t_rt_lat',
                 parameter_overrides=[Parameter('initial_position', value=[95.0, 0.0, 0.0])])
    with pytest.raises(refused, match=r'initial_velocity\[1\]=1e\+08 is out of range; valid: '):
        SinsNode(namespace='/t_rt_v',
                 parameter_overrides=[Parameter('initial_velocity', value=[0.0, 1e8, 0.0])])
    with pytest.raises(ros_params.InvalidParameter,
                       match='valid: coning_algorithm one of 1, 6, 7'):
        SinsNode(namespace='/t_rt_pr', parameter_overrides=[
            Parameter('navigation', value=True), Parameter('velocity_update', value='printed')])
    ok = SinsNode(namespace='/t_rt_pr_ok', parameter_overrides=[
        Parameter('navigation', value=True), Parameter('velocity_update', value='printed'),
        Parameter('coning_algorithm', value='1'), Parameter('accel_rate', value=300.0)])
    ok.destroy_node()


def test_a_number_given_as_text_is_stored_with_its_type(ros):
    """
    Check: a number given as text is stored with its type.

    A quoted number for a double ("0.05", as YAML files may quote it) or an integer for a double is
    used as the double AND stored as one, so `ros2 param get` shows what the node uses; text that
    is no number is still refused.
    """
    node = SinsNode(namespace='/t_text_num', parameter_overrides=[
        Parameter('batch_period', value='0.05'), Parameter('accel_wait', value=1)])
    try:
        p = node.get_parameter('batch_period')
        assert p.type_ == Parameter.Type.DOUBLE and p.value == 0.05
        assert node.p['batch_period'] == 0.05
        p = node.get_parameter('accel_wait')
        assert p.type_ == Parameter.Type.DOUBLE and p.value == 1.0
        # at run time text is refused with a clear reason (it would stay text otherwise)
        res = node.set_parameters([Parameter('accel_wait', value='0.2')])[0]
        assert not res.successful and 'accel_wait must be set as a number' in res.reason
        assert node.get_parameter('accel_wait').value == 1.0
    finally:
        node.destroy_node()
    with pytest.raises(ros_params.InvalidParameter, match='batch_period must be a number'):
        SinsNode(namespace='/t_text_bad',
                 parameter_overrides=[Parameter('batch_period', value='fast')])
