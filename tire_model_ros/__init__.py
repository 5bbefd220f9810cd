"""tire_model_ros: an extended Magic Formula tyre model for ROS 2.

Layout (data flows one way: recording -> aligned arrays -> model/fit/diagnosis -> report/.tir):

- ``model``      pure numpy/numba Magic Formula and .tir I/O
- ``recording``  rosbag2 read, the alignment rule on slip stamps (``align``), write
- ``rig``        the virtual test rig (its own physics, not the fitted forms)
- ``fit``        staged bounded least-squares refit of .tir coefficients
- ``diagnosis``  locate, name and model what a fit leaves out
- ``wheel``      the node's per-wheel logic and parameter table, without ROS
- ``cli``        the ``tire-model`` command and its subcommands
- ``vocabulary`` the shared words of INTERFACE.md: topics, message types, channels, effects
- ``delivery``   what play, the node and record did not deliver: their reports, the account
- ``ros``        everything that needs ROS 2 (rclpy): the node, play, record; nothing outside
  this folder imports ROS, so the offline tool runs from a plain ``pip install``
"""

import os

# One BLAS thread unless the user says otherwise: the package's linear algebra is small dense
# problems (least-squares Jacobians of a few thousand rows), where a thread pool only costs. On
# a busy 2-core machine a threaded SVD of 3000 x 16 took 0.4 s against 1.5 ms on one thread
# (the diagnosis spent half its time there). Effective only before numpy is first imported;
# the fit and the diagnosis also hold BLAS to one thread while they run (``blas``), for a user
# who imported numpy first.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

__version__ = "0.1.0"
