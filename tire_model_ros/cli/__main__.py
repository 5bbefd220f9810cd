"""``python -m tire_model_ros.cli``: the ``tire-model`` command without its script."""

import sys

from tire_model_ros.cli import main

sys.exit(main())
