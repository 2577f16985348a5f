"""
Many units' recordings on Dask: calibrate and check each, follow each unit's effects over time.

:mod:`~strapdown_ros.fleet.manifest` (which unit recorded what, when, with which model),
:mod:`~strapdown_ros.fleet.analysis` (the task on one recording), :mod:`~strapdown_ros.fleet.cache`
(results by content hash), :mod:`~strapdown_ros.fleet.cluster` (the Dask client: a LocalCluster
or a scheduler address, and the task map the benches use too),
:mod:`~strapdown_ros.fleet.changes` (the change test between recordings, the population),
:mod:`~strapdown_ros.fleet.report` (tables, plots, summary) and :mod:`~strapdown_ros.fleet.run`
(the whole run, what the ``fleet`` command calls).  Dask distributed and pyarrow are imported
where they are used.
"""
