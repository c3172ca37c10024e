"""``python -m sb3_maddpg run|tune|report ...``, the same as ``sb3-maddpg ...``: see :mod:`sb3_maddpg.cli.main`."""

import sys

from sb3_maddpg.cli.main import main

if __name__ == "__main__":
    sys.exit(main())
