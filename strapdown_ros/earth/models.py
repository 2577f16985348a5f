"""
The gravity models of the package by name, and their comparison.

:data:`GRAVITY_MODELS` maps the parameter ``gravity_model`` to a vectorised function and
:data:`SCALAR_GRAVITY` to the scalar form the navigation loop compiles;
:func:`compare_models` and :func:`report` give the numbers of doc/navigation_gravity.md.
"""
import numpy as np

from strapdown_ros.earth.ellipsoid import (A, E2_003, ETA_003, GE, geodetic_to_ecef, GM, J2,
                                           OMEGA, WGS84)
from strapdown_ros.earth.normal_field import (j2_gravity, level_ellipsoid_j2, normal_exact_xyz,
                                              normal_gravity_exact, somigliana)
from strapdown_ros.earth.printed_formula import (printed_gravity, printed_gravity_xyz,
                                                 PRINTED_VARIANTS)

#: the default normal-gravity model of the whole package (core functions, node and tool
#: parameters): the exact normal gravity of the level ellipsoid; "pz90_003" (003's formula,
#: corrected) stays selectable by name
DEFAULT_GRAVITY_MODEL = 'normal_exact'

GRAVITY_MODELS = {'pz90_003': printed_gravity, 'normal_exact': normal_gravity_exact,
                  'j2': j2_gravity}
#: scalar forms of the models (numba-compilable) that the navigation loop can run compiled
SCALAR_GRAVITY = {'pz90_003': printed_gravity_xyz, 'normal_exact': normal_exact_xyz}


def get_gravity_model(name):
    """
    Return the vectorised gravity function registered under ``name``.

    Parameters
    ----------
    name : str
        A key of :data:`GRAVITY_MODELS`.

    Returns
    -------
    callable
        r (..., 3) ECEF, m → g (..., 3) ECEF, m/s².

    Raises
    ------
    ValueError
        For an unknown name, listing the valid ones.

    """
    try:
        return GRAVITY_MODELS[name]
    except KeyError:
        raise ValueError(
            f'unknown gravity model {name!r}; valid: {sorted(GRAVITY_MODELS)}') from None


def normal_gravity(r, model=DEFAULT_GRAVITY_MODEL):
    """
    Return the ECEF gravity vector (gravitation + centrifugal) at ECEF positions.

    Parameters
    ----------
    r : array_like (..., 3)
        ECEF positions, m.
    model : str
        A key of :data:`GRAVITY_MODELS`.

    Returns
    -------
    ndarray (..., 3)
        Gravity, m/s², ECEF axes.

    """
    return get_gravity_model(model)(np.asarray(r, dtype=np.float64))


# --- comparison -------------------------------------------------------------------------
def _angle_arcsec(g1, g2):
    cr = np.linalg.norm(np.cross(g1, g2), axis=-1)
    return np.degrees(np.arctan2(cr, np.sum(g1 * g2, axis=-1))) * 3600.0


def compare_models(test='pz90_003', reference='normal_exact', heights=(0.0, 1e3, 1e4, 2e4, 1e5),
                   lat_step_deg=5.0, lon_deg=(0.0, 37.0, 143.0, -100.0)):
    """
    Return the differences of ``test`` against ``reference`` on a geodetic grid, per height.

    Parameters
    ----------
    test, reference : str or callable
        Registry names or callables r (..., 3) → g (..., 3).
    heights : sequence of float
        Heights above the ellipsoid, m.
    lat_step_deg : float
        Latitude step of the grid, degrees.
    lon_deg : sequence of float
        Longitudes of the grid, degrees.

    Returns
    -------
    dict
        {h: {"max_mag", "rms_mag" (m/s²), "max_mag_mgal", "rms_mag_mgal", "max_dir_arcsec",
        "rms_dir_arcsec", "worst_lat_deg"}}.

    """
    ft = get_gravity_model(test) if isinstance(test, str) else test
    fr = get_gravity_model(reference) if isinstance(reference, str) else reference
    lat = np.radians(np.arange(-90.0, 90.0 + 1e-9, lat_step_deg))
    lon = np.radians(np.asarray(lon_deg, dtype=np.float64))
    out = {}
    for h in heights:
        la, lo = np.meshgrid(lat, lon, indexing='ij')
        r = geodetic_to_ecef(la, lo, h)
        gt, gr = ft(r), fr(r)
        dm = np.linalg.norm(gt, axis=-1) - np.linalg.norm(gr, axis=-1)
        da = _angle_arcsec(gt, gr)
        out[float(h)] = {
            'max_mag': float(np.max(np.abs(dm))), 'rms_mag': float(np.sqrt(np.mean(dm ** 2))),
            'max_mag_mgal': float(np.max(np.abs(dm))) * 1e5,
            'rms_mag_mgal': float(np.sqrt(np.mean(dm ** 2))) * 1e5,
            'max_dir_arcsec': float(np.max(da)),
            'rms_dir_arcsec': float(np.sqrt(np.mean(da ** 2))),
            'worst_lat_deg': float(np.degrees(la.ravel()[np.argmax(np.abs(dm).ravel())])),
        }
    return out


def report(heights=(0.0, 1e3, 1e4, 2e4, 1e5)):
    """
    Return the Markdown tables of :func:`compare_models` (quoted in doc/navigation_gravity.md).

    Parameters
    ----------
    heights : sequence of float
        Heights above the ellipsoid, m.

    Returns
    -------
    str
        The constants, the model comparisons and the printed-formula variants.

    """
    ge_pz, gp_pz = float(somigliana(0.0)), float(somigliana(np.pi / 2))
    ge_w, gp_w = float(somigliana(0.0, WGS84)), float(somigliana(np.pi / 2, WGS84))
    c0, c1 = GE * (1 - 0.5 * E2_003 + 1.5 * ETA_003), GE * (E2_003 - ETA_003)
    lines = ['### Constants', '',
             f'* Somigliana PZ-90.11: γ_e = {ge_pz:.10f}, γ_p = {gp_pz:.10f} m/s² '
             f'(003 g_e = {GE}); WGS-84: γ_e = {ge_w:.10f}, γ_p = {gp_w:.10f}',
             f'* J2 of the PZ-90.11 level ellipsoid = {level_ellipsoid_j2():.10e} '
             f'(published {J2:.10e})',
             f'* η = aΩ²/g_e = {A * OMEGA ** 2 / GE:.10f} (003 prints {ETA_003})',
             f'* first-order coefficients: g_e(1 − ½e² + 3/2η) = {c0:.6f} '
             f'vs GM/a² = {GM / A ** 2:.6f}; '
             f'g_e(e² − η) = {c1:.6f} vs 3·J2·GM/a² = {3 * J2 * GM / A ** 2:.6f} m/s²', '']
    head = '| h, km | max abs Δ‖g‖, mGal | RMS Δ‖g‖, mGal | max angle, ″ | RMS angle, ″ |'
    for test, ref in (('pz90_003', 'normal_exact'), ('j2', 'normal_exact'), ('pz90_003', 'j2')):
        lines += [f'### {test} vs {ref}', '', head, '|---|---|---|---|---|']
        for h, d in compare_models(test, ref, heights).items():
            lines.append(f"| {h / 1e3:g} | {d['max_mag_mgal']:.3g} | {d['rms_mag_mgal']:.3g} | "
                         f"{d['max_dir_arcsec']:.3g} | {d['rms_dir_arcsec']:.3g} |")
        lines.append('')
    lines += ['### Printed-formula variants vs normal_exact, h = 0 … 20 km (worst over heights)',
              '', '| variant | max abs Δ‖g‖, mGal | max angle, ″ | RMS angle, ″ |',
              '|---|---|---|---|']
    for name, fn in PRINTED_VARIANTS.items():
        c = compare_models(fn, 'normal_exact', (0.0, 1e4, 2e4)).values()
        worst = [max(d[k] for d in c)
                 for k in ('max_mag_mgal', 'max_dir_arcsec', 'rms_dir_arcsec')]
        lines.append(f'| {name} | ' + ' | '.join(f'{v:.3g}' for v in worst) + ' |')
    return '\n'.join(lines)
