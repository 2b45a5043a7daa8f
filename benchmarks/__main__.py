"""``python -m strol_gym.benchmarks``: the same as the ``strol-bench`` console script."""

import sys

from strol_gym.benchmarks.cli import main

sys.exit(main())
