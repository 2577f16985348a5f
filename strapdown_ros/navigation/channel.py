"""
The navigation channel as ``sins_node`` and ``sins_bag`` run it.

Static alignment or a given attitude, then :class:`~.navigator.Navigator` over the attitude
integrator's updates.

:class:`NavigationChannel` is fed what the node has already validated: compensated gyro
increments, accelerometer increments (both stamped, seconds relative to the stamp origin) and,
once it is aligned, the attitude updates.  It owns the alignment state and tells its owner the
attitude to start the integrator from.  No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from strapdown_ros.earth import enu_rotation, geodetic_to_ecef
from strapdown_ros.navigation.alignment import AlignmentResult, static_alignment
from strapdown_ros.navigation.covariance import NavigationCovariance
from strapdown_ros.navigation.navigator import NavigationBatch, Navigator
from strapdown_ros.sensors.model import SensorSigmas

__all__ = ['NavigationChannel', 'NavigationSettings', 'ALIGNMENT_MODES', 'VELOCITY_UPDATES']

ALIGNMENT_MODES = ('given', 'static')
VELOCITY_UPDATES = ('derived', 'printed')


def _spread(xs) -> float:
    """Return the RMS deviation of vectors from their mean."""
    return float(np.sqrt(np.mean(np.sum((np.array(xs) - np.mean(xs, 0)) ** 2, 1))))


@dataclass(frozen=True)
class NavigationSettings:
    """
    The settings of the navigation channel (the names of ``sins_node``'s parameters).

    Attributes
    ----------
    initial_position : tuple of float
        Latitude °, longitude °, height m (PZ-90).
    initial_velocity : tuple of float
        East, north, up m/s at that point.
    initial_position_sigma, initial_velocity_sigma : float
        1σ per axis, m and m/s.
    initial_alignment : str
        ``given`` or ``static``.
    alignment_time : float
        Static alignment window, s.
    velocity_update : str
        ``derived`` or ``printed``.
    sculling_compensation : bool
        Rotation and sculling from the fitted motion (false: rotation only).
    gravity_model : str
        Normal gravity model.
    navigation_covariance_period : float
        Propagation period of the covariance, s.

    """

    initial_position: tuple = (50.45, 30.52, 150.0)
    initial_velocity: tuple = (0.0, 0.0, 0.0)
    initial_position_sigma: float = 0.0
    initial_velocity_sigma: float = 0.0
    initial_alignment: str = 'given'
    alignment_time: float = 60.0
    velocity_update: str = 'derived'
    sculling_compensation: bool = True
    gravity_model: str = 'pz90_003'
    navigation_covariance_period: float = 1.0

    @classmethod
    def from_values(cls, values) -> NavigationSettings:
        """
        Build the settings from parameter values (other names are not read).

        Parameters
        ----------
        values : mapping
            Parameter name → value (defaults where absent).

        Returns
        -------
        NavigationSettings
            The settings.

        """
        out = {f.name: values[f.name] for f in fields(cls) if f.name in values}
        for k in ('initial_position', 'initial_velocity'):
            if k in out:
                out[k] = tuple(float(x) for x in out[k])
        return cls(**out)


class NavigationChannel:
    """
    Alignment and navigation over validated sensor data, with the state a node reports.

    Parameters
    ----------
    p : NavigationSettings
        Where it starts, how it aligns and which update it runs.
    gyro, accel : SensorSigmas
        Statistics of the sensor errors.
    gyro_period, accel_period : float
        Sample intervals, s.
    samples_per_update : int
        Gyro increments per attitude update (the coning algorithm's samples).

    Raises
    ------
    ValueError
        For an unknown alignment mode or velocity update.

    """

    def __init__(self, p: NavigationSettings, gyro: SensorSigmas, accel: SensorSigmas,
                 gyro_period: float,
                 accel_period: float, samples_per_update: int):
        lat, lon, h = (float(x) for x in p.initial_position)
        self.position0 = geodetic_to_ecef(np.radians(lat), np.radians(lon), h)
        self.enu = enu_rotation(np.radians(lat), np.radians(lon))
        self.velocity0 = self.enu @ np.asarray(p.initial_velocity, dtype=float)
        self.p, self.gyro_sig, self.accel_sig = p, gyro, accel
        self.gyro_period, self.accel_period = float(gyro_period), float(accel_period)
        self.samples = int(samples_per_update)
        self.mode = p.initial_alignment
        if self.mode not in ALIGNMENT_MODES:
            raise ValueError(f'initial_alignment must be one of {ALIGNMENT_MODES}, '
                             f'got {self.mode!r}')
        if p.velocity_update not in VELOCITY_UPDATES:
            raise ValueError(f'velocity_update must be one of {VELOCITY_UPDATES}')
        self.navigator: Navigator | None = None
        self.alignment: AlignmentResult | None = None
        self.refusals = 0
        self._early_accel: list = []       # accelerometer data that arrive before the start
        self._reset_alignment()

    # --- alignment ------------------------------------------------------------------------------
    def _reset_alignment(self):
        self._al = {'t0': None, 't1': None, 'g': np.zeros(3), 'a': np.zeros(3), 'ga': [], 'aa': []}

    @property
    def aligning(self) -> bool:
        """
        Tell whether the channel is collecting data for a static alignment.

        Returns
        -------
        bool
            True in ``static`` mode before the navigator starts.

        """
        return self.navigator is None and self.mode == 'static'

    def align_gyro(self, inc: np.ndarray, t: np.ndarray) -> None:
        """
        Add gyro increments to the alignment window.

        Parameters
        ----------
        inc : (n, 3) ndarray
            Compensated increments, body axes, rad.
        t : (n,) ndarray
            Their end stamps, s.

        """
        al = self._al
        if al['t0'] is None and len(t):
            al['t0'] = float(t[0]) - self.gyro_period
        al['g'] += inc.sum(0)
        al['t1'] = float(t[-1]) if len(t) else al['t1']
        al['ga'].append(inc.sum(0) / max(len(t), 1) / self.gyro_period)

    def align_accel(self, inc: np.ndarray, t: np.ndarray) -> None:
        """
        Add accelerometer increments to the alignment window.

        Parameters
        ----------
        inc : (n, 3) ndarray
            Compensated increments, body axes, m/s.
        t : (n,) ndarray
            Their end stamps, s.

        """
        self._al['aa'].append((inc, t))             # selected by the gyro window in try_align

    def try_align(self) -> tuple[bool, np.ndarray | None, float | None]:
        """
        Align when the alignment window is full, and start the navigator.

        A refusal is counted, kept in :attr:`alignment` with its reason, and the window starts
        again.

        Returns
        -------
        tuple
            ``(done, C_E_B (3, 3), start time s)``; ``(False, None, None)`` while the window is
            not full or after a refusal.

        """
        al = self._al
        if al['t0'] is None or al['t1'] is None:
            return False, None, None
        span = al['t1'] - al['t0']
        if span < float(self.p.alignment_time):
            return False, None, None
        if al['aa']:
            inc = np.concatenate([a[0] for a in al['aa']])
            t = np.concatenate([a[1] for a in al['aa']])
            sel = (t > al['t0'] + 1e-9) & (t <= al['t1'] + 1e-9)
            al['a'] = inc[sel].sum(0)
            # per-0.1 s means for the static test
            chunks = max(1, int(sel.sum() * self.accel_period / 0.1))
            al['aa'] = [c.sum(0) / (len(c) * self.accel_period)
                        for c in np.array_split(inc[sel], chunks) if len(c)]
        res = static_alignment(al['a'] / span, al['g'] / span, self.position0, span, self.gyro_sig,
                               self.accel_sig,
                               f_spread=_spread(al['aa']) if len(al['aa']) > 1 else None,
                               w_spread=None, sample_period=0.1,
                               gravity_model=self.p.gravity_model)
        self.alignment = res
        t_end = al['t1']
        self._reset_alignment()
        if not res.ok:
            self.refusals += 1
            return False, None, None
        self.start(t_end, res.attitude, res.covariance)
        return True, res.attitude, t_end

    # --- navigation ---------------------------------------------------------------------------
    def start(self, t0: float, attitude_e_b: np.ndarray | None = None,
              attitude_cov: np.ndarray | None = None, attitude_sigma: float = 0.0) -> None:
        """
        Start the navigator at a time, from the initial position and velocity.

        Parameters
        ----------
        t0 : float
            Start of the attitude integrator, s.
        attitude_e_b : (3, 3) ndarray or None
            Initial C_E_B (unused here: the owner starts the integrator from it).
        attitude_cov : (3, 3) ndarray or None
            Covariance of ψ, E axes, rad²; None: ``attitude_sigma``² I.
        attitude_sigma : float
            1σ of the initial attitude per axis, rad.

        """
        p = self.p
        p0 = np.zeros((9, 9))
        p0[0:3, 0:3] = float(p.initial_position_sigma) ** 2 * np.eye(3)
        p0[3:6, 3:6] = float(p.initial_velocity_sigma) ** 2 * np.eye(3)
        p0[6:9, 6:9] = (attitude_cov if attitude_cov is not None
                        else attitude_sigma ** 2 * np.eye(3))
        derived = p.velocity_update == 'derived'
        if derived:
            form = 'exact' if p.sculling_compensation else 'rotation_only'
        else:
            form = 'printed'
        accel_per_step = max(1, int(round(self.samples * self.gyro_period / self.accel_period)))
        covariance = NavigationCovariance(self.gyro_sig, self.accel_sig, p0,
                                          float(p.navigation_covariance_period))
        self.navigator = Navigator(
            self.position0, self.velocity0, t0, self.samples, accel_per_step,
            self.gyro_period, self.accel_period, form=form,
            scheme='exact' if derived else 'printed', gravity_model=p.gravity_model,
            covariance=covariance)
        for inc, t in self._early_accel:            # the steps' fits may reach back before t0
            keep = t > t0 - 1.0
            self.navigator.add_accel(inc[keep], t[keep])
        self._early_accel.clear()

    def add_gyro(self, inc, t) -> None:
        """
        Feed gyro increments to the navigator, once it runs.

        Parameters
        ----------
        inc : (n, 3) array_like
            Compensated increments, body axes, rad.
        t : (n,) array_like
            Their end stamps, s.

        """
        if self.navigator is not None:
            self.navigator.add_gyro(inc, t)

    def add_accel(self, inc, t) -> None:
        """
        Feed accelerometer increments to the navigator, or keep them until it starts.

        Parameters
        ----------
        inc : (n, 3) array_like
            Compensated increments, body axes, m/s.
        t : (n,) array_like
            Their end stamps, s.

        """
        inc = np.asarray(inc, dtype=float).reshape(-1, 3)
        t = np.asarray(t, dtype=float).reshape(-1)
        if self.navigator is not None:
            self.navigator.add_accel(inc, t)
            return
        if self.aligning:
            self.align_accel(inc, t)
        # kept (bounded: the last 2 s) until the navigator starts: the first step needs them
        self._early_accel.append((inc, t))
        newest = t[-1] if len(t) else -np.inf
        early = self._early_accel
        while early and len(early[0][1]) and early[0][1][-1] < newest - 2.0:
            early.pop(0)

    def add_updates(self, stamps, intervals, attitude_end, attitude_start) -> None:
        """
        Queue attitude updates for the navigator (:meth:`.navigator.Navigator.add_updates`).

        Parameters
        ----------
        stamps : (M,) array_like
            End stamps of the updates, s.
        intervals : (M,) array_like
            Their lengths, s.
        attitude_end, attitude_start : (M, 4) array_like
            q_I_B at their ends and at their starts, scalar first.

        """
        if self.navigator is not None:
            self.navigator.add_updates(stamps, intervals, attitude_end, attitude_start)

    def process(self, newest: float, wait: float) -> NavigationBatch | None:
        """
        Navigate the queued steps that are ready (:meth:`.navigator.Navigator.process`).

        Parameters
        ----------
        newest : float
            Newest stamp the owner has seen, s.
        wait : float
            How long a step waits for its accelerometer data, s.

        Returns
        -------
        NavigationBatch or None
            The navigated steps; None before the navigator starts.

        """
        if self.navigator is None:
            return None
        return self.navigator.process(newest, wait)

    def status(self) -> dict:
        """
        Return the channel's state for the node's status message.

        Returns
        -------
        dict
            ``navigation_state``, ``alignment_refusals``, the alignment's outcome and the
            navigator's step counts when there are any.

        """
        if self.aligning:
            state = 'aligning'
        else:
            state = 'navigating' if self.navigator else 'waiting'
        d = {'navigation_state': state, 'alignment_refusals': self.refusals}
        if self.alignment is not None:
            d['alignment'] = self.alignment.reason
            if self.alignment.ok:
                d['alignment_tilt_sigma_rad'] = self.alignment.tilt_sigma
                d['alignment_heading_sigma_rad'] = self.alignment.heading_sigma
        if self.navigator is not None:
            d['navigation_steps'] = self.navigator.steps
            d['navigation_steps_accel_extrapolated'] = self.navigator.extrapolated_steps
        return d
