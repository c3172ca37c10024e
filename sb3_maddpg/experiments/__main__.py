"""``python -m sb3_maddpg.experiments run|tune|report ...``: see :mod:`sb3_maddpg.experiments.cli`."""

import sys

from sb3_maddpg.experiments.cli import main

if __name__ == "__main__":
    sys.exit(main())
