"""
The discrepancy workflow: where a recording and its model disagree and which effect is missing.

The entry point is :func:`strapdown_ros.discrepancy.workflow.analyse`; the ``discrepancy``
tool reads a bag with :mod:`strapdown_ros.discrepancy.bag_input` and writes the report of
:mod:`strapdown_ros.discrepancy.report`.
"""
