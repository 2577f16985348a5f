"""Estimation: the star-camera-aided attitude filter (MEKF) and its analytic steady state."""
from strapdown_ros.estimation.attitude_filter import (AttitudeFilter, FilterCounters, FixResult,
    chi2_3_quantile)
from strapdown_ros.estimation.farrenkopf import (SteadyState, farrenkopf_steady_state,
    riccati_steady_state)

__all__ = ["AttitudeFilter", "FilterCounters", "FixResult", "chi2_3_quantile", "SteadyState",
           "farrenkopf_steady_state", "riccati_steady_state"]
