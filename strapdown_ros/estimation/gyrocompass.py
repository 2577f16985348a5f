"""
Vavilov 1982 (paper 001): the gyro-horizon-compass error model and the Doppler-log measurement.

Their observability, as a linear time-varying system in the paper's dimensionless variables;
:mod:`strapdown_ros.reproductions.vavilov1982` reproduces the paper with it.

Variables (001 §2, §3).  Time τ = ω0·t with the Schuler frequency ω0 = √(g/R).
    x = (α1, α2, μ ω2 α3, Δω2/ω0)   vertical errors α1, α2 [rad], azimuth error α3 scaled by
                                    μω2, error of the gyrocompass's own velocity signal ω2'
                                    [÷ω0];
    z                               latitude error: sin φ = sin φ_computed + μ1 z;
    Δ                               tilt of the total angular momentum above the instrument
                                    horizon [rad], constant on the interval (eq. 2.1).
Parameters: μ = u/ω0 (u Earth rate), μ1 = V0/(R u) (V0 the characteristic relative speed),
λ = ω3⁰/ω0.  Kinematics of the Darboux trihedron Mx (x1 along the absolute velocity, x3 up):
ω2 = |v|/(R u) (dimensionless absolute speed, 001's ``v``), λω3 = (turn rate of x1 about the
vertical)/ω0, V1, V2 the relative velocity along x1, x2 in units of V0.

Equations implemented (numbers are 001's):
    (2.9)  ẋ = B x + b Δ,  B = B1 + λω3 B2,  b = (−ω̇2/ω2, −λω3, 0, 0)
    (3.4)  ż = h2ᵀ x,     h2 = (0, 0, V1, −V2)
    (3.7)  σ = h1ᵀ x − μ μ1 sin φ · z,   h1 = (0, 0, −μ1 V2, ω2 − μ1 V1)
    (4.2)  y = G1 x,  G_i = [h_i, B1ᵀh_i, −B2ᵀh_i, B2ᵀB1ᵀh_i]ᵀ
    (4.6)  ship:       ẏ = (B2 + c B1) y + c b1 Δ, σ = y1        (c = μ sin φ)
    (4.8)  aircraft:   ṡ = D s, σ = s1
    (4.11) ship circulation: (y1, y2, p1, p2) with p1 = d2Δ, p2 = d4Δ (time τ1 = Ωt)

Misprints found and corrected (derivations in doc/results/reproductions/observability_001.md):
    * (2.1) ΔM3 = −ω2Δ is dimensionally wrong; (2.8) Δω1 = −(ω̇2/ω2)Δ requires ΔM3 = −ω̇2Δ.
    * (3.2) prefactor 0.5μ1 → 0.5μ; (3.5) lacks that factor μ; (3.3) coefficient μ1μ1 → μμ1
      (all checked against the exact nonlinear measurement by :func:`exact_measurement`).
    * (4.7)–(4.8) hold for μ1 = 1 only (rows 1–3 of D to O(c²)); rows 4–5 of D omit O(c)
      terms c(y1 + (1+μ1)z3), which reach σ only at O(c²).  (4.1), (4.3), (4.4), (4.10) agree
      with the exact geometry as printed.

No ROS imports; numpy only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ['EARTH_RATE', 'EARTH_RADIUS', 'GRAVITY', 'SCHULER_RATE', 'B1', 'B2', 'Parameters',
           'SmallCircleMotion', 'orthodrome', 'circulation', 'error_matrices',
           'measurement_vectors', 'full_system', 'transform', 'ship_system', 'aircraft_matrix',
           'circulation_ship_system', 'exact_measurement', 'linear_measurement', 'STATE_LABELS']

EARTH_RATE = 7.292115e-5            # u [rad/s]
EARTH_RADIUS = 6.371e6              # R, the paper's Earth sphere [m]
GRAVITY = 9.81                      # g [m/s²]
SCHULER_RATE = np.sqrt(GRAVITY / EARTH_RADIUS)     # ω0 [rad/s]

STATE_LABELS = ('x1=α1', 'x2=α2', 'x3=μω2α3', 'x4=Δω2', 'z', 'Δ')

# 001 §2, the matrices of (2.9)
B1 = np.array([[0, 0, -1, 0], [0, 0, 0, 1], [1, 0, 0, 0], [0, -1, 0, 0]], float)
B2 = np.array([[0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, -1], [0, 0, 1, 0]], float)


@dataclass(frozen=True)
class Parameters:
    """
    Dimensionless parameters of 001 from the physical ones.

    Parameters
    ----------
    speed : float
        V0, the characteristic relative speed, m/s.
    earth_rate : float
        u, rad/s.
    radius : float
        R, the paper's Earth sphere, m.
    gravity : float
        g, m/s².

    """

    speed: float
    earth_rate: float = EARTH_RATE
    radius: float = EARTH_RADIUS
    gravity: float = GRAVITY

    @property
    def schuler_rate(self) -> float:
        """Return the Schuler frequency ω0 = √(g/R), rad/s."""
        return float(np.sqrt(self.gravity / self.radius))

    @property
    def mu(self) -> float:
        """Return μ = u/ω0."""
        return self.earth_rate / self.schuler_rate

    @property
    def mu1(self) -> float:
        """Return μ1 = V0/(R u)."""
        return self.speed / (self.radius * self.earth_rate)


class SmallCircleMotion:
    """
    Uniform motion along a circle on the rotating Earth sphere, exact kinematics.

    Earth-fixed unit position p(t) = cos a·c + sin a (cos θ e1 + sin θ e2), θ = θ0 + θ̇ t,
    about the circle's centre c (a = π/2: a great circle, 001's orthodrome §4.1; a ≪ 1: a
    circulation §4.2).  Relative speed V = R sin a |θ̇|.  :meth:`kinematics` returns the
    quantities 001's matrices need, computed from the geometry (not from 001's (4.1)/(4.9),
    which they check).

    Parameters
    ----------
    centre : array_like (3,)
        Centre c of the circle, Earth axes (normalised here).
    e1 : array_like (3,)
        Direction of θ = 0 (made orthogonal to c).
    angular_radius : float
        a, rad.
    rate : float
        θ̇, rad/s.
    phase : float
        θ0, rad.
    params : Parameters
        The physical parameters.

    """

    def __init__(self, centre, e1, angular_radius: float, rate: float, phase: float,
                 params: Parameters):
        self.c = np.asarray(centre, float) / np.linalg.norm(centre)
        e1 = np.asarray(e1, float) - np.dot(e1, self.c) * self.c
        self.e1 = e1 / np.linalg.norm(e1)
        self.e2 = np.cross(self.c, self.e1)
        self.a, self.rate, self.phase, self.p = angular_radius, rate, phase, params

    def kinematics(self, tau: float) -> dict:
        """
        Return the kinematics of the Darboux trihedron at a dimensionless time.

        Parameters
        ----------
        tau : float
            τ = ω0 t.

        Returns
        -------
        dict
            ``omega2`` (001's v), ``lam_omega3`` (λω3), ``omega2_rate_ratio`` (ω̇2/ω2 per τ),
            ``V1``, ``V2`` (units V0), ``sin_lat``.

        """
        P = self.p
        t = tau / P.schuler_rate
        th = self.phase + self.rate * t
        sa, ca = np.sin(self.a), np.cos(self.a)
        pos = ca * self.c + sa * (np.cos(th) * self.e1 + np.sin(th) * self.e2)
        vel = sa * self.rate * (-np.sin(th) * self.e1 + np.cos(th) * self.e2)     # ṗ [1/s]
        acc = -sa * self.rate ** 2 * (np.cos(th) * self.e1 + np.sin(th) * self.e2)  # p̈
        k = np.array([0.0, 0.0, 1.0])
        u, R = P.earth_rate, P.radius
        v_abs = R * (vel + u * np.cross(k, pos))          # inertial velocity, Earth axes
        a_abs = R * (acc + u * np.cross(k, vel)) + u * np.cross(k, v_abs)   # its derivative
        speed = np.linalg.norm(v_abs)
        x1 = v_abs / speed
        x3 = pos
        x2 = np.cross(x3, x1)
        x1_dot = (a_abs - np.dot(a_abs, x1) * x1) / speed
        rel = R * vel
        return {'omega2': speed / (R * u),                                  # 001's ω2 = v
                'lam_omega3': float(np.dot(x1_dot, x2)) / P.schuler_rate,   # λω3
                # ω̇2/ω2 per unit τ
                'omega2_rate_ratio': float(np.dot(a_abs, x1)) / speed / P.schuler_rate,
                'V1': float(np.dot(rel, x1)) / P.speed, 'V2': float(np.dot(rel, x2)) / P.speed,
                'sin_lat': float(pos[2])}


def orthodrome(params: Parameters, inclination: float, polar_angle0: float = 0.0,
               eastward: bool = True) -> SmallCircleMotion:
    """
    Return 001 §4.1's motion: uniform, on the great circle through Oξ1 inclined ϑ to the equator.

    The polar angle ψ in the great-circle plane is measured from Oξ1; latitude
    sin φ = sin ψ sin ϑ.

    Parameters
    ----------
    params : Parameters
        The physical parameters (speed V0).
    inclination : float
        ϑ, rad.
    polar_angle0 : float
        ψ at t = 0, rad.
    eastward : bool
        Direction of motion.

    Returns
    -------
    SmallCircleMotion
        The motion.

    """
    c = np.array([0.0, -np.sin(inclination), np.cos(inclination)])     # pole of the plane
    rate = params.speed / params.radius * (1 if eastward else -1)
    return SmallCircleMotion(c, [1.0, 0.0, 0.0], np.pi / 2, rate, polar_angle0, params)


def circulation(params: Parameters, latitude: float, period: float,
                phase0: float = 0.0) -> SmallCircleMotion:
    """
    Return 001 §4.2's motion: circulation at constant speed with a period, about a latitude.

    Counter-clockwise seen from above (θ from east towards north); angular radius
    V·period/(2πR).

    Parameters
    ----------
    params : Parameters
        The physical parameters (speed V0).
    latitude : float
        Latitude of the centre, rad.
    period : float
        Period of one circle, s.
    phase0 : float
        θ at t = 0, rad.

    Returns
    -------
    SmallCircleMotion
        The motion.

    """
    c = np.array([np.cos(latitude), 0.0, np.sin(latitude)])
    east = np.array([0.0, 1.0, 0.0])
    rate = 2 * np.pi / period
    a = float(np.arcsin(params.speed / (params.radius * rate)))
    return SmallCircleMotion(c, east, a, rate, phase0, params)


# --------------------------------------------------------------------------------- matrices
def error_matrices(lam_omega3: float, omega2_rate_ratio: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return (2.9)'s B = B1 + λω3 B2 and b = (−ω̇2/ω2, −λω3, 0, 0).

    Parameters
    ----------
    lam_omega3 : float
        λω3.
    omega2_rate_ratio : float
        ω̇2/ω2 per unit τ.

    Returns
    -------
    B : ndarray (4, 4)
        The error dynamics.
    b : ndarray (4,)
        The column of Δ.

    """
    return B1 + lam_omega3 * B2, np.array([-omega2_rate_ratio, -lam_omega3, 0.0, 0.0])


def measurement_vectors(V1: float, V2: float, omega2: float,
                        mu1: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return (3.5)–(3.6)'s h1 = (0, 0, −μ1V2, v − μ1V1) and h2 = (0, 0, V1, −V2), v = ω2.

    Parameters
    ----------
    V1, V2 : float
        Relative velocity along x1, x2, units V0.
    omega2 : float
        ω2 = v, the dimensionless absolute speed.
    mu1 : float
        μ1.

    Returns
    -------
    h1, h2 : ndarray (4,)
        The measurement and latitude-error vectors.

    """
    return np.array([0.0, 0.0, -mu1 * V2, omega2 - mu1 * V1]), np.array([0.0, 0.0, V1, -V2])


def full_system(motion: SmallCircleMotion):
    """
    Return (3.6)–(3.7) as the LTV system of the state (x1..x4, z, Δ).

    Parameters
    ----------
    motion : SmallCircleMotion
        The motion.

    Returns
    -------
    F : callable
        F(τ), the (6, 6) system matrix.
    H : callable
        H(τ), the (1, 6) measurement row.

    """
    P = motion.p
    mu, mu1 = P.mu, P.mu1

    def F(tau):
        k = motion.kinematics(tau)
        B, b = error_matrices(k['lam_omega3'], k['omega2_rate_ratio'])
        _, h2 = measurement_vectors(k['V1'], k['V2'], k['omega2'], mu1)
        out = np.zeros((6, 6))
        out[:4, :4] = B
        out[:4, 5] = b
        out[4, :4] = h2
        return out

    def H(tau):
        k = motion.kinematics(tau)
        h1, _ = measurement_vectors(k['V1'], k['V2'], k['omega2'], mu1)
        return np.concatenate([h1, [-mu * mu1 * k['sin_lat'], 0.0]])[None, :]

    return F, H


def transform(h: np.ndarray) -> np.ndarray:
    """
    Return (4.2)'s G = [h, B1ᵀh, −B2ᵀh, B2ᵀB1ᵀh]ᵀ.

    So y = G x has y1 = hᵀx, y2 = hᵀB1x, y3 = −hᵀB2x, y4 = hᵀB1B2x.

    Parameters
    ----------
    h : array_like (4,)
        A measurement vector.

    Returns
    -------
    ndarray (4, 4)
        G.

    """
    h = np.asarray(h, float)
    return np.vstack([h, B1.T @ h, -B2.T @ h, B2.T @ B1.T @ h])


def ship_system(c: float, b1_2: float, b1_4: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """
    Return (4.6)'s ship system: state (y1, y2, y3, y4, Δ), ẏ = (B2 + c B1) y + c b1 Δ, σ = y1.

    b1 = (0, b1_2, 0, b1_4) with (4.4) b1_2 = v − μ1²V²/v, b1_4 = 2μ1V2 (→ 0 for the ship).

    Parameters
    ----------
    c : float
        μ sin φ.
    b1_2, b1_4 : float
        The components of b1.

    Returns
    -------
    A : ndarray (5, 5)
        System matrix.
    H : ndarray (1, 5)
        Measurement row.

    """
    A = np.zeros((5, 5))
    A[:4, :4] = B2 + c * B1
    A[:4, 4] = c * np.array([0.0, b1_2, 0.0, b1_4])
    H = np.array([[1.0, 0, 0, 0, 0]])
    return A, H


def aircraft_matrix(c: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return (4.8)'s aircraft system: ṡ = D s, σ = s1 for the combinations s1..s5 of (4.7).

    Parameters
    ----------
    c : float
        μ sin φ.

    Returns
    -------
    D : ndarray (5, 5)
        System matrix.
    H : ndarray (1, 5)
        Measurement row.

    """
    D = np.array([[0, 1, 0, c, 0], [0, 0, 1, 0, 0], [0, -1, 0, 2 * c, 0],
                  [0, 0, 0, 0, -1], [0, 0, 0, 1, 0]], float)
    return D, np.array([[1.0, 0, 0, 0, 0]])


def circulation_ship_system(lam1: float, mu1: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return (4.11)'s ship circulation system, time τ1 = Ωt.

    y1' = λ1y2, y2' = −λ1y1 + μ1p1, p1' = −p2, p2' = p1, σ = y1; state order (y1, y2, p1, p2).

    Parameters
    ----------
    lam1 : float
        λ1.
    mu1 : float
        μ1.

    Returns
    -------
    A : ndarray (4, 4)
        System matrix.
    H : ndarray (1, 4)
        Measurement row.

    """
    A = np.array([[0, lam1, 0, 0], [-lam1, 0, mu1, 0], [0, 0, 0, -1], [0, 0, 1, 0]], float)
    return A, np.array([[1.0, 0, 0, 0]])


# ------------------------------------------------------------------ the measurement, exactly
def exact_measurement(mu: float, mu1: float, V1: float, V2: float, omega2_true: float,
                      alpha3: float, d_omega2: float, sin_lat_true: float, z: float) -> float:
    """
    Compute 001's σ from erroneous signals, without linearisation (checks (3.1)–(3.7)).

    The log gives V in the compass frame Mz, turned by α3 from Mx; the compass signal is
    ω2' = ω2 + Δω2 (units u; Δω2 = x4/μ); the computed latitude is sin φ − μ1 z.
    σ = ½μ[μ1²V² + sin²φ_c − 1 + ω2'² − 2μ1ω2'V1']  (our corrected (3.5)).

    Parameters
    ----------
    mu, mu1 : float
        μ and μ1.
    V1, V2 : float
        True relative velocity along x1, x2, units V0.
    omega2_true : float
        True ω2.
    alpha3 : float
        Azimuth error, rad.
    d_omega2 : float
        Error of the compass's velocity signal, units u.
    sin_lat_true : float
        sin φ, true.
    z : float
        Latitude error.

    Returns
    -------
    float
        σ.

    """
    # components along Mz (small rotation by α3 about the vertical, V_z = (E + α̂)V_x)
    V1z = V1 + alpha3 * V2
    V2z = V2 - alpha3 * V1
    w2 = omega2_true + d_omega2
    s_c = sin_lat_true - mu1 * z
    return 0.5 * mu * (mu1 ** 2 * (V1z ** 2 + V2z ** 2) + s_c ** 2 - 1 + w2 ** 2
                       - 2 * mu1 * w2 * V1z)


def linear_measurement(mu: float, mu1: float, V1: float, V2: float, omega2: float,
                       alpha3: float, d_omega2: float, sin_lat: float, z: float) -> float:
    """
    Compute (3.7)'s σ = h1ᵀx − μμ1 sin φ z with x3 = μω2α3, x4 = μΔω2.

    Parameters
    ----------
    mu, mu1 : float
        μ and μ1.
    V1, V2 : float
        Relative velocity along x1, x2, units V0.
    omega2 : float
        ω2.
    alpha3 : float
        Azimuth error, rad.
    d_omega2 : float
        Δω2, units u.
    sin_lat : float
        sin φ.
    z : float
        Latitude error.

    Returns
    -------
    float
        σ, linearised.

    """
    h1, _ = measurement_vectors(V1, V2, omega2, mu1)
    x = np.array([0.0, 0.0, mu * omega2 * alpha3, mu * d_omega2])
    return float(h1 @ x - mu * mu1 * sin_lat * z)
