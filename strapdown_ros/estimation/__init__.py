"""
Estimation: the star-camera-aided attitude filter (MEKF) and the estimation tools under it.

The filter (:mod:`.attitude_filter`, its support, late-fix memory, system and live model
check), its analytic steady state (:mod:`.farrenkopf`), the χ² helpers (:mod:`.chi_square`),
observability (:mod:`.observability`) and 001's gyrocompass model and steady filter.  Above
motion, sensors and attitude; below calibration, navigation and the discrepancy workflow.
"""
from strapdown_ros.estimation.attitude_filter import AttitudeFilter
from strapdown_ros.estimation.chi_square import chi2_3_quantile
from strapdown_ros.estimation.farrenkopf import (farrenkopf_steady_state, riccati_steady_state,
                                                 SteadyState)
from strapdown_ros.estimation.filter_support import FilterCounters, FixResult

__all__ = ['AttitudeFilter', 'FilterCounters', 'FixResult', 'chi2_3_quantile', 'SteadyState',
           'farrenkopf_steady_state', 'riccati_steady_state']
