"""
Input streams: validation rules, bounded buffers, raw CDR decoding, increments from rates.

The lowest room that sees messages: the nodes, the SINS core and the bag readers hand their
raw streams here before any numerical work.  No ROS imports.
"""
