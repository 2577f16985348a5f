"""
The Earth model: ellipsoids, normal gravity and geodetic conversions.

One room above the base: the motion profiles, the navigation channel and the parameter tables
use it.  Split by subject: :mod:`~strapdown_ros.earth.ellipsoid` (constants, ellipsoids,
geodesy), :mod:`~strapdown_ros.earth.normal_field` (the exact normal field, Somigliana, J2),
:mod:`~strapdown_ros.earth.printed_formula` (paper 003's formula, corrected and as printed)
and :mod:`~strapdown_ros.earth.models` (the models by name and their comparison).  Its names
are imported from ``strapdown_ros.earth``; ``python -m strapdown_ros.earth`` prints the
comparison of doc/navigation_gravity.md.
"""
from strapdown_ros.earth.ellipsoid import (A, E2, E2_003, ecef_to_geodetic, Ellipsoid,
                                           enu_rotation, ETA_003, F, GE, geodetic_to_ecef, GM, J2,
                                           OMEGA, PZ90_11, WGS84)
from strapdown_ros.earth.models import (compare_models, DEFAULT_GRAVITY_MODEL, get_gravity_model,
                                        GRAVITY_MODELS, normal_gravity, report, SCALAR_GRAVITY)
from strapdown_ros.earth.normal_field import (j2_gravity, j2_potential, level_ellipsoid_j2,
                                              normal_exact_xyz, normal_gravity_exact,
                                              normal_potential, somigliana)
from strapdown_ros.earth.printed_formula import (MISPRINTS, printed_gravity,
                                                 printed_gravity_as_printed,
                                                 printed_gravity_variant, printed_gravity_xyz,
                                                 PRINTED_VARIANTS)

__all__ = ['A', 'compare_models', 'DEFAULT_GRAVITY_MODEL', 'E2', 'E2_003', 'ecef_to_geodetic',
           'Ellipsoid', 'enu_rotation', 'ETA_003', 'F', 'GE', 'geodetic_to_ecef',
           'get_gravity_model', 'GM', 'GRAVITY_MODELS', 'J2', 'j2_gravity', 'j2_potential',
           'level_ellipsoid_j2', 'MISPRINTS', 'normal_exact_xyz', 'normal_gravity',
           'normal_gravity_exact', 'normal_potential', 'OMEGA', 'printed_gravity',
           'printed_gravity_as_printed', 'printed_gravity_variant', 'printed_gravity_xyz',
           'PRINTED_VARIANTS', 'PZ90_11', 'report', 'SCALAR_GRAVITY', 'somigliana', 'WGS84']
