"""Shared pytest setup."""

import os

# Headless rendering: pygame (imported by mpe2) must see this before it opens a display.
os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
