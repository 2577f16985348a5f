"""
One library call per offline command, each on one recording.

Each call takes a recording (:class:`~strapdown_ros.runs.source.RecordingSource`: the path and
the typed input options), the typed :class:`~strapdown_ros.sensors.sensor_model.SensorModel`
and typed settings, and returns a typed, picklable result with no printing: what the command
prints and writes (JSON-ready records, counts, the model found where there is one).

* :func:`strapdown_ros.runs.sins.run_sins` → :class:`~strapdown_ros.runs.sins.SinsRun`
  (``sins_bag``);
* :func:`strapdown_ros.runs.boresight.calibrate_boresight` →
  :class:`~strapdown_ros.runs.boresight.BoresightRun` (``calibrate_bag``);
* :func:`strapdown_ros.runs.gyro.calibrate_gyro` → :class:`~strapdown_ros.runs.gyro.GyroRun`
  (``calibrate_gyro_bag``);
* :func:`strapdown_ros.runs.filter.run_filter_on` →
  :class:`~strapdown_ros.runs.filter.FilterRun` (``filter_bag``);
* :func:`strapdown_ros.runs.discrepancy.analyse_discrepancies` →
  :class:`~strapdown_ros.runs.discrepancy.DiscrepancyRun` (``discrepancy``).

The boresight, gyro and discrepancy calls also come in a form that takes streams already read
(``*_of_data``, ``*_of_recording``), so the fleet reads a recording once for all three.
Imports rosbags (the ``tools`` extra).
"""
