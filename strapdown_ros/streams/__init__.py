"""Input streams: validation rules, bounded buffers, raw CDR decoding, increments from rates (no ROS)."""
