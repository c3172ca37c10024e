"""Where a warning should point: the user's line that called into sb3_maddpg, however deep the package's frames go."""

import os
import sys

PACKAGE_DIRECTORY = os.path.dirname(os.path.dirname(os.path.realpath(__file__))) + os.sep  # sb3_maddpg/, above common/


def user_stacklevel() -> int:
    """
    :return: The ``stacklevel`` that makes a ``warnings.warn`` in the function calling this one point at the first
        frame outside the package (``MADDPG(...)`` and ``MATD3(...)`` reach the same warning through different
        numbers of the package's frames).
    """
    frame = sys._getframe(1)  # the function that warns: stacklevel 1
    level = 1
    while frame.f_back is not None and os.path.realpath(frame.f_code.co_filename).startswith(PACKAGE_DIRECTORY):
        frame = frame.f_back
        level += 1
    return level
