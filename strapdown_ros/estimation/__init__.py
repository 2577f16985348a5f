"""Estimation: the star-camera-aided attitude filter (MEKF) and its analytic steady state."""
from strapdown_ros.estimation.attitude_filter import (AttitudeFilter, chi2_3_quantile,
                                                      FilterCounters, FixResult)
from strapdown_ros.estimation.farrenkopf import (farrenkopf_steady_state, riccati_steady_state,
                                                 SteadyState)

__all__ = ['AttitudeFilter', 'FilterCounters', 'FixResult', 'chi2_3_quantile', 'SteadyState',
           'farrenkopf_steady_state', 'riccati_steady_state']
