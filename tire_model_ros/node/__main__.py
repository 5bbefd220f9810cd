"""``python -m tire_model_ros.node``: the same as ``tire-model-node``."""

from tire_model_ros.node import main

main()
