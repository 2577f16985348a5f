"""Estimation: the star-camera-aided attitude filter (MEKF) and its analytic steady state."""
from strapdown_ros.estimation.attitude_filter import AttitudeFilter
from strapdown_ros.estimation.chi_square import chi2_3_quantile
from strapdown_ros.estimation.farrenkopf import (farrenkopf_steady_state, riccati_steady_state,
                                                 SteadyState)
from strapdown_ros.estimation.filter_support import FilterCounters, FixResult

__all__ = ['AttitudeFilter', 'FilterCounters', 'FixResult', 'chi2_3_quantile', 'SteadyState',
           'farrenkopf_steady_state', 'riccati_steady_state']
