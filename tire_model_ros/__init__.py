"""tire_model_ros: an extended Magic Formula tyre model for ROS 2.

Layout (data flows one way: recording -> aligned arrays -> model/fit/diagnosis -> report/.tir):

- ``model``      pure numpy/numba Magic Formula and .tir I/O, no ROS import
- ``recording``  rosbag2 read/write, alignment on slip stamps, play and record
- ``rig``        the virtual test rig (its own physics, not the fitted forms)
- ``fit``        staged bounded least-squares refit of .tir coefficients
- ``diagnosis``  locate, name and model what a fit leaves out
- ``node``       the ROS 2 node (glue only)
- ``cli``        the ``tire-model`` command and its subcommands
"""

__version__ = "0.1.0"
