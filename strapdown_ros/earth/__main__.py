"""
Print the gravity model comparison of doc/navigation_gravity.md.

Run as ``python -m strapdown_ros.earth``.
"""
from strapdown_ros.earth.models import report

print(report())
