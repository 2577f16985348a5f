"""Estimation: the star-camera-aided attitude filter (MEKF) and its analytic steady state."""
from .attitude_filter import AttitudeFilter, FilterCounters, FixResult, chi2_3_quantile
from .farrenkopf import SteadyState, farrenkopf_steady_state, riccati_steady_state

__all__ = ["AttitudeFilter", "FilterCounters", "FixResult", "chi2_3_quantile", "SteadyState",
           "farrenkopf_steady_state", "riccati_steady_state"]
