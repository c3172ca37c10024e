"""Shared pytest setup."""

import os

# Headless rendering: pygame (imported by mpe2) must see this before it opens a display.
os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

# One torch thread (unless OMP_NUM_THREADS says otherwise), as the package's entry points use: the tests' tiny
# networks gain nothing from more, and on a shared CPU several threads wait on each other.
from sb3_maddpg.torch_threads import use_torch_threads  # after the SDL variables

use_torch_threads()
