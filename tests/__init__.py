"""The tests, in folders as the package's; shared helpers and fixtures at this level."""
